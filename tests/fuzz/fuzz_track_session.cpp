// libFuzzer target for the session side of `hardcopy track`: arbitrary bytes are read as an MCAP
// session (written to a scratch file, since the reader takes a path) with a two-camera calibration
// (cam0, cam1, 64 x 48). Sync/step/ground-truth JSON, image messages and metadata must be refused
// with a Status, never crash; whatever is read is then tracked onto a tiny template.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include "processing/fem/verification.h"
#include "processing/tracking/session_tracking.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::filesystem::path path =
      std::filesystem::temp_directory_path() /
      ("hardcopy-fuzz-track-" + std::to_string(::getpid()) + ".mcap");
  {
    std::ofstream f(path, std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  }
  hc::RigCalibration rig;
  for (int i = 0; i < 2; ++i) {
    hc::CameraModel c;
    c.name = "cam" + std::to_string(i);
    c.width = 64;
    c.height = 48;
    c.fx = c.fy = 100;
    c.cx = 31.5;
    c.cy = 23.5;
    c.t_m = Eigen::Vector3d(-0.05 * i, 0, 0.3);
    rig.cameras.push_back(c);
  }
  hc::tracking::SessionReadOptions ro;
  ro.max_steps = 4;
  ro.threads = 1;
  hc::Result<hc::tracking::SessionDetections> det =
      hc::tracking::read_session_detections(path, rig, ro);
  if (!det.ok()) return 0;
  if (det->cameras.size() != 2) __builtin_trap();
  const hc::TetMesh templ =
      hc::fem::structured_box_mesh({-0.01, 0.0, 0.01}, {-0.01, 0.0, 0.01}, {-0.01, 0.0});
  (void)hc::tracking::track_detections(*det, rig, templ);
  return 0;
}
