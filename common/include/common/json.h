// JSON for --json output and the JSON artefacts (samples, materials), on nlohmann::json:
// conversions for Eigen types, Status as JSON, printing, and parsing that returns a Status (with
// line and column) instead of throwing.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <string_view>
#include <type_traits>

#include "common/status.h"

namespace hc {

using Json = nlohmann::json;

// `v` as a JSON number, or null when it is NaN or infinite (JSON has no such numbers; readers in
// other languages reject them).
inline Json finite_or_null(double v) { return std::isfinite(v) ? Json(v) : Json(nullptr); }

// A vector (one row or one column at compile time) as a flat array [x, y, z]; any other matrix
// as an array of rows, so a #V by 3 matrix gives [[x, y, z], ...] even when #V is 1. Floating
// entries that are not finite become null. `Json j = v;` does the same for Eigen::Matrix types.
template <typename Derived>
Json eigen_to_json(const Eigen::DenseBase<Derived>& m) {
  using Scalar = typename Derived::Scalar;
  const auto value = [](const Scalar& v) {
    if constexpr (std::is_floating_point_v<Scalar>) {
      return finite_or_null(static_cast<double>(v));
    } else {
      return Json(v);
    }
  };
  Json out = Json::array();
  if constexpr (Derived::RowsAtCompileTime == 1 || Derived::ColsAtCompileTime == 1) {
    for (Eigen::Index r = 0; r < m.rows(); ++r)
      for (Eigen::Index c = 0; c < m.cols(); ++c) out.push_back(value(m(r, c)));
  } else {
    for (Eigen::Index r = 0; r < m.rows(); ++r) {
      Json row = Json::array();
      for (Eigen::Index c = 0; c < m.cols(); ++c) row.push_back(value(m(r, c)));
      out.push_back(std::move(row));
    }
  }
  return out;
}

// {"min": [x, y, z], "max": [x, y, z]} (units as stored in the box, SI inside Hardcopy), or null
// for an empty box (a default-constructed one holds no point). `Json j = box;` does the same.
template <typename Scalar, int Dim>
Json box_to_json(const Eigen::AlignedBox<Scalar, Dim>& box) {
  if (box.isEmpty()) return Json(nullptr);
  return Json{{"min", eigen_to_json(box.min())}, {"max", eigen_to_json(box.max())}};
}

// "ok", "invalid_argument", "not_found", ...: the StatusCode enumerator without its k, as a stable
// identifier for scripts (to_string(StatusCode) is the human spelling).
std::string_view status_code_name(StatusCode code);

// {"ok": true} or {"ok": false, "code": "invalid_argument", "message": "bunny.ply:12: ..."}.
Json status_to_json(const Status& status);

// Pretty text: 2-space indent and a trailing newline. Invalid UTF-8 in strings (a file name from
// the disk) is replaced with U+FFFD rather than failing.
std::string dump_json(const Json& json);

// Writes dump_json(json) to `out`. Fails with kIoError when the stream does (closed pipe, full
// disk), so that a tool can exit non-zero instead of leaving a truncated result.
Status print_json(const Json& json, std::FILE* out = stdout);

// parse_json refuses deeper nesting: no Hardcopy file comes near it, and nlohmann's printing and
// comparison recurse, so a hostile file must not get that far.
inline constexpr int kMaxJsonDepth = 512;

// Parses one JSON value. Fails with kInvalidArgument "NAME:LINE:COLUMN: what" (1-based, column in
// bytes) on a syntax error or nesting deeper than kMaxJsonDepth, or "NAME: what" when a number
// does not fit a double.
Result<Json> parse_json(std::string_view text, std::string_view name);

// Reads and parses the file; messages name it by `path`. Adds kNotFound and kIoError.
Result<Json> load_json(const std::filesystem::path& path);

}  // namespace hc

namespace nlohmann {

// `Json j = Eigen::Vector3d(...)` and `Json j = box`: output only. Reading goes through functions
// that return a Status, since from_json could only throw.
template <typename Scalar, int Rows, int Cols, int Options, int MaxRows, int MaxCols>
struct adl_serializer<Eigen::Matrix<Scalar, Rows, Cols, Options, MaxRows, MaxCols>> {
  template <typename BasicJson>
  static void to_json(BasicJson& j,
                      const Eigen::Matrix<Scalar, Rows, Cols, Options, MaxRows, MaxCols>& m) {
    j = hc::eigen_to_json(m);
  }
};

template <typename Scalar, int Dim>
struct adl_serializer<Eigen::AlignedBox<Scalar, Dim>> {
  template <typename BasicJson>
  static void to_json(BasicJson& j, const Eigen::AlignedBox<Scalar, Dim>& box) {
    j = hc::box_to_json(box);
  }
};

}  // namespace nlohmann
