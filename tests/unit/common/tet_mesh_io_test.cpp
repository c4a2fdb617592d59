// TetGen .node/.ele reading and writing, .vtu writing, and malformed input.
#include "common/tet_mesh_io.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "common/file_io.h"
#include "test_data.h"

namespace hc {
namespace {

using ::testing::HasSubstr;
using testing::ScratchDir;
using testing::shared_data;

// A unit cube split into 5 tets (corner tets + the middle one), 1-based, with markers and regions.
constexpr std::string_view kCubeNode =
    "# unit cube\n"
    "8 3 1 1\n"
    "1 0 0 0  0.5 1\n"
    "2 1 0 0  0.5 1\n"
    "3 0 1 0  0.5 1\n"
    "4 1 1 0  0.5 1\n"
    "\n"
    "5 0 0 1  0.5 0   # top\n"
    "6 1 0 1  0.5 0\n"
    "7 0 1 1  0.5 0\n"
    "8 1 1 1  0.5 0\n";
constexpr std::string_view kCubeEle =
    "5 4 1\n"
    "1 1 2 3 5 7\n"
    "2 2 4 3 8 7\n"
    "3 2 5 6 8 7\n"
    "4 3 8 7 5 7\n"
    "5 2 3 5 8 9\n";

TEST(TetgenRead, CubeWithAttributesMarkersRegions) {
  Result<TetMesh> m = parse_tetgen(kCubeNode, kCubeEle, "cube.node", "cube.ele");
  ASSERT_TRUE(m.ok()) << m.status().to_string();
  EXPECT_EQ(m->num_nodes(), 8);
  EXPECT_EQ(m->num_tets(), 5);
  ASSERT_EQ(m->node_markers.size(), 8u);
  EXPECT_EQ(m->node_markers[0], 1);
  EXPECT_EQ(m->node_markers[7], 0);
  ASSERT_EQ(m->node_attributes.cols(), 1);
  EXPECT_EQ(m->node_attributes(3, 0), 0.5);
  ASSERT_EQ(m->tet_regions.size(), 5u);
  EXPECT_EQ(m->tet_regions[4], 9);
  EXPECT_EQ(m->nodes(7, 2), 1.0);
  // Every tet positive after reading; the five tets fill the unit cube (volume 1, exact).
  double total = 0;
  for (Eigen::Index t = 0; t < m->num_tets(); ++t) {
    EXPECT_GT(tet_signed_volume(*m, t), 0) << t;
    total += tet_signed_volume(*m, t);
  }
  EXPECT_NEAR(total, 1.0, 1e-15);
}

TEST(TetgenRead, ZeroBasedIndices) {
  const std::string node = "4 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n";
  const std::string ele = "1 4 0\n0 0 1 2 3\n";
  Result<TetMesh> m = parse_tetgen(node, ele, "a.node", "a.ele");
  ASSERT_TRUE(m.ok()) << m.status().to_string();
  EXPECT_EQ(m->tets(0, 0), 0);
  EXPECT_NEAR(tet_signed_volume(*m, 0), 1.0 / 6.0, 1e-15);
  // One-based node numbering must not accept index 0 in the .ele.
  const std::string node1 = "4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n";
  Result<TetMesh> bad = parse_tetgen(node1, ele, "b.node", "b.ele");
  ASSERT_FALSE(bad.ok());
  EXPECT_THAT(bad.status().message(), HasSubstr("b.ele:2:"));
  EXPECT_THAT(bad.status().message(), HasSubstr("out of range"));
}

// TetGen 1.5.0's own output (tetgen -pq1.414a0.1 example.poly, ../shared/data/fem/tetgen): the
// counts are in tetgen_1.5.0_reference_counts.txt (482 points, 1533 tetrahedra).
TEST(TetgenRead, ReferenceOutputOfTetgen) {
  Result<TetMesh> m = read_tetgen(shared_data("fem/tetgen/example_pq1.414a0.1/example.1.node"));
  ASSERT_TRUE(m.ok()) << m.status().to_string();
  EXPECT_EQ(m->num_nodes(), 482);
  EXPECT_EQ(m->num_tets(), 1533);
  EXPECT_EQ(m->node_markers.size(), 482u);
  for (Eigen::Index t = 0; t < m->num_tets(); ++t) ASSERT_GT(tet_signed_volume(*m, t), 0) << t;
}

TEST(TetgenWrite, RoundTripIsExact) {
  Result<TetMesh> m = parse_tetgen(kCubeNode, kCubeEle, "cube.node", "cube.ele");
  ASSERT_TRUE(m.ok());
  m->nodes(0, 0) = 0.1 + 0.2;  // a double with a long shortest representation
  ScratchDir dir;
  ASSERT_TRUE(write_tetgen(dir / "cube", *m).ok());
  Result<TetMesh> back = read_tetgen(dir / "cube.ele");
  ASSERT_TRUE(back.ok()) << back.status().to_string();
  EXPECT_EQ(back->nodes, m->nodes);
  EXPECT_EQ(back->tets, m->tets);
  EXPECT_EQ(back->tet_regions, m->tet_regions);
  EXPECT_EQ(back->node_markers, m->node_markers);
  EXPECT_EQ(back->node_attributes, m->node_attributes);
}

TEST(TetgenWrite, RefusesBadMeshAndLeavesNoFile) {
  TetMesh m;
  m.nodes.resize(4, 3);
  m.nodes << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  m.tets.resize(1, 4);
  m.tets << 0, 1, 2, 4;  // index 4 out of range
  ScratchDir dir;
  Status s = write_tetgen(dir / "bad", m);
  EXPECT_FALSE(s.ok());
  EXPECT_THAT(s.message(), HasSubstr("out of range"));
  EXPECT_FALSE(std::filesystem::exists(dir / "bad.node"));
  EXPECT_FALSE(std::filesystem::exists(dir / "bad.ele"));
}

struct Malformed {
  std::string node;
  std::string ele;
  std::string expect;  // substring of the message, including FILE:LINE
};

class TetgenMalformed : public ::testing::TestWithParam<Malformed> {};

TEST_P(TetgenMalformed, ClearError) {
  const Malformed& c = GetParam();
  Result<TetMesh> m = parse_tetgen(c.node, c.ele, "m.node", "m.ele");
  ASSERT_FALSE(m.ok()) << "accepted:\n" << c.node << "\n" << c.ele;
  EXPECT_EQ(m.status().code(), StatusCode::kInvalidArgument);
  EXPECT_THAT(m.status().message(), HasSubstr(c.expect));
}

const std::string kGoodNode = "4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n";
const std::string kGoodEle = "1 4 0\n1 1 2 3 4\n";
// A comment line appended where a truncated record would otherwise be caught by the byte-count
// check before the record itself is read.
const std::string kPad = "# padding padding padding padding\n";

INSTANTIATE_TEST_SUITE_P(
    Cases, TetgenMalformed,
    ::testing::Values(
        Malformed{"", kGoodEle, "m.node:1: file ends before the header"},
        Malformed{"# only a comment\n", kGoodEle, "m.node:2: file ends before the header"},
        Malformed{"4 2 0 0\n", kGoodEle, "m.node:1: dimension 2, expected 3"},
        Malformed{"-4 3 0 0\n", kGoodEle, "negative number of points"},
        Malformed{"4 3 0 2\n", kGoodEle, "boundary marker flag 2"},
        Malformed{"4 3 999 0\n", kGoodEle, "attribute count 999"},
        Malformed{"1000000 3 0 0\n1 0 0 0\n", kGoodEle, "m.node:1: header declares 1000000 points"},
        Malformed{"4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n" + kPad, kGoodEle,
                  "m.node:6: file ends before point 4 of 4"},
        Malformed{"4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0\n" + kPad, kGoodEle,
                  "m.node:5: line ends before coordinate z of point 4"},
        Malformed{"4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 nan\n", kGoodEle,
                  "m.node:5: coordinate z of point 4 is not finite"},
        Malformed{"4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1e999\n", kGoodEle, "not finite"},
        Malformed{"4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 x 0\n4 0 0 1\n", kGoodEle,
                  "m.node:4: expected coordinate y of point 3 (a number), got 'x'"},
        Malformed{"4 3 0 0\n1 0 0 0\n3 1 0 0\n3 0 1 0\n4 0 0 1\n", kGoodEle,
                  "m.node:3: point index 3, expected 2"},
        Malformed{"4 3 0 0\n2 0 0 0\n3 1 0 0\n4 0 1 0\n5 0 0 1\n", kGoodEle,
                  "first point has index 2"},
        Malformed{"4 3 0 0\n1 0 0 0 7\n2 1 0 0\n3 0 1 0\n4 0 0 1\n", kGoodEle,
                  "m.node:2: unexpected '7' after point 1"},
        Malformed{"4 3 0 1\n1 0 0 0\n2 1 0 0 1\n3 0 1 0 1\n4 0 0 1 1\n" + kPad, kGoodEle,
                  "m.node:2: line ends before the boundary marker of point 1"},
        Malformed{kGoodNode + "5 1 1 1\n", kGoodEle, "m.node:6: unexpected '5' after the 4"},
        Malformed{kGoodNode, "", "m.ele:1: file ends before the header"},
        Malformed{kGoodNode, "1 10 0\n1 1 2 3 4 5 6 7 8 9 10\n", "only linear (4-node)"},
        Malformed{kGoodNode, "0 4 0\n", "number of tetrahedra 0"},
        Malformed{kGoodNode, "1 4 2\n1 1 2 3 4 1 1\n", "region attribute count 2"},
        Malformed{kGoodNode, "100 4 0\n1 1 2 3 4\n", "m.ele:1: header declares 100 tetrahedra"},
        Malformed{kGoodNode, "2 4 0\n1 1 2 3 4\n" + kPad,
                  "m.ele:4: file ends before tetrahedron 2 of 2"},
        Malformed{kGoodNode, "1 4 0\n1 1 2 3\n" + kPad, "m.ele:2: line ends before node 3"},
        Malformed{kGoodNode, "1 4 0\n1 1 2 3 5\n", "m.ele:2: tetrahedron 1: node index 5 is out"},
        Malformed{kGoodNode, "1 4 0\n1 1 2 3 -1\n", "out of range"},
        Malformed{kGoodNode, "1 4 0\n1 1 2 3 99999999999999999999\n", "(an integer)"},
        Malformed{kGoodNode, "1 4 1\n1 1 2 3 4 0.5\n", "region attribute 0.5 is not an integer"},
        Malformed{kGoodNode, "1 4 0\n1 1 2 3 3\n", "m.ele:2: tetrahedron 1 is degenerate"},
        Malformed{"4 3 0 0\n1 0 0 0\n2 1 0 0\n3 2 0 0\n4 3 0 0\n", kGoodEle, "degenerate"},
        Malformed{kGoodNode, "1 4 0\n1 1 2 3 4\n2 1 2 3 4\n", "m.ele:3: unexpected '2'"}));

TEST(TetgenRead, MissingFileIsNotFound) {
  ScratchDir dir;
  Result<TetMesh> m = read_tetgen(dir / "nothing");
  ASSERT_FALSE(m.ok());
  EXPECT_EQ(m.status().code(), StatusCode::kNotFound);
}

TEST(Vtu, WritesArraysAndCells) {
  Result<TetMesh> m = parse_tetgen(kCubeNode, kCubeEle, "cube.node", "cube.ele");
  ASSERT_TRUE(m.ok());
  VtuData data;
  data.point_data.push_back({"displacement_m", 3, std::vector<double>(24, 0.25)});
  data.cell_data.push_back({"youngs_pa", 1, {1e6, 2e6, 3e6, 4e6, 5e6}});
  Result<std::string> text = format_vtu(*m, data);
  ASSERT_TRUE(text.ok()) << text.status().to_string();
  EXPECT_THAT(*text, HasSubstr("<VTKFile type=\"UnstructuredGrid\""));
  EXPECT_THAT(*text, HasSubstr("NumberOfPoints=\"8\" NumberOfCells=\"5\""));
  EXPECT_THAT(*text, HasSubstr("Name=\"displacement_m\" NumberOfComponents=\"3\""));
  EXPECT_THAT(*text, HasSubstr("Name=\"youngs_pa\" NumberOfComponents=\"1\""));
  EXPECT_THAT(*text, HasSubstr("Name=\"region\""));
  EXPECT_THAT(*text, HasSubstr("Name=\"marker\""));
  EXPECT_THAT(*text, HasSubstr("\n          5e+06\n"));
  EXPECT_THAT(*text, HasSubstr("\n          20\n"));  // last offset: 4 × 5
  // One VTK_TETRA (10) per cell.
  std::size_t tens = 0;
  for (std::size_t p = text->find("          10\n"); p != std::string::npos;
       p = text->find("          10\n", p + 1))
    ++tens;
  EXPECT_EQ(tens, 5u);
  ScratchDir dir;
  ASSERT_TRUE(write_vtu(dir / "cube.vtu", *m, data).ok());
  Result<std::string> back = read_file(dir / "cube.vtu");
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(*back, *text);
}

TEST(Vtu, RefusesWrongSizesNaNAndDuplicates) {
  Result<TetMesh> m = parse_tetgen(kCubeNode, kCubeEle, "cube.node", "cube.ele");
  ASSERT_TRUE(m.ok());
  VtuData wrong;
  wrong.cell_data.push_back({"e", 1, {1, 2, 3}});
  EXPECT_THAT(format_vtu(*m, wrong).status().message(), HasSubstr("has 3 values, expected 5"));
  VtuData nan;
  nan.point_data.push_back({"d", 1, std::vector<double>(8, std::nan(""))});
  EXPECT_THAT(format_vtu(*m, nan).status().message(), HasSubstr("not finite"));
  VtuData dup;
  dup.cell_data.push_back({"e", 1, std::vector<double>(5, 1)});
  dup.cell_data.push_back({"e", 1, std::vector<double>(5, 1)});
  EXPECT_THAT(format_vtu(*m, dup).status().message(), HasSubstr("given twice"));
  VtuData bad_name;
  bad_name.cell_data.push_back({"a\"b", 1, std::vector<double>(5, 1)});
  EXPECT_FALSE(format_vtu(*m, bad_name).ok());
  ScratchDir dir;
  EXPECT_FALSE(write_vtu(dir / "x.vtu", *m, wrong).ok());
  EXPECT_FALSE(std::filesystem::exists(dir / "x.vtu"));
}

}  // namespace
}  // namespace hc
