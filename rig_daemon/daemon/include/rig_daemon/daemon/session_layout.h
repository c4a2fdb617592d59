// How rigd lays out a session in MCAP: one channel per device stream, named after the device, plus
// the session's own channels. Every channel's metadata carries "device", "kind" and "backend" (the
// session channels: "device" = "session"), so a reader (the replay backends, `hardcopy session`)
// can find a device's stream without knowing the topic.
//
//   /<camera>/image       foxglove.RawImage (protobuf)   log_time = Frame::host_ns,
//                                                        publish_time = device stamp (else host),
//                                                        sequence = frame_id
//   /<trigger>/edges      hardcopy.TriggerEdge (json)    sequence = device_counter
//   /<fsr>/samples        hardcopy.FsrSample (json)      sequence = sequence
//   /<ft>/wrench          hardcopy.WrenchSample (json)   sequence = rdt_sequence
//   /<arm>/state          hardcopy.ArmState (json)       sequence = sequence
//   /<arm>/command        hardcopy.ArmCommand (json)     sequence = command sequence
//   /session/sync         hardcopy.SyncRecord (json)     one per rising trigger edge: the frames
//   and
//                                                        force samples associated with it
//   /session/steps        hardcopy.Step (json)           protocol step markers
//   /session/events       hardcopy.Event (json)          safety trips, pauses, device errors, log
//   /sim/ground_truth     hardcopy.GroundTruth (json)    simulated rigs only
//
// Metadata records (names from recording/session_conventions.h): rig_config {yaml}, plan {yaml,
// json}, specimen {...}, software {name, version}, calibration {json}, device_stats (last one
// wins), and "session" {state, reason, association counts, safety numbers} at the end.
#pragma once

#include <string>
#include <string_view>

namespace hc::rig {

// "/<device>/<stream>" (built by appending: g++ 12 warns falsely on "/" + std::string).
inline std::string device_topic(std::string_view device, std::string_view stream) {
  std::string t;
  t.reserve(device.size() + stream.size() + 2);
  t += '/';
  t += device;
  t += '/';
  t += stream;
  return t;
}
inline std::string camera_topic(std::string_view device) { return device_topic(device, "image"); }
inline std::string trigger_topic(std::string_view device) { return device_topic(device, "edges"); }
inline std::string fsr_topic(std::string_view device) { return device_topic(device, "samples"); }
inline std::string wrench_topic(std::string_view device) { return device_topic(device, "wrench"); }
inline std::string arm_state_topic(std::string_view device) {
  return device_topic(device, "state");
}
inline std::string arm_command_topic(std::string_view device) {
  return device_topic(device, "command");
}
inline constexpr std::string_view kSyncTopic = "/session/sync";
inline constexpr std::string_view kStepsTopic = "/session/steps";
inline constexpr std::string_view kEventsTopic = "/session/events";
inline constexpr std::string_view kGroundTruthTopic = "/sim/ground_truth";
inline constexpr std::string_view kMetadataSession = "session";

}  // namespace hc::rig
