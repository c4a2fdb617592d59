#include "common/units.h"

#include <array>
#include <utility>

namespace hc::units {
namespace {
constexpr std::array<std::pair<LengthUnit, std::string_view>, 6> kNames{{
    {LengthUnit::kMicron, "micron"},
    {LengthUnit::kMillimetre, "millimeter"},
    {LengthUnit::kCentimetre, "centimeter"},
    {LengthUnit::kInch, "inch"},
    {LengthUnit::kFoot, "foot"},
    {LengthUnit::kMetre, "meter"},
}};
}  // namespace

std::string_view to_3mf_name(LengthUnit u) {
  for (const auto& [unit, name] : kNames)
    if (unit == u) return name;
  return "millimeter";
}

std::optional<LengthUnit> length_unit_from_name(std::string_view name) {
  for (const auto& [unit, n] : kNames)
    if (n == name) return unit;
  if (name == "mm") return LengthUnit::kMillimetre;
  if (name == "m" || name == "metre") return LengthUnit::kMetre;
  if (name == "cm" || name == "centimetre") return LengthUnit::kCentimetre;
  if (name == "um" || name == "µm") return LengthUnit::kMicron;
  if (name == "in") return LengthUnit::kInch;
  if (name == "ft") return LengthUnit::kFoot;
  return std::nullopt;
}

}  // namespace hc::units
