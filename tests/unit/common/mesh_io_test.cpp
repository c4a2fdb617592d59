// Mesh readers on small hand-written files with known counts, writer round trips, and the 3MF
// writer checked by a third-party reader (lib3mf).
#include "common/mesh_io.h"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <bit>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "common/file_io.h"
#include "mesh_test_util.h"
#include "test_data.h"

namespace hc {
namespace {

using testing::gzip;
using ::testing::HasSubstr;
using testing::signed_volume;

Result<TriangleMesh> parse(std::string_view text, MeshFormat format,
                           const MeshReadOptions& options = {}) {
  return parse_mesh(text, format, "test", options);
}

// Unit tetrahedron with awkward coordinates (0.1 and 1/3 are not exact in binary), outward faces.
TriangleMesh tetrahedron() {
  TriangleMesh m;
  m.vertices.resize(4, 3);
  m.vertices << 0.1, 0.0, 0.0,  //
      1.0, 0.0, 0.0,            //
      0.0, 1.0 / 3.0, 0.0,      //
      0.0, 0.0, 1e-7;
  m.triangles.resize(4, 3);
  m.triangles << 0, 2, 1,  //
      0, 1, 3,             //
      0, 3, 2,             //
      1, 2, 3;
  return m;
}

// Builds binary files value by value in either byte order.
class Bytes {
 public:
  explicit Bytes(bool big_endian = false) : big_(big_endian) {}
  template <typename T>
  Bytes& put(T v) {
    char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    if (big_ == (std::endian::native == std::endian::little)) std::reverse(b, b + sizeof(T));
    s_.append(b, sizeof(T));
    return *this;
  }
  Bytes& text(std::string_view t) {
    s_.append(t);
    return *this;
  }
  const std::string& str() const { return s_; }

 private:
  bool big_;
  std::string s_;
};

// A binary STL of the given triangles (9 floats each); the header starts with "solid" on purpose.
std::string binary_stl(const std::vector<std::array<float, 9>>& tris) {
  Bytes b;
  std::string header = "solid looks like ASCII but is binary";
  header.resize(80, ' ');
  b.text(header).put(static_cast<std::uint32_t>(tris.size()));
  for (const auto& t : tris) {
    b.put(0.f).put(0.f).put(0.f);
    for (float f : t) b.put(f);
    b.put(std::uint16_t{0});
  }
  return b.str();
}

// ---------------------------------------------------------------------------------------------
TEST(MeshIoFormat, FromPathIsCaseInsensitiveAndKnowsPlyGz) {
  EXPECT_EQ(*mesh_format_from_path("a/b.OBJ"), MeshFormat::kObj);
  EXPECT_EQ(*mesh_format_from_path("x.stl"), MeshFormat::kStl);
  EXPECT_EQ(*mesh_format_from_path("x.ply"), MeshFormat::kPly);
  EXPECT_EQ(*mesh_format_from_path("x.PLY.GZ"), MeshFormat::kPly);
  EXPECT_EQ(*mesh_format_from_path("x.off"), MeshFormat::kOff);
  EXPECT_EQ(*mesh_format_from_path("x.3mf"), MeshFormat::k3mf);
  const auto bad = mesh_format_from_path("x.step");
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), StatusCode::kUnsupported);
  EXPECT_THAT(bad.status().message(), HasSubstr("x.step"));
  EXPECT_FALSE(mesh_format_from_path("x.stl.gz").ok());
  EXPECT_FALSE(mesh_format_from_path(".obj").ok());  // a hidden file named "obj", no extension
}

TEST(MeshIoFormat, ToString) {
  EXPECT_EQ(to_string(MeshFormat::kObj), "obj");
  EXPECT_EQ(to_string(MeshFormat::kStl), "stl");
  EXPECT_EQ(to_string(MeshFormat::kPly), "ply");
  EXPECT_EQ(to_string(MeshFormat::kOff), "off");
  EXPECT_EQ(to_string(MeshFormat::k3mf), "3mf");
}

TEST(MeshIoFormat, ReadMeshRefusesStdinAnd3mfAndReportsMissingFile) {
  EXPECT_EQ(read_mesh("-").status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(read_mesh("model.3mf").status().code(), StatusCode::kUnsupported);
  const auto missing = read_mesh("/nonexistent/dir/model.obj");
  EXPECT_EQ(missing.status().code(), StatusCode::kNotFound);
}

// ---------------------------------------------------------------------------------------------
TEST(MeshIoObj, ReadsTrianglesAndFanTriangulatesPolygons) {
  // A unit cube: 8 vertices, 6 quads -> 12 triangles.
  constexpr std::string_view kCube = R"(# cube
o cube
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
v 1 0 1
v 1 1 1
v 0 1 1
f 1 4 3 2
f 5 6 7 8
f 1 2 6 5
f 2 3 7 6
f 3 4 8 7
f 4 1 5 8
)";
  auto m = parse(kCube, MeshFormat::kObj);
  ASSERT_TRUE(m.ok()) << m.status().to_string();
  EXPECT_EQ(m->num_vertices(), 8);
  EXPECT_EQ(m->num_triangles(), 12);
  EXPECT_NEAR(signed_volume(*m).signed_sum, 1.0, 1e-15);  // analytic: unit cube
  // Fan from the first corner: (1 4 3 2) -> (0 3 2), (0 2 1).
  EXPECT_EQ(m->triangles.row(0), Eigen::RowVector3i(0, 3, 2));
  EXPECT_EQ(m->triangles.row(1), Eigen::RowVector3i(0, 2, 1));
}

TEST(MeshIoObj, AcceptsEveryFaceVertexFormAndIgnoresOtherStatements) {
  constexpr std::string_view kText =
      "mtllib x.mtl\r\n"
      "v 0 0 0\r\n"
      "v +1.5 0 0 1.0\r\n"         // optional w, leading '+'
      "v 0 1e0 0 0.5 0.5 0.5\r\n"  // vertex colours
      "v 0 0 -1E+0\r\n"
      "vt 0 0\nvt 1 0\nvt 0 1\n"
      "vn 0 0 1\n"
      "g group\ns 1\nusemtl red\n"
      "f 1 2 3   # trailing comment\n"
      "f 1/1 2/2 4/3\n"
      "f 1/1/1 3/3/1 4/1/1\n"
      "f 2//1 3//1 4//1\n"
      "l 1 2\n";
  auto m = parse(kText, MeshFormat::kObj);
  ASSERT_TRUE(m.ok()) << m.status().to_string();
  EXPECT_EQ(m->num_vertices(), 4);
  EXPECT_EQ(m->num_triangles(), 4);
  EXPECT_EQ(m->vertices(1, 0), 1.5);
  EXPECT_EQ(m->vertices(3, 2), -1.0);
  EXPECT_EQ(m->triangles.row(1), Eigen::RowVector3i(0, 1, 3));
  EXPECT_EQ(m->triangles.row(3), Eigen::RowVector3i(1, 2, 3));
}

TEST(MeshIoObj, NegativeIndicesAreRelativeToVerticesReadSoFar) {
  constexpr std::string_view kText =
      "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
      "f -3 -2 -1\n"
      "v 0 0 1\n"
      "f -4 -3 -1\n";
  auto m = parse(kText, MeshFormat::kObj);
  ASSERT_TRUE(m.ok()) << m.status().to_string();
  EXPECT_EQ(m->triangles.row(0), Eigen::RowVector3i(0, 1, 2));
  EXPECT_EQ(m->triangles.row(1), Eigen::RowVector3i(0, 1, 3));
}

TEST(MeshIoObj, KeepsUnreferencedVerticesAndAllowsForwardReferences) {
  auto m = parse("f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 5 5\n", MeshFormat::kObj);
  ASSERT_TRUE(m.ok()) << m.status().to_string();
  EXPECT_EQ(m->num_vertices(), 4);
  EXPECT_EQ(m->num_triangles(), 1);
}

// ---------------------------------------------------------------------------------------------
TEST(MeshIoOff, ReadsCommentsBlankLinesAndCountsOnTheHeaderLine) {
  constexpr std::string_view kText = R"(# a tetrahedron
OFF 4 4 6

# vertices
0 0 0
1 0 0   # trailing comment
0 1 0
0 0 1
3 0 2 1
3 0 1 3

3 0 3 2
3 1 2 3
)";
  auto m = parse(kText, MeshFormat::kOff);
  ASSERT_TRUE(m.ok()) << m.status().to_string();
  EXPECT_EQ(m->num_vertices(), 4);
  EXPECT_EQ(m->num_triangles(), 4);
  EXPECT_NEAR(signed_volume(*m).signed_sum, 1.0 / 6.0, 1e-15);  // analytic: unit corner tetrahedron
}

TEST(MeshIoOff, IgnoresExtraVertexColumnsAndFaceColoursAndFansPolygons) {
  // COFF: RGBA per vertex; faces carry colours; one quad.
  constexpr std::string_view kText =
      "COFF\n5 2 0\n"
      "0 0 0 255 0 0 255\n"
      "1 0 0 0 255 0 255\n"
      "1 1 0 0 0 255 255\n"
      "0 1 0 10 10 10 255\n"
      "9 9 9 1 2 3 4\n"
      "4 0 1 2 3 0.5 0.5 0.5\n"
      "3 0 1 4 1 0 0\n";
  auto m = parse(kText, MeshFormat::kOff);
  ASSERT_TRUE(m.ok()) << m.status().to_string();
  EXPECT_EQ(m->num_vertices(), 5);
  EXPECT_EQ(m->num_triangles(), 3);
  EXPECT_EQ(m->vertices(4, 2), 9.0);
  EXPECT_EQ(m->triangles.row(1), Eigen::RowVector3i(0, 2, 3));

  auto n = parse("NOFF\n3 1 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n3 0 1 2\n", MeshFormat::kOff);
  ASSERT_TRUE(n.ok()) << n.status().to_string();
  EXPECT_EQ(n->num_triangles(), 1);
}

TEST(MeshIoOff, RefusesBinaryAnd4dVariants) {
  const auto bin = parse("OFF BINARY\n", MeshFormat::kOff);
  ASSERT_FALSE(bin.ok());
  EXPECT_THAT(bin.status().message(), HasSubstr("binary OFF"));
  const auto four = parse("4OFF\n1 0 0\n0 0 0 0\n", MeshFormat::kOff);
  ASSERT_FALSE(four.ok());
  EXPECT_THAT(four.status().message(), HasSubstr("3-D"));
}

// ---------------------------------------------------------------------------------------------
constexpr std::string_view kAsciiStlTwoFacets =
    "solid square\n"
    "  facet normal 0 0 1\n"
    "    outer loop\n"
    "      vertex 0 0 0\n"
    "      vertex 1 0 0\n"
    "      vertex 1 1 0\n"
    "    endloop\n"
    "  endfacet\n"
    "  facet normal nan nan nan\n"  // some exporters write this for any facet; ignored
    "    outer loop\n"
    "      vertex 0 0 0\n"
    "      vertex 1 1 0\n"
    "      vertex 0 1 0\n"
    "    endloop\n"
    "  endfacet\n"
    "endsolid square\n";

TEST(MeshIoStl, ReadsAsciiAndWeldsSharedCorners) {
  auto m = parse(kAsciiStlTwoFacets, MeshFormat::kStl);
  ASSERT_TRUE(m.ok()) << m.status().to_string();
  EXPECT_EQ(m->num_triangles(), 2);
  EXPECT_EQ(m->num_vertices(), 4);
  EXPECT_EQ(m->triangles.row(1), Eigen::RowVector3i(0, 2, 3));

  MeshReadOptions raw;
  raw.weld_stl_vertices = false;
  auto soup = parse(kAsciiStlTwoFacets, MeshFormat::kStl, raw);
  ASSERT_TRUE(soup.ok()) << soup.status().to_string();
  EXPECT_EQ(soup->num_vertices(), 6);
}

TEST(MeshIoStl, ReadsUtf8SolidNames) {
  std::string text(kAsciiStlTwoFacets);
  text.replace(0, std::string_view("solid square").size(), "solid W\xc3\xbcrfel \xe2\x80\x94 1");
  auto m = parse(text, MeshFormat::kStl);
  ASSERT_TRUE(m.ok()) << m.status().to_string();
  EXPECT_EQ(m->num_triangles(), 2);
}

TEST(MeshIoStl, ReadsSeveralSolidsAndCrLf) {
  std::string two(kAsciiStlTwoFacets);
  two += kAsciiStlTwoFacets;
  std::string crlf;
  for (char c : two) {
    if (c == '\n') crlf += '\r';
    crlf += c;
  }
  auto m = parse(crlf, MeshFormat::kStl);
  ASSERT_TRUE(m.ok()) << m.status().to_string();
  EXPECT_EQ(m->num_triangles(), 4);
  EXPECT_EQ(m->num_vertices(), 4);
}

TEST(MeshIoStl, ReadsBinaryEvenWhenTheHeaderStartsWithSolid) {
  const std::string stl = binary_stl({{0, 0, 0, 1, 0, 0, 1, 1, 0}, {0, 0, 0, 1, 1, 0, 0, 1, 0}});
  ASSERT_EQ(stl.size(), 84u + 2 * 50u);
  auto m = parse(stl, MeshFormat::kStl);
  ASSERT_TRUE(m.ok()) << m.status().to_string();
  EXPECT_EQ(m->num_triangles(), 2);
  EXPECT_EQ(m->num_vertices(), 4);
  EXPECT_EQ(m->vertices.row(2), Eigen::RowVector3d(1, 1, 0));

  MeshReadOptions raw;
  raw.weld_stl_vertices = false;
  auto soup = parse(stl, MeshFormat::kStl, raw);
  ASSERT_TRUE(soup.ok());
  EXPECT_EQ(soup->num_vertices(), 6);
  EXPECT_EQ(soup->triangles.row(1), Eigen::RowVector3i(3, 4, 5));
}

TEST(MeshIoStl, WeldsOnlyBitIdenticalPositions) {
  // -0.0 and 0.0 compare equal but are different bits: kept apart, as slicers do.
  const std::string stl = binary_stl({{0, 0, 0, 1, 0, 0, 0, 1, 0}, {-0.f, 0, 0, 1, 0, 0, 0, 0, 1}});
  auto m = parse(stl, MeshFormat::kStl);
  ASSERT_TRUE(m.ok()) << m.status().to_string();
  EXPECT_EQ(m->num_vertices(), 5);
}

TEST(MeshIoStl, WeldingScalesToManyVertices) {
  // A 300 x 300 grid of quads: 180,000 triangles, 301^2 distinct corners; forces table growth.
  constexpr int kN = 300;
  std::vector<std::array<float, 9>> tris;
  for (int i = 0; i < kN; ++i) {
    for (int j = 0; j < kN; ++j) {
      const float x0 = static_cast<float>(i), x1 = static_cast<float>(i + 1);
      const float y0 = static_cast<float>(j), y1 = static_cast<float>(j + 1);
      tris.push_back({x0, y0, 0, x1, y0, 0, x1, y1, 0});
      tris.push_back({x0, y0, 0, x1, y1, 0, x0, y1, 0});
    }
  }
  auto m = parse(binary_stl(tris), MeshFormat::kStl);
  ASSERT_TRUE(m.ok()) << m.status().to_string();
  EXPECT_EQ(m->num_triangles(), 2 * kN * kN);
  EXPECT_EQ(m->num_vertices(), (kN + 1) * (kN + 1));
}

// ---------------------------------------------------------------------------------------------
constexpr std::string_view kAsciiPly = R"(ply
format ascii 1.0
comment made by hand
obj_info nothing
element vertex 4
property float nx
property float z
property uchar red
property double x
property float y
element material 2
property list uchar float weights
property int id
element face 2
property uchar flags
property list uchar int vertex_indices
property float quality
end_header
0 0 1 0 0
0 0 2 1 0
0 0 3 1 1
0 0 4 0 1
3 0.1 0.2 0.3 7
0 8
0 4 0 1 2 3 0.5
1 3 0 2 1 0.25
)";

TEST(MeshIoPly, ReadsAsciiWithPropertiesInAnyOrderAndSkipsOtherElements) {
  auto m = parse(kAsciiPly, MeshFormat::kPly);
  ASSERT_TRUE(m.ok()) << m.status().to_string();
  EXPECT_EQ(m->num_vertices(), 4);
  EXPECT_EQ(m->num_triangles(), 3);  // a quad and a triangle
  EXPECT_EQ(m->vertices.row(2), Eigen::RowVector3d(1, 1, 0));
  EXPECT_EQ(m->triangles.row(2), Eigen::RowVector3i(0, 2, 1));
}

// The same mesh in binary: every scalar type for something, `vertex_index` as the list name.
std::string binary_ply(bool big_endian) {
  Bytes b(big_endian);
  b.text(fmt::format("ply\nformat {} 1.0\n",
                     big_endian ? "binary_big_endian" : "binary_little_endian"))
      .text("element vertex 4\n")
      .text("property int16 s\nproperty float64 z\nproperty char c\nproperty float x\n")
      .text("property ushort u\nproperty int y\nproperty uint w\n")
      .text("element edge 1\nproperty list ushort uint ends\nproperty uchar k\n")
      .text(
          "element face 2\nproperty list int8 uint16 vertex_index\nproperty list uint32 double "
          "uv\n")
      .text("end_header\n");
  const double xyz[4][3] = {{0, 0, 0.5}, {1, 0, 0.5}, {1, 1, 0.5}, {0, 1, 0.5}};
  for (const auto& v : xyz)
    b.put(std::int16_t{-1})
        .put(v[2])
        .put(std::int8_t{-2})
        .put(static_cast<float>(v[0]))
        .put(std::uint16_t{3})
        .put(static_cast<std::int32_t>(v[1]))
        .put(std::uint32_t{4});
  b.put(std::uint16_t{2}).put(std::uint32_t{0}).put(std::uint32_t{1}).put(std::uint8_t{9});
  b.put(std::int8_t{4})
      .put(std::uint16_t{0})
      .put(std::uint16_t{1})
      .put(std::uint16_t{2})
      .put(std::uint16_t{3});
  b.put(std::uint32_t{1}).put(0.5);
  b.put(std::int8_t{3}).put(std::uint16_t{3}).put(std::uint16_t{2}).put(std::uint16_t{0});
  b.put(std::uint32_t{0});
  return b.str();
}

TEST(MeshIoPly, ReadsBinaryLittleAndBigEndianWithAnyPropertyTypes) {
  for (const bool big : {false, true}) {
    SCOPED_TRACE(big ? "big endian" : "little endian");
    auto m = parse(binary_ply(big), MeshFormat::kPly);
    ASSERT_TRUE(m.ok()) << m.status().to_string();
    EXPECT_EQ(m->num_vertices(), 4);
    EXPECT_EQ(m->num_triangles(), 3);
    EXPECT_EQ(m->vertices.row(1), Eigen::RowVector3d(1, 0, 0.5));
    EXPECT_EQ(m->triangles.row(1), Eigen::RowVector3i(0, 2, 3));
    EXPECT_EQ(m->triangles.row(2), Eigen::RowVector3i(3, 2, 0));
  }
}

TEST(MeshIoPly, ReadsGzipByMagicNotByName) {
  auto m = parse(gzip(kAsciiPly), MeshFormat::kPly);
  ASSERT_TRUE(m.ok()) << m.status().to_string();
  EXPECT_EQ(m->num_triangles(), 3);
  const std::string bin = binary_ply(false);
  auto b = parse(gzip(bin), MeshFormat::kPly);
  ASSERT_TRUE(b.ok()) << b.status().to_string();
  EXPECT_EQ(b->num_triangles(), 3);
}

TEST(MeshIoPly, ReadsConcatenatedGzipMembersAsOneStream) {
  // RFC 1952 §2.2: a gzip file is a series of members; cut inside the header on purpose.
  const std::string plain(kAsciiPly);
  const std::string gz = gzip(plain.substr(0, 30)) + gzip(plain.substr(30));
  auto m = parse(gz, MeshFormat::kPly);
  ASSERT_TRUE(m.ok()) << m.status().to_string();
  EXPECT_EQ(m->num_triangles(), 3);
}

TEST(MeshIoPly, WriteMeshGzipsPlyGzAndReadsItBack) {
  testing::ScratchDir dir;
  ASSERT_TRUE(write_mesh(dir / "t.ply.gz", tetrahedron()).ok());
  auto raw = read_file(dir / "t.ply.gz");
  ASSERT_TRUE(raw.ok());
  ASSERT_GE(raw->size(), 2u);
  EXPECT_EQ(static_cast<unsigned char>((*raw)[0]), 0x1f);  // gzip magic (RFC 1952)
  EXPECT_EQ(static_cast<unsigned char>((*raw)[1]), 0x8b);
  auto back = read_mesh(dir / "t.ply.gz");
  ASSERT_TRUE(back.ok()) << back.status().to_string();
  EXPECT_EQ(back->vertices, tetrahedron().vertices);
}

// ---------------------------------------------------------------------------------------------
struct RoundTrip {
  std::string file;
  bool binary;
  bool exact;  // double precision formats give back the very same doubles
};

// STL numbers vertices in first-seen corner order: compare triangle corners, not vertex rows.
void expect_same_corners_as_floats(const TriangleMesh& in, const TriangleMesh& out) {
  for (Eigen::Index t = 0; t < in.num_triangles(); ++t)
    for (int c = 0; c < 3; ++c)
      for (int k = 0; k < 3; ++k)
        EXPECT_EQ(out.vertices(out.triangles(t, c), k),
                  static_cast<double>(static_cast<float>(in.vertices(in.triangles(t, c), k))))
            << "triangle " << t << " corner " << c;
}

class MeshIoRoundTrip : public ::testing::TestWithParam<RoundTrip> {};

TEST_P(MeshIoRoundTrip, WriteThenReadKeepsTheMesh) {
  const RoundTrip& rt = GetParam();
  testing::ScratchDir dir;
  const TriangleMesh in = tetrahedron();
  MeshWriteOptions wo;
  wo.binary = rt.binary;
  const auto path = dir / rt.file;
  ASSERT_TRUE(write_mesh(path, in, wo).ok());
  auto out = read_mesh(path);
  ASSERT_TRUE(out.ok()) << out.status().to_string();
  ASSERT_EQ(out->num_vertices(), in.num_vertices());
  ASSERT_EQ(out->num_triangles(), in.num_triangles());
  if (rt.exact) {
    EXPECT_EQ(out->triangles, in.triangles);
    EXPECT_EQ(out->vertices, in.vertices);
  } else {
    expect_same_corners_as_floats(in, *out);
  }
  // No temporary files left next to the output.
  int files = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir.path())) ++files;
  EXPECT_EQ(files, 1);
}

INSTANTIATE_TEST_SUITE_P(
    MeshIoAllWriters, MeshIoRoundTrip,
    ::testing::Values(RoundTrip{"m.obj", true, true}, RoundTrip{"m.off", true, true},
                      RoundTrip{"m.ply", true, true}, RoundTrip{"m.ply", false, true},
                      RoundTrip{"m.ply.gz", true, true}, RoundTrip{"m.ply.gz", false, true},
                      RoundTrip{"m.stl", true, false}),
    [](const ::testing::TestParamInfo<RoundTrip>& param_info) {
      const RoundTrip& p = param_info.param;
      std::string n = p.file + (p.binary ? "_binary" : "_ascii");
      for (char& c : n)
        if (c == '.') c = '_';
      return n;
    });

TEST(MeshIoWrite, AsciiStlKeepsDoublesAndHasUnitNormals) {
  const TriangleMesh in = tetrahedron();
  MeshWriteOptions wo;
  wo.binary = false;
  auto text = format_mesh(in, MeshFormat::kStl, wo);
  ASSERT_TRUE(text.ok());
  EXPECT_TRUE(text->starts_with("solid "));
  EXPECT_THAT(*text, HasSubstr("facet normal 0 0 -1\n"));  // first facet lies in z = 0, facing down
  auto out = parse(*text, MeshFormat::kStl);
  ASSERT_TRUE(out.ok()) << out.status().to_string();
  ASSERT_EQ(out->num_vertices(), 4);
  // ASCII carries the shortest round-trip doubles, so corners come back exactly.
  for (Eigen::Index t = 0; t < in.num_triangles(); ++t)
    for (int c = 0; c < 3; ++c)
      EXPECT_EQ(out->vertices.row(out->triangles(t, c)), in.vertices.row(in.triangles(t, c)));
}

TEST(MeshIoWrite, BinaryStlLayoutAndNormals) {
  const TriangleMesh in = tetrahedron();
  auto bytes = format_mesh(in, MeshFormat::kStl);
  ASSERT_TRUE(bytes.ok());
  ASSERT_EQ(bytes->size(), 84u + 4 * 50u);
  std::uint32_t n = 0;
  std::memcpy(&n, bytes->data() + 80, 4);
  EXPECT_EQ(n, 4u);
  float normal[3];
  std::memcpy(normal, bytes->data() + 84, 12);
  EXPECT_EQ(normal[0], 0.f);
  EXPECT_EQ(normal[1], 0.f);
  EXPECT_EQ(normal[2], -1.f);
}

TEST(MeshIoWrite, RefusesInvalidMeshesAndLeavesNoFile) {
  testing::ScratchDir dir;
  TriangleMesh bad = tetrahedron();
  bad.triangles(2, 1) = 4;
  for (const char* name : {"b.obj", "b.stl", "b.ply", "b.ply.gz", "b.off", "b.3mf"}) {
    const Status s = write_mesh(dir / name, bad);
    EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << name;
    EXPECT_THAT(s.message(), HasSubstr("triangle 2")) << name;
    EXPECT_FALSE(std::filesystem::exists(dir / name)) << name;
  }
  TriangleMesh nan = tetrahedron();
  nan.vertices(1, 1) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(write_mesh(dir / "n.stl", nan).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(format_mesh(nan, MeshFormat::kObj).status().code(), StatusCode::kInvalidArgument);
  EXPECT_TRUE(std::filesystem::is_empty(dir.path()));
}

TEST(MeshIoWrite, FailsCleanlyIntoAMissingDirectory) {
  testing::ScratchDir dir;
  EXPECT_FALSE(write_mesh(dir / "no/such/dir/m.stl", tetrahedron()).ok());
  EXPECT_FALSE(write_mesh(dir / "no/such/dir/m.3mf", tetrahedron()).ok());
  EXPECT_EQ(write_mesh(dir / "m.xyz", tetrahedron()).code(), StatusCode::kUnsupported);
}

// ---------------------------------------------------------------------------------------------
std::string read_zip_entry_names(const std::string& bytes) {
  // Local file headers (PK\3\4) carry the names; enough to see the three OPC parts are there.
  std::string names;
  for (std::size_t at = bytes.find("PK\x03\x04"); at != std::string::npos;
       at = bytes.find("PK\x03\x04", at + 4)) {
    if (at + 30 > bytes.size()) break;
    std::uint16_t len = 0;
    std::memcpy(&len, bytes.data() + at + 26, 2);
    names += bytes.substr(at + 30, len) + ";";
  }
  return names;
}

TEST(MeshIo3mf, PackageHoldsTheOpcParts) {
  auto bytes = format_mesh(tetrahedron(), MeshFormat::k3mf);
  ASSERT_TRUE(bytes.ok()) << bytes.status().to_string();
  EXPECT_TRUE(bytes->starts_with("PK"));
  const std::string names = read_zip_entry_names(*bytes);
  EXPECT_THAT(names, HasSubstr("[Content_Types].xml;"));
  EXPECT_THAT(names, HasSubstr("_rels/.rels;"));
  EXPECT_THAT(names, HasSubstr("3D/3dmodel.model;"));
}

TEST(MeshIo3mf, RefusesWhat3mfCannotHold) {
  testing::ScratchDir dir;
  MeshPart a{"a", tetrahedron(), "PLA", std::array<std::uint8_t, 4>{255, 0, 0, 255}};
  MeshPart b{"b", tetrahedron(), "PLA", std::array<std::uint8_t, 4>{0, 255, 0, 255}};
  const std::vector<MeshPart> clash{a, b};
  const Status s = write_3mf(dir / "clash.3mf", clash);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_THAT(s.message(), HasSubstr("PLA"));
  MeshPart degenerate{"d", tetrahedron(), "", std::nullopt};
  degenerate.mesh.triangles(0, 1) = degenerate.mesh.triangles(0, 0);
  EXPECT_EQ(write_3mf(dir / "d.3mf", std::span<const MeshPart>(&degenerate, 1)).code(),
            StatusCode::kInvalidArgument);
  EXPECT_EQ(write_3mf(dir / "none.3mf", {}).code(), StatusCode::kInvalidArgument);
  EXPECT_TRUE(std::filesystem::is_empty(dir.path()));
}

#if HARDCOPY_HAVE_LIB3MF
// lib3mf's C interface, wrapped just enough for the checks below.
struct Lib3mfHandle {
  NMR::PLib3MFBase* p = nullptr;
  ~Lib3mfHandle() {
    if (p != nullptr) NMR::lib3mf_release(p);
  }
};

std::string object_name(NMR::PLib3MFModelObjectResource* obj) {
  ULONG needed = 0;
  NMR::lib3mf_object_getnameutf8(obj, nullptr, 0, &needed);
  std::string s(needed + 1, '\0');
  NMR::lib3mf_object_getnameutf8(obj, s.data(), static_cast<ULONG>(s.size()), &needed);
  s.resize(std::strlen(s.c_str()));
  return s;
}

std::string material_name(NMR::PLib3MFModelBaseMaterial* m, DWORD i) {
  ULONG needed = 0;
  NMR::lib3mf_basematerial_getnameutf8(m, i, nullptr, 0, &needed);
  std::string s(needed + 1, '\0');
  NMR::lib3mf_basematerial_getnameutf8(m, i, s.data(), static_cast<ULONG>(s.size()), &needed);
  s.resize(std::strlen(s.c_str()));
  return s;
}

TEST(MeshIo3mf, Lib3mfReadsOurPartsNamesCountsAndMaterials) {
  testing::ScratchDir dir;
  TriangleMesh cube;
  {
    auto c = parse(
        "OFF\n8 6 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n1 0 1\n1 1 1\n0 1 1\n"
        "4 0 3 2 1\n4 4 5 6 7\n4 0 1 5 4\n4 1 2 6 5\n4 2 3 7 6\n4 3 0 4 7\n",
        MeshFormat::kOff);
    ASSERT_TRUE(c.ok());
    cube = *c;
  }
  const std::vector<MeshPart> parts{
      {"body & \"lid\"", cube, "PLA red", std::array<std::uint8_t, 4>{0xFF, 0x10, 0x00, 0xFF}},
      {"insert", tetrahedron(), "TPU", std::array<std::uint8_t, 4>{0x00, 0x00, 0xFF, 0x80}},
      {"second red", tetrahedron(), "PLA red", std::nullopt},
      {"bare", cube, "", std::nullopt},
  };
  const auto path = dir / "parts.3mf";
  ASSERT_TRUE(write_3mf(path, parts, units::LengthUnit::kInch).ok());

  Lib3mfHandle model, reader;
  ASSERT_EQ(NMR::lib3mf_createmodel(&model.p), 0);
  ASSERT_EQ(NMR::lib3mf_model_queryreader(model.p, "3mf", &reader.p), 0);
  ASSERT_EQ(testing::read_3mf_file(reader.p, path), 0);
  DWORD warnings = 0;
  NMR::lib3mf_reader_getwarningcount(reader.p, &warnings);
  EXPECT_EQ(warnings, 0u);
  DWORD unit = 99;
  NMR::lib3mf_model_getunit(model.p, &unit);
  EXPECT_EQ(unit, static_cast<DWORD>(NMR::MODELUNIT_INCH));

  Lib3mfHandle it;
  ASSERT_EQ(NMR::lib3mf_model_getmeshobjects(model.p, &it.p), 0);
  std::vector<std::string> names;
  std::vector<std::pair<DWORD, DWORD>> counts;
  std::vector<std::pair<DWORD, DWORD>> materials;  // (group id, index); (0, 0) when none
  BOOL has = 0;
  while (NMR::lib3mf_resourceiterator_movenext(it.p, &has) == 0 && has) {
    Lib3mfHandle res;
    ASSERT_EQ(NMR::lib3mf_resourceiterator_getcurrent(it.p, &res.p), 0);
    names.push_back(object_name(res.p));
    DWORD nv = 0, nt = 0;
    NMR::lib3mf_meshobject_getvertexcount(res.p, &nv);
    NMR::lib3mf_meshobject_gettrianglecount(res.p, &nt);
    counts.emplace_back(nv, nt);
    Lib3mfHandle handler;
    ASSERT_EQ(NMR::lib3mf_object_createdefaultpropertyhandler(res.p, &handler.p), 0);
    DWORD group = 0, index = 0;
    if (NMR::lib3mf_defaultpropertyhandler_getbasematerial(handler.p, &group, &index) != 0)
      group = index = 0;
    materials.emplace_back(group, index);
  }
  EXPECT_THAT(names, ::testing::ElementsAre("body & \"lid\"", "insert", "second red", "bare"));
  EXPECT_THAT(counts, ::testing::ElementsAre(
                          std::pair<DWORD, DWORD>{8, 12}, std::pair<DWORD, DWORD>{4, 4},
                          std::pair<DWORD, DWORD>{4, 4}, std::pair<DWORD, DWORD>{8, 12}));
  ASSERT_EQ(materials.size(), 4u);
  EXPECT_NE(materials[0].first, 0u);
  EXPECT_EQ(materials[0].second, 0u);
  EXPECT_EQ(materials[1], std::make_pair(materials[0].first, DWORD{1}));
  EXPECT_EQ(materials[2], materials[0]);  // same material name, same base
  EXPECT_EQ(materials[3].first, 0u);

  Lib3mfHandle group;
  ASSERT_EQ(NMR::lib3mf_model_getbasematerialbyid(model.p, materials[0].first, &group.p), 0);
  DWORD n = 0;
  NMR::lib3mf_basematerial_getcount(group.p, &n);
  ASSERT_EQ(n, 2u);
  EXPECT_EQ(material_name(group.p, 0), "PLA red");
  EXPECT_EQ(material_name(group.p, 1), "TPU");
  BYTE r = 0, g = 0, b = 0, a = 0;
  NMR::lib3mf_basematerial_getdisplaycolor(group.p, 1, &r, &g, &b, &a);
  EXPECT_EQ(std::vector<int>({r, g, b, a}), std::vector<int>({0x00, 0x00, 0xFF, 0x80}));
  NMR::lib3mf_basematerial_getdisplaycolor(group.p, 0, &r, &g, &b, &a);
  EXPECT_EQ(std::vector<int>({r, g, b, a}), std::vector<int>({0xFF, 0x10, 0x00, 0xFF}));

  Lib3mfHandle items;
  ASSERT_EQ(NMR::lib3mf_model_getbuilditems(model.p, &items.p), 0);
  int n_items = 0;
  while (NMR::lib3mf_builditemiterator_movenext(items.p, &has) == 0 && has) ++n_items;
  EXPECT_EQ(n_items, 4);
}

TEST(MeshIo3mf, Lib3mfReadsVerticesOfASingleMeshFromWriteMesh) {
  testing::ScratchDir dir;
  const auto path = dir / "tetra.3mf";
  ASSERT_TRUE(write_mesh(path, tetrahedron()).ok());
  Lib3mfHandle model, reader, it, res;
  ASSERT_EQ(NMR::lib3mf_createmodel(&model.p), 0);
  ASSERT_EQ(NMR::lib3mf_model_queryreader(model.p, "3mf", &reader.p), 0);
  ASSERT_EQ(testing::read_3mf_file(reader.p, path), 0);
  DWORD unit = 99;
  NMR::lib3mf_model_getunit(model.p, &unit);
  EXPECT_EQ(unit, static_cast<DWORD>(NMR::MODELUNIT_MILLIMETER));
  ASSERT_EQ(NMR::lib3mf_model_getmeshobjects(model.p, &it.p), 0);
  BOOL has = 0;
  ASSERT_EQ(NMR::lib3mf_resourceiterator_movenext(it.p, &has), 0);
  ASSERT_TRUE(has);
  ASSERT_EQ(NMR::lib3mf_resourceiterator_getcurrent(it.p, &res.p), 0);
  EXPECT_EQ(object_name(res.p), "tetra");
  std::vector<NMR::MODELMESHVERTEX> v(4);
  DWORD nv = 0;
  ASSERT_EQ(NMR::lib3mf_meshobject_getvertices(res.p, v.data(), 4, &nv), 0);
  ASSERT_EQ(nv, 4u);
  const TriangleMesh in = tetrahedron();
  for (int i = 0; i < 4; ++i)
    for (int k = 0; k < 3; ++k)  // lib3mf stores floats
      EXPECT_EQ(v[static_cast<std::size_t>(i)].m_fPosition[k],
                static_cast<float>(in.vertices(i, k)));
  std::vector<NMR::MODELMESHTRIANGLE> t(4);
  DWORD nt = 0;
  ASSERT_EQ(NMR::lib3mf_meshobject_gettriangleindices(res.p, t.data(), 4, &nt), 0);
  ASSERT_EQ(nt, 4u);
  for (int i = 0; i < 4; ++i)
    for (int k = 0; k < 3; ++k)
      EXPECT_EQ(static_cast<int>(t[static_cast<std::size_t>(i)].m_nIndices[k]), in.triangles(i, k));
}
#endif  // HARDCOPY_HAVE_LIB3MF

}  // namespace
}  // namespace hc
