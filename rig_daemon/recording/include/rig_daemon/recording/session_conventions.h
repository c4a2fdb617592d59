// Conventions shared by the writer of Hardcopy sessions (rig_daemon/daemon's recorder) and the
// readers (replay backends, `hardcopy session ...`): message encodings, metadata names and the
// device statistics record. Nothing here is required by MCAP itself.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "common/json.h"
#include "common/status.h"
#include "rig_daemon/recording/mcap_records.h"

namespace hc::recording {

// Encodings (MCAP well-known names).
inline constexpr std::string_view kJsonEncoding = "json";              // Channel.message_encoding
inline constexpr std::string_view kJsonSchemaEncoding = "jsonschema";  // Schema.encoding
inline constexpr std::string_view kProtobufEncoding = "protobuf";      // both

// Metadata record names a session carries (each a string map; YAML / JSON documents go in a
// single key "yaml" / "json").
inline constexpr std::string_view kMetadataRigConfig = "rig_config";
inline constexpr std::string_view kMetadataCalibration = "calibration";
inline constexpr std::string_view kMetadataPlan = "plan";
inline constexpr std::string_view kMetadataSpecimen = "specimen";
inline constexpr std::string_view kMetadataSoftware = "software";  // keys "name", "version", ...
// Lost / late samples per device. The recorder writes one Metadata record named "device_stats" (at
// the end of the session; writing it again later supersedes the earlier one — readers use the
// last) with keys "<device>.received", "<device>.lost", "<device>.late" (decimal counts), e.g.
// {"ft0.received": "70000", "ft0.lost": "3", "ft0.late": "0"}.
inline constexpr std::string_view kMetadataDeviceStats = "device_stats";
// rigd's end-of-session record: keys "state", "reason", "json" (last one wins).
inline constexpr std::string_view kMetadataSessionEnd = "session";

// ---- JSON time series ----
// A JSON Schema (draft 2020-12 subset Foxglove understands) for a flat object whose fields are
// numbers, integers, booleans or strings: {"type":"object","title":title,"properties":{...}}.
enum class JsonFieldType : std::uint8_t { kNumber, kInteger, kBoolean, kString };
struct JsonField {
  std::string name;
  JsonFieldType type = JsonFieldType::kNumber;
  std::string description;  // units go here, e.g. "force along x, N"
};
std::string json_schema_for(std::string_view title, const std::vector<JsonField>& fields);
// The message bytes of a JSON object (compact dump).
Bytes json_message(const Json& object);
// Parses a JSON message; invalid_argument with the parser's position on malformed text.
Result<Json> parse_json_message(ByteSpan data);

}  // namespace hc::recording
