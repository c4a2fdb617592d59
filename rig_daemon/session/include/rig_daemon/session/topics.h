// How rigd lays out a session in MCAP: one channel per device stream, named after the device, plus
// the session's own channels. Every channel's metadata carries "device", "kind" and "backend" (the
// session channels: "device" = "session"), so a reader (the replay backends, the offline rooms,
// `hardcopy session`) can find a device's stream without knowing the topic.
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
//                                                        and force samples associated with it
//   /session/steps        hardcopy.Step (json)           protocol step markers
//   /session/events       hardcopy.Event (json)          safety trips, pauses, device errors, log
//   /sim/ground_truth     hardcopy.GroundTruth (json)    simulated rigs only: one per frame time;
//                                                        sequence = trigger index
// (the last four: session_records.h, written and read through codec.h and session_reader.h).
//
// Metadata records (names from recording/session_conventions.h): rig_config {yaml}, plan {yaml,
// json}, specimen {...}, software {name, version}, calibration {json}, device_stats (last one
// wins), and "session" {state, reason, association counts, safety numbers} at the end.
//
// Simulated rigs also get "sim_cameras" {json}: the TRUE parameters of every simulated camera of
// the session, {NAME: {width, height, fx, fy, cx, cy, distortion [k1, k2, p1, p2[, k3[, k4, k5, k6]]], R [[3x3
// rows]], t_m [x, y, z], center_m [x, y, z]}} with x_cam = R x_world + t (OpenCV's model, pixel
// centres at integer coordinates; common/camera's camera_to_json), for comparing a calibration
// with the truth. A calibration session on a simulated rig also gets "sim_board" {json}: {cols,
// rows, square_m, margin_squares, poses: [{R, t_m}...]} (the pose sequence; frame k of the
// session shows pose k mod N, and /sim/ground_truth names it per frame).
#pragma once

#include <string>
#include <string_view>

namespace hc::session {

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
inline constexpr std::string_view kMetadataSimCameras = "sim_cameras";
inline constexpr std::string_view kMetadataSimBoard = "sim_board";

}  // namespace hc::session
