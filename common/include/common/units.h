// SI-unit conventions. Inside Hardcopy every quantity is SI (m, N, Pa, s, kg); names carry the unit
// where the type does not (force_n, stamp_ns, depth_m). Millimetres appear only at the user-facing
// edge (print files, reports) and are converted here, in one place.
#pragma once

#include <numbers>
#include <optional>
#include <string_view>

namespace hc::units {

inline constexpr double kMetresPerMillimetre = 1e-3;
inline constexpr double kMetresPerMicron = 1e-6;
inline constexpr double kMetresPerCentimetre = 1e-2;
inline constexpr double kMetresPerInch = 0.0254;  // exact, international inch (1959)
inline constexpr double kMetresPerFoot = 0.3048;  // exact, international foot (1959)
inline constexpr double kPascalsPerMegapascal = 1e6;
inline constexpr double kNanosecondsPerSecond = 1e9;
inline constexpr double kRadiansPerDegree = std::numbers::pi / 180;

constexpr double mm_to_m(double mm) { return mm * kMetresPerMillimetre; }
constexpr double m_to_mm(double m) { return m / kMetresPerMillimetre; }
constexpr double deg_to_rad(double deg) { return deg * kRadiansPerDegree; }
constexpr double rad_to_deg(double rad) { return rad / kRadiansPerDegree; }

// Length units a mesh file may be written in. The names are the 3MF core specification's
// (§3.4 "unit" attribute of <model>), which also lists exactly these six.
enum class LengthUnit { kMicron, kMillimetre, kCentimetre, kInch, kFoot, kMetre };

constexpr double metres_per(LengthUnit u) {
  switch (u) {
    case LengthUnit::kMicron:
      return kMetresPerMicron;
    case LengthUnit::kMillimetre:
      return kMetresPerMillimetre;
    case LengthUnit::kCentimetre:
      return kMetresPerCentimetre;
    case LengthUnit::kInch:
      return kMetresPerInch;
    case LengthUnit::kFoot:
      return kMetresPerFoot;
    case LengthUnit::kMetre:
      return 1.0;
  }
  return 1.0;
}

// "micron", "millimeter", "centimeter", "inch", "foot", "meter" (3MF spelling).
std::string_view to_3mf_name(LengthUnit u);
std::optional<LengthUnit> length_unit_from_name(std::string_view name);

}  // namespace hc::units
