#include "rig_daemon/recording/session_conventions.h"

#include <fmt/format.h>

namespace hc::recording {

std::string json_schema_for(std::string_view title, const std::vector<JsonField>& fields) {
  Json props = Json::object();
  Json required = Json::array();
  for (const auto& f : fields) {
    Json p;
    switch (f.type) {
      case JsonFieldType::kNumber:
        p["type"] = "number";
        break;
      case JsonFieldType::kInteger:
        p["type"] = "integer";
        break;
      case JsonFieldType::kBoolean:
        p["type"] = "boolean";
        break;
      case JsonFieldType::kString:
        p["type"] = "string";
        break;
    }
    if (!f.description.empty()) p["description"] = f.description;
    props[f.name] = std::move(p);
    required.push_back(f.name);
  }
  Json schema = {{"type", "object"},
                 {"title", std::string(title)},
                 {"properties", props},
                 {"required", required}};
  return schema.dump();
}

Bytes json_message(const Json& object) {
  const std::string s = object.dump();
  return Bytes(s.begin(), s.end());
}

Result<Json> parse_json_message(ByteSpan data) {
  // nlohmann::json throws on malformed text; turned into a Status at this boundary.
  try {
    return Json::parse(data.begin(), data.end());
  } catch (const Json::parse_error& e) {
    return invalid_argument(fmt::format("JSON message: byte {}: {}", e.byte, e.what()));
  }
}

}  // namespace hc::recording
