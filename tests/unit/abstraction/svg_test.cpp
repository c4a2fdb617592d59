// SVG outlines in and out: areas of documents whose geometry is known by construction, units,
// transforms, curves, and malformed input (each names what is wrong).
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "fabrication/abstraction/svg.h"
#include "test_data.h"

namespace hc::abstraction {
namespace {

std::string doc(
    const std::string& body,
    const std::string& root = R"svg(width="100mm" height="100mm" viewBox="0 0 100 100")svg") {
  return "<svg xmlns=\"http://www.w3.org/2000/svg\" " + root + ">" + body + "</svg>";
}

TEST(Svg, RectangleInMillimetres) {
  auto p = parse_svg(doc(R"svg(<rect x="10" y="10" width="10" height="20"/>)svg"), "t");
  ASSERT_TRUE(p.ok()) << p.status().to_string();
  EXPECT_NEAR(area(*p), 200.0, 1e-9);
}

TEST(Svg, UnitlessDocumentsArePixels) {
  // 96 px per inch: a 96 x 96 px square is 25.4 mm on a side.
  auto p = parse_svg(doc(R"svg(<path d="M0 0 h96 v96 h-96 z"/>)svg", ""), "t");
  ASSERT_TRUE(p.ok()) << p.status().to_string();
  EXPECT_NEAR(area(*p), 25.4 * 25.4, 1e-9);
}

TEST(Svg, TransformsComposeAndHolesUseEvenOdd) {
  // scale(2) of a 10 x 10 square with a 2 x 2 hole (relative path): 400 - 16.
  auto p = parse_svg(
      doc(R"svg(<g transform="translate(5 5)"><path transform="scale(2)" d="M0,0 l10,0 l0,10 l-10,0 z m4,4 h2 v2 h-2 z"/></g>)svg"),
      "t");
  ASSERT_TRUE(p.ok()) << p.status().to_string();
  EXPECT_EQ(p->loops.size(), 2u);
  EXPECT_NEAR(area(*p), 400.0 - 16.0, 1e-9);
  EXPECT_NEAR(p->bounding_box().min().x(), 5.0, 1e-12);
}

TEST(Svg, CirclesAndArcsAreFlattenedWithinTheTolerance) {
  // A circle of radius 10 flattened to within 0.01 mm: area within 2 pi r * 0.01 of pi r^2.
  auto c = parse_svg(doc(R"svg(<circle cx="50" cy="50" r="10"/>)svg"), "t");
  ASSERT_TRUE(c.ok()) << c.status().to_string();
  EXPECT_NEAR(area(*c), std::numbers::pi * 100, 2 * std::numbers::pi * 10 * 0.01);
  // Two half-circle arcs give the same disc; the first writes its flags packed ("1120" is large
  // arc 1, sweep 1, x 20), as SVG's grammar allows.
  auto b = parse_svg(doc(R"svg(<path d="M40 50 a10 10 0 1120 0 A10,10 0 1,1 40,50 Z"/>)svg"), "t");
  ASSERT_TRUE(b.ok()) << b.status().to_string();
  EXPECT_NEAR(area(*b), std::numbers::pi * 100, 2 * std::numbers::pi * 10 * 0.01);
}

TEST(Svg, RoundTrip) {
  auto p = parse_svg(doc(R"svg(<polygon points="0,0 30,0 30,20 15,35 0,20"/>)svg"), "t");
  ASSERT_TRUE(p.ok());
  auto q = parse_svg(format_svg(*p), "round trip");
  ASSERT_TRUE(q.ok()) << q.status().to_string();
  ASSERT_EQ(q->loops.size(), 1u);
  ASSERT_EQ(q->loops[0].size(), p->loops[0].size());
  for (std::size_t i = 0; i < p->loops[0].size(); ++i)
    EXPECT_LT((q->loops[0][i] - p->loops[0][i]).norm(), 1e-7);
}

TEST(Svg, MalformedInputNamesTheProblem) {
  const std::pair<std::string, std::string> cases[] = {
      {"<svg xmlns=\"http://www.w3.org/2000/svg\"><path d=\"M0 0 L1 0 L1 1 z\"", "malformed XML"},
      {doc(""), "no closed path"},
      {doc(R"svg(<path d="M0 0 L1 0 Lx 1 z"/>)svg"), "expected a number"},
      {doc(R"svg(<path d="M0 0 K1 0 z"/>)svg"), "unknown path command"},
      {doc(R"svg(<path d="0 0 L1 0 L1 1 z"/>)svg"), "must start with a command"},
      {doc(R"svg(<rect width="1" height="1" transform="wobble(3)"/>)svg"), "unknown transform"},
      {"<html><body/></html>", "expected <svg>"},
      {doc("", R"svg(width="10furlong" viewBox="0 0 1 1")svg"), "unit"},
      {doc(R"svg(<path d="M0 0 L1 0 L2 0 z"/>)svg"), "no closed path"},
      // Relative moves that overflow to infinity, then a curve through them (its flattening saw
      // NaN: a fuzzer's find).
      {doc(R"svg(<path d="M0 0 l1e308 0 l1e308 0 c1 1 2 2 3 3 z"/>)svg"), "not finite"},
      {doc(R"svg(<path d="M0 0 h1 v1 z" transform="scale(1e200) scale(1e200)"/>)svg"), "not finite"},
  };
  for (const auto& [text, expected] : cases) {
    auto p = parse_svg(text, "bad.svg");
    ASSERT_FALSE(p.ok()) << text;
    EXPECT_NE(p.status().message().find(expected), std::string::npos) << p.status().message();
    EXPECT_NE(p.status().message().find("bad.svg"), std::string::npos) << p.status().message();
  }
}

TEST(Svg, AnOutlineTooFineToHoldIsAClearError) {
  // 1,100 cubic curves at a flatness of 1e-9 mm would flatten to 11 million points (10,000 per
  // curve, the cap): the reader stops at 10 million and names the option to raise.
  std::string d = "M0 0";
  for (int i = 0; i < 1100; ++i) d += " c0 50 100 50 100 0";
  d += " z";
  SvgReadOptions options;
  options.flatness_mm = 1e-9;
  auto p = parse_svg(doc("<path d=\"" + d + "\"/>"), "fine.svg", options);
  ASSERT_FALSE(p.ok());
  EXPECT_NE(p.status().message().find("raise the flatness"), std::string::npos)
      << p.status().message();
  // The same document at the default flatness reads.
  EXPECT_TRUE(parse_svg(doc("<path d=\"" + d + "\"/>"), "fine.svg").ok());
}

TEST(Svg, WriteIsAtomicAndReadable) {
  testing::ScratchDir dir;
  auto p = parse_svg(doc(R"svg(<rect x="0" y="0" width="3" height="4"/>)svg"), "t");
  ASSERT_TRUE(p.ok());
  ASSERT_TRUE(write_svg(dir.path() / "out.svg", *p).ok());
  auto q = read_svg(dir.path() / "out.svg");
  ASSERT_TRUE(q.ok()) << q.status().to_string();
  EXPECT_NEAR(area(*q), 12.0, 1e-9);
  EXPECT_FALSE(read_svg(dir.path() / "missing.svg").ok());
}

}  // namespace
}  // namespace hc::abstraction
