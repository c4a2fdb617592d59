// Marker dots rendered by the simulated cameras through the project's one camera model
// (camera/camera_model.h), where a calibrated real camera would see them.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <vector>

#include "camera/camera_model.h"
#include "rig_daemon/devices/types.h"

namespace hc::devices::sim {

// The simulator's camera when a rig file gives no intrinsics: 1600 x 1200 px, f = 2000 px,
// principal point at the image centre, no distortion, at the reference frame's origin.
CameraModel default_camera();

}  // namespace hc::devices::sim

namespace hc::devices::sim {

class ProbeLayer;  // sim_scene.h

// How marker dots look in a rendered image (8-bit grey levels).
struct DotStyle {
  std::uint8_t background = 30;
  std::uint8_t dot = 220;
};

// Draws each world-frame dot centre (at least 1 mm in front of the camera) as a disc of radius f *
// radius_m / depth pixels (the disc's foreshortening is ignored: dots are small) with anti-aliased
// edges (8 x 8 supersampling of edge pixels), so the intensity-weighted centroid of a dot lands on
// its projected centre to a few hundredths of a pixel. `frame` must be Mono8 of the camera's size;
// it is not cleared. Returns how many dots were drawn (in front of the camera and at least partly
// in the image). With an `occluder` (the probe, already composited into `frame`), a dot pixel the
// probe covers in front of the dot (probe depth < dot centre depth) shows the dot only through the
// uncovered fraction; a dot in front of the probe is drawn over it.
std::size_t render_dots(const CameraModel& cam, const std::vector<Eigen::Vector3d>& centers_m,
                        double radius_m, const DotStyle& style, Frame& frame,
                        const ProbeLayer* occluder = nullptr);

}  // namespace hc::devices::sim
