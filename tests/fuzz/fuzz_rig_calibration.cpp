// libFuzzer target for the rig calibration reader (OpenCV FileStorage YAML): arbitrary bytes are
// written to a scratch file and read. A successful read must validate, write and read back to the
// same cameras.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include "camera/camera_model.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::filesystem::path dir = [] {
    auto d = std::filesystem::temp_directory_path() /
             ("hc-fuzz-rig-calibration-" + std::to_string(::getpid()));
    std::filesystem::create_directories(d);
    return d;
  }();
  const auto in = dir / "in.yml";
  {
    std::ofstream f(in, std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  }
  hc::Result<hc::RigCalibration> rig = hc::read_rig_calibration(in);
  if (!rig.ok()) {
    if (rig.status().message().empty()) __builtin_trap();
    return 0;
  }
  for (const hc::CameraModel& c : rig->cameras)
    if (!hc::validate(c).ok()) __builtin_trap();
  const auto out = dir / "out.yml";
  // Names the reader accepts may still not be writable YAML keys; then writing must fail cleanly.
  if (!hc::write_rig_calibration(out, *rig).ok()) return 0;
  hc::Result<hc::RigCalibration> again = hc::read_rig_calibration(out);
  if (!again.ok() || again->cameras.size() != rig->cameras.size()) __builtin_trap();
  for (std::size_t i = 0; i < rig->cameras.size(); ++i)
    if (again->cameras[i].name != rig->cameras[i].name) __builtin_trap();
  return 0;
}
