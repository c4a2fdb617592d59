// Helpers the session codecs share (codec.cpp: device samples, session_codec.cpp: the session's
// own records).
#pragma once

#include <array>
#include <optional>
#include <string>
#include <string_view>

#include "common/json.h"
#include "common/json_reader.h"
#include "rig_daemon/session/records.h"

namespace hc::session::detail {

// Invalid UTF-8 in a string (a device's fault text) is replaced rather than thrown on.
inline std::string dump(const Json& j) {
  return j.dump(-1, ' ', false, Json::error_handler_t::replace);
}

inline Result<Json> parse_object(std::string_view text, std::string_view type) {
  Json j = Json::parse(text.begin(), text.end(), nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded() || !j.is_object())
    return invalid_argument(std::string(type) + ": not a JSON object");
  return j;
}

template <typename T>
void put_opt(Json& j, const char* key, const std::optional<T>& v) {
  if (v) j[key] = *v;
}

inline Json pose_json(const ArmPose& p) {
  return Json{{"x_m", finite_or_null(p.x_m)},
              {"y_m", finite_or_null(p.y_m)},
              {"z_m", finite_or_null(p.z_m)},
              {"yaw_rad", finite_or_null(p.yaw_rad)}};
}
inline Status read_pose(const JsonNode& j, std::string_view key, ArmPose& p) {
  HC_ASSIGN_OR_RETURN(const JsonNode o, j.member(key));
  HC_RETURN_IF_ERROR(o.get("x_m", p.x_m));
  HC_RETURN_IF_ERROR(o.get("y_m", p.y_m));
  HC_RETURN_IF_ERROR(o.get("z_m", p.z_m));
  return o.get("yaw_rad", p.yaw_rad);
}

// An array of N measurements (a null is a value that was not finite when written: NaN).
template <std::size_t N>
Status read_measurements(const JsonNode& j, std::string_view key, std::array<double, N>& out) {
  HC_ASSIGN_OR_RETURN(const JsonNode a, j.member(key));
  HC_RETURN_IF_ERROR(a.expect_array_of(N, "numbers"));
  for (std::size_t i = 0; i < N; ++i) {
    HC_ASSIGN_OR_RETURN(out[i], a[i].number_or_null());
  }
  return {};
}

}  // namespace hc::session::detail
