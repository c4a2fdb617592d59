// Slices a 3MF with PrusaSlicer 2.5 (Debian package `prusa-slicer`, headless --export-gcode) on a
// multi-extruder printer and returns the filament each extruder uses, from the G-code's
// "; filament used [mm] = ..." line (lengths of 1.75 mm filament; the [cm3] line has 2 decimals). Solid (100 % infill), no skirt, brim, wipe tower or supports,
// so that the extruded volume is the parts' volume.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

namespace hc::testing {

inline bool prusa_slicer_available() { return std::system("prusa-slicer --help > /dev/null 2>&1") == 0; }

// Extruded volume per extruder in mm^3, or nullopt (with the log in *log) when slicing failed.
inline std::optional<std::vector<double>> prusa_slicer_filament_mm3(
    const std::filesystem::path& model, int extruders, const std::filesystem::path& work_dir,
    std::string* log = nullptr) {
  const std::filesystem::path ini = work_dir / "printer.ini";
  const std::filesystem::path gcode = work_dir / "out.gcode";
  const std::filesystem::path out_log = work_dir / "slicer.log";
  const auto list = [extruders](const std::string& v) {
    std::string s;
    for (int i = 0; i < extruders; ++i) s += (i ? "," : "") + v;
    return s;
  };
  {
    std::ofstream f(ini);
    f << "nozzle_diameter = " << list("0.4") << "\n"
      << "filament_diameter = " << list("1.75") << "\n"
      << "extrusion_multiplier = " << list("1") << "\n"
      << "temperature = " << list("210") << "\n"
      << "first_layer_temperature = " << list("210") << "\n"
      << "bed_shape = 0x0,250x0,250x210,0x210\n"
      << "gcode_flavor = marlin2\n"
      << "layer_height = 0.2\n"
      << "first_layer_height = 0.2\n"
      << "fill_density = 100%\n"
      << "fill_pattern = rectilinear\n"
      << "perimeters = 2\n"
      << "skirts = 0\n"
      << "brim_width = 0\n"
      << "wipe_tower = 0\n"
      << "support_material = 0\n"
      << "complete_objects = 0\n";
  }
  const std::string cmd = "prusa-slicer --export-gcode --load '" + ini.string() + "' -o '" +
                          gcode.string() + "' '" + model.string() + "' > '" + out_log.string() +
                          "' 2>&1";
  const int rc = std::system(cmd.c_str());
  if (log != nullptr) {
    std::ifstream l(out_log);
    std::stringstream ss;
    ss << l.rdbuf();
    *log = ss.str();
  }
  if (rc != 0) return std::nullopt;
  std::ifstream g(gcode);
  std::string line;
  const std::string key = "; filament used [mm] = ";
  constexpr double kFilamentAreaMm2 = 3.14159265358979 * 0.875 * 0.875;
  while (std::getline(g, line)) {
    if (line.rfind(key, 0) != 0) continue;
    std::vector<double> out;
    std::stringstream values(line.substr(key.size()));
    std::string item;
    while (std::getline(values, item, ',')) out.push_back(kFilamentAreaMm2 * std::stod(item));
    return out;
  }
  if (log != nullptr) *log += "\nno '" + key + "' line in the G-code";
  return std::nullopt;
}

}  // namespace hc::testing
