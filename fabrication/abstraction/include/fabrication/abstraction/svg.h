// SVG input and output of planar shapes (the 2-D side of `hardcopy abstract`, `engrave`, `offset`,
// `boolean`). Reading takes the closed outlines of <path> (M/L/H/V/C/S/Q/T/A/Z, absolute and
// relative; curves flattened to within a tolerance), <polygon>, <rect>, <circle> and <ellipse>,
// through nested transform attributes (matrix, translate, scale, rotate, skewX, skewY), parsed
// with expat. Coordinates are converted to millimetres: scaled by the root's width over its
// viewBox width when the width carries a unit, otherwise as CSS pixels (96 per inch); the
// viewBox origin is not subtracted, so a written file reads back to the same coordinates. The
// interior is the even-odd fill of all outlines. Open subpaths (no Z) are closed, as SVG's fill
// does.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

#include "common/status.h"
#include "fabrication/abstraction/polygon.h"

namespace hc::abstraction {

struct SvgReadOptions {
  double flatness_mm = 0.01;  // largest distance of a flattened curve from the true one
};

// Parses an SVG document. kInvalidArgument naming `name` and the line for malformed XML, a bad
// path or number, or a document with no closed outline of positive area.
Result<Polygon2> parse_svg(std::string_view text, std::string_view name,
                           const SvgReadOptions& options = {});
Result<Polygon2> read_svg(const std::filesystem::path& path, const SvgReadOptions& options = {});

// One <path> with fill-rule evenodd holding every loop, in millimetres (width, height and viewBox
// set so that one user unit is one millimetre).
std::string format_svg(const Polygon2& polygon);
Status write_svg(const std::filesystem::path& path, const Polygon2& polygon);

}  // namespace hc::abstraction
