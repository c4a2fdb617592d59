// What a printer technology asks of print-in-place joints (thesis Secs. 6.3, 6.5): the clearance d
// between moving parts, the smallest critical cross-section A_min that is not brittle, the friction
// bumps' radius r_b, the default ranges, the alpha of the wrap that closes soups, and FDM's
// orientation rules. Read from YAML in millimetres:
//
//   base: fdm            # polyjet (default), sla or fdm: start from its values
//   clearance_mm: 0.45
//   min_area_mm2: 12
//   bump_radius_mm: 0.8
//   default_cone_deg: 10
//   default_swing_deg: 45
//   wrap_alpha_mm: 1.0
//   pins_upright: true
//   max_overhang_deg: 45
#pragma once

#include <filesystem>
#include <string>

#include "common/config.h"
#include "common/status.h"

namespace hc::articulation {

struct PrinterProfile {
  std::string name = "polyjet";
  double clearance_m = 0.3e-3;    // d: parts fuse below it (PolyJet: thesis Sec. 6.5)
  double min_area_m2 = 10e-6;     // A_min: VeroClear/VeroBlack, thesis Sec. 6.5
  double bump_radius_m = 0.7e-3;  // r_b, thesis Sec. 6.5 (must exceed d to grip)
  double default_cone_rad = 10.0 * 3.14159265358979 / 180;   // beta of default ball joints
  double default_swing_rad = 45.0 * 3.14159265358979 / 180;  // hinges with no range given
  double wrap_alpha_m = 0.5e-3;   // alpha of the wrap for soups: the smallest feature kept
  // FDM: hinge pins printed upright (a default hinge axis is turned towards the build
  // direction), and cavities given a 45-degree roof (no overhang past max_overhang).
  bool pins_upright = false;
  double max_overhang_rad = 3.14159265358979 / 2;  // pi/2: no limit

  Status read(ConfigNode node);
  Status validate() const;
};

// The built-in profiles: "polyjet" (thesis: d 0.3 mm, A_min 10 mm^2, r_b 0.7 mm), "sla" (d 0.25
// mm), "fdm" (d 0.4 mm, pins upright, overhangs <= 45 deg). kInvalidArgument for other names.
Result<PrinterProfile> builtin_printer_profile(const std::string& name);

// Reads a profile file (see above); messages name the file, line and key.
Result<PrinterProfile> load_printer_profile(const std::filesystem::path& path);
Result<PrinterProfile> parse_printer_profile(std::string_view yaml, std::string_view name);

}  // namespace hc::articulation
