// A scalar field on a triangulated surface drawn as a colour map (e.g. the position error of a
// fitted material on the specimen's surface, thesis Fig. 5.8.1's "error plot"): the surface is
// projected orthographically along a view direction, triangles are painted back to front with
// colours interpolated between their corners (Cairo mesh gradients), and a colour bar shows the
// scale (viridis).
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "common/status.h"
#include "plot/chart.h"

namespace hc::plot {

struct SurfaceMap {
  std::string title;
  std::string value_label;  // colour bar label with its unit, e.g. "error (mm)"
  std::string axis_unit;    // unit of the projected coordinates for the frame, e.g. "mm"
  std::vector<std::array<double, 3>> vertices;
  std::vector<std::array<int, 3>> triangles;
  std::vector<double> values;  // one per vertex
  // Looking along this direction (e.g. the probe's push direction): the view's "up" is the world
  // axis least aligned with it.
  std::array<double, 3> view_direction{0, 0, -1};
  std::optional<double> value_min, value_max;  // colour scale; unset: from the values
  // Points drawn as white-edged dots on top (e.g. probe locations), in world coordinates.
  std::vector<std::array<double, 3>> marks;

  // kInvalidArgument: sizes that do not match, an index out of range, a non-finite number, a
  // zero view direction, no triangles.
  Status validate() const;
};

// Viridis (matplotlib's default perceptually uniform map, van der Walt & Smith 2015) at t in
// [0, 1] (clamped).
Rgb viridis(double t);

Result<std::string> render_surface_map(const SurfaceMap& map, ImageFormat format,
                                       const RenderOptions& options = {});
Status write_surface_map(const SurfaceMap& map, const std::filesystem::path& path,
                         const RenderOptions& options = {});

}  // namespace hc::plot
