#include "fabrication/articulation/printer_profile.h"
#include "common/units.h"

#include <fmt/format.h>

#include <cmath>
#include <numbers>

namespace hc::articulation {
Result<PrinterProfile> builtin_printer_profile(const std::string& name) {
  PrinterProfile p;  // PolyJet (Objet Connex 500, VeroClear): the thesis's measured values
  if (name == "polyjet") return p;
  if (name == "sla") {
    // The issue's ~0.25 mm clearance; standard SLA resins are about as strong as VeroClear
    // (tensile ~50-65 MPa), so A_min stays 10 mm^2; bumps scaled with the clearance.
    p.name = "sla";
    p.clearance_m = units::mm_to_m(0.25);
    p.bump_radius_m = units::mm_to_m(0.6);
    p.wrap_alpha_m = units::mm_to_m(0.4);
    return p;
  }
  if (name == "fdm") {
    // The issue's ~0.4 mm clearance (one 0.4 mm line). Layers bond at roughly half the strength
    // of the filament, so A_min is raised to 15 mm^2 (an assumption, not measured); bumps of two
    // lines; the wrap keeps features of two lines (0.8 mm).
    p.name = "fdm";
    p.clearance_m = units::mm_to_m(0.4);
    p.min_area_m2 = 15e-6;
    p.bump_radius_m = units::mm_to_m(0.8);
    p.wrap_alpha_m = units::mm_to_m(0.8);
    p.pins_upright = true;
    p.max_overhang_rad = units::deg_to_rad(45);
    return p;
  }
  return invalid_argument(
      fmt::format("unknown printer profile '{}' (expected polyjet, sla or fdm)", name));
}

Status PrinterProfile::read(ConfigNode node) {
  std::string base = "polyjet";
  node.optional("base", base, {"polyjet", "sla", "fdm"});
  if (Result<PrinterProfile> b = builtin_printer_profile(base); b.ok()) *this = *b;
  name = base;
  node.optional("name", name);
  double clearance_mm = units::m_to_mm(clearance_m),
         area_mm2 = min_area_m2 / (units::kMetresPerMillimetre * units::kMetresPerMillimetre);
  double bump_mm = units::m_to_mm(bump_radius_m), cone_deg = units::rad_to_deg(default_cone_rad);
  double swing_deg = units::rad_to_deg(default_swing_rad), alpha_mm = units::m_to_mm(wrap_alpha_m);
  double overhang_deg = units::rad_to_deg(max_overhang_rad);
  node.optional("clearance_mm", clearance_mm, Bounds::positive());
  node.optional("min_area_mm2", area_mm2, Bounds::positive());
  node.optional("bump_radius_mm", bump_mm, Bounds::non_negative());
  node.optional("default_cone_deg", cone_deg, Bounds::between(0, 80));
  node.optional("default_swing_deg", swing_deg, Bounds::between(0, 170));
  node.optional("wrap_alpha_mm", alpha_mm, Bounds::positive());
  node.optional("pins_upright", pins_upright);
  node.optional("max_overhang_deg", overhang_deg, Bounds::between(30, 90));
  clearance_m = units::mm_to_m(clearance_mm);
  min_area_m2 = area_mm2 * units::kMetresPerMillimetre * units::kMetresPerMillimetre;
  bump_radius_m = units::mm_to_m(bump_mm);
  default_cone_rad = units::deg_to_rad(cone_deg);
  default_swing_rad = units::deg_to_rad(swing_deg);
  wrap_alpha_m = units::mm_to_m(alpha_mm);
  max_overhang_rad = units::deg_to_rad(overhang_deg);
  return node.status();
}

Status PrinterProfile::validate() const {
  if (!(clearance_m > 0) || !(min_area_m2 > 0) || !(wrap_alpha_m > 0))
    return invalid_argument("clearance, minimum area and wrap alpha must be > 0");
  if (bump_radius_m > 0 && bump_radius_m <= clearance_m)
    return invalid_argument(fmt::format(
        "bump_radius_mm ({:g}) must exceed clearance_mm ({:g}) for the bumps to grip, or be 0",
        units::m_to_mm(bump_radius_m), units::m_to_mm(clearance_m)));
  return {};
}

Result<PrinterProfile> parse_printer_profile(std::string_view yaml, std::string_view name) {
  HC_ASSIGN_OR_RETURN(const Config config, parse_config(yaml, name));
  return read_config<PrinterProfile>(config);
}

Result<PrinterProfile> load_printer_profile(const std::filesystem::path& path) {
  HC_ASSIGN_OR_RETURN(const Config config, load_config(path));
  return read_config<PrinterProfile>(config);
}

}  // namespace hc::articulation
