// JSON messages for the rig's time-series channels (MCAP message_encoding "json", schema encoding
// "jsonschema"), shared by the recorder and the replay backends so that replaying a session and
// recording it again reproduces the same bytes, and by the offline rooms that read a session's
// samples. Frames are not here: they travel as foxglove.RawImage / foxglove.CompressedImage (the
// recording library's encoding).
//
// Field names follow records.h; 64-bit integers are JSON numbers (exact up to 2^53, which host_ns
// and counters stay below for centuries); absent optionals are omitted. Decoding is strict: a
// missing required field, a wrong type or an out-of-range integer is kInvalidArgument naming the
// field.
#pragma once

#include <string>
#include <string_view>

#include "common/status.h"
#include "rig_daemon/session/records.h"
#include "rig_daemon/session/session_records.h"

namespace hc::session {

// Schema names ("hardcopy.TriggerEdge", ...) and their JSON Schema documents.
struct MessageSchema {
  std::string_view name;
  std::string_view json_schema;
};
const MessageSchema& trigger_edge_schema();
const MessageSchema& fsr_sample_schema();
const MessageSchema& wrench_sample_schema();
const MessageSchema& arm_state_schema();
const MessageSchema& arm_command_schema();
const MessageSchema& sync_record_schema();
const MessageSchema& step_record_schema();
const MessageSchema& event_record_schema();
const MessageSchema& ground_truth_schema();

std::string to_json(const TriggerEdge& edge);
std::string to_json(const FsrSample& sample);
std::string to_json(const WrenchSample& sample);
std::string to_json(const ArmState& state);
std::string to_json(const ArmCommand& command);
std::string to_json(const SyncRecord& record);
std::string to_json(const StepRecord& record);
std::string to_json(const EventRecord& record);
std::string to_json(const GroundTruthRecord& record);

Result<TriggerEdge> trigger_edge_from_json(std::string_view json);
Result<FsrSample> fsr_sample_from_json(std::string_view json);
Result<WrenchSample> wrench_sample_from_json(std::string_view json);
Result<ArmState> arm_state_from_json(std::string_view json);
Result<ArmCommand> arm_command_from_json(std::string_view json);
Result<SyncRecord> sync_record_from_json(std::string_view json);
Result<StepRecord> step_record_from_json(std::string_view json);
Result<EventRecord> event_record_from_json(std::string_view json);
Result<GroundTruthRecord> ground_truth_from_json(std::string_view json);

}  // namespace hc::session
