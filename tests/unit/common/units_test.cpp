#include "common/units.h"

#include <gtest/gtest.h>

#include <array>

namespace hc::units {
namespace {

// The 1959 international yard and pound agreement defines 1 yd = 0.9144 m exactly, with 3 ft per
// yard and 12 in per foot: 1 ft = 0.3048 m and 1 in = 0.0254 m = 25.4 mm.
constexpr double kMetresPerYard1959 = 0.9144;

TEST(Units, InchAndFootFollowThe1959Agreement) {
  EXPECT_DOUBLE_EQ(kMetresPerFoot, kMetresPerYard1959 / 3.0);
  EXPECT_DOUBLE_EQ(kMetresPerInch, kMetresPerYard1959 / 36.0);
  EXPECT_DOUBLE_EQ(12.0 * kMetresPerInch, kMetresPerFoot);
  EXPECT_DOUBLE_EQ(m_to_mm(kMetresPerInch), 25.4);
}

TEST(Units, MetricPrefixes) {
  EXPECT_DOUBLE_EQ(mm_to_m(1.0), 1e-3);
  EXPECT_DOUBLE_EQ(mm_to_m(254.0), 0.254);
  EXPECT_DOUBLE_EQ(m_to_mm(0.3048), 304.8);
  EXPECT_DOUBLE_EQ(m_to_mm(mm_to_m(123.456)), 123.456);
  EXPECT_DOUBLE_EQ(kMetresPerMicron * 1000.0, kMetresPerMillimetre);
  EXPECT_DOUBLE_EQ(kMetresPerMillimetre * 10.0, kMetresPerCentimetre);
  EXPECT_DOUBLE_EQ(kPascalsPerMegapascal, 1e6);
  EXPECT_DOUBLE_EQ(kNanosecondsPerSecond, 1e9);
}

TEST(Units, MetresPerLengthUnit) {
  EXPECT_DOUBLE_EQ(metres_per(LengthUnit::kMicron), 1e-6);
  EXPECT_DOUBLE_EQ(metres_per(LengthUnit::kMillimetre), 1e-3);
  EXPECT_DOUBLE_EQ(metres_per(LengthUnit::kCentimetre), 1e-2);
  EXPECT_DOUBLE_EQ(metres_per(LengthUnit::kInch), 0.0254);
  EXPECT_DOUBLE_EQ(metres_per(LengthUnit::kFoot), 0.3048);
  EXPECT_DOUBLE_EQ(metres_per(LengthUnit::kMetre), 1.0);
  // A 3MF file in inches scales coordinates by 25.4 into millimetres.
  EXPECT_DOUBLE_EQ(metres_per(LengthUnit::kInch) / metres_per(LengthUnit::kMillimetre), 25.4);
}

// 3MF Core Specification §3.4, <model> attribute "unit" (ST_Unit): micron, millimeter,
// centimeter, inch, foot, meter, in American spelling.
constexpr std::array<std::pair<LengthUnit, std::string_view>, 6> k3mfUnits{{
    {LengthUnit::kMicron, "micron"},
    {LengthUnit::kMillimetre, "millimeter"},
    {LengthUnit::kCentimetre, "centimeter"},
    {LengthUnit::kInch, "inch"},
    {LengthUnit::kFoot, "foot"},
    {LengthUnit::kMetre, "meter"},
}};

TEST(Units, ThreeMfNamesRoundTrip) {
  for (const auto& [unit, name] : k3mfUnits) {
    EXPECT_EQ(to_3mf_name(unit), name);
    const std::optional<LengthUnit> parsed = length_unit_from_name(name);
    ASSERT_TRUE(parsed.has_value()) << name;
    EXPECT_EQ(*parsed, unit) << name;
  }
}

TEST(Units, ShortAndBritishNames) {
  EXPECT_EQ(length_unit_from_name("mm"), LengthUnit::kMillimetre);
  EXPECT_EQ(length_unit_from_name("m"), LengthUnit::kMetre);
  EXPECT_EQ(length_unit_from_name("metre"), LengthUnit::kMetre);
  EXPECT_EQ(length_unit_from_name("cm"), LengthUnit::kCentimetre);
  EXPECT_EQ(length_unit_from_name("centimetre"), LengthUnit::kCentimetre);
  EXPECT_EQ(length_unit_from_name("um"), LengthUnit::kMicron);
  EXPECT_EQ(length_unit_from_name("\xC2\xB5m"), LengthUnit::kMicron);  // "µm" in UTF-8
  EXPECT_EQ(length_unit_from_name("in"), LengthUnit::kInch);
  EXPECT_EQ(length_unit_from_name("ft"), LengthUnit::kFoot);
}

TEST(Units, UnknownNames) {
  EXPECT_FALSE(length_unit_from_name("").has_value());
  EXPECT_FALSE(length_unit_from_name("furlong").has_value());
  EXPECT_FALSE(length_unit_from_name("Millimeter").has_value());  // 3MF names are case-sensitive
  EXPECT_FALSE(length_unit_from_name("millimeters").has_value());
}

}  // namespace
}  // namespace hc::units
