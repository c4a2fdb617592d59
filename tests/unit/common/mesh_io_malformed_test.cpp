// Malformed mesh files: every reader must answer kInvalidArgument with a message that says where
// and what, and never crash, hang or allocate what a hostile header asks for.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <bit>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "common/mesh_io.h"
#include "mesh_test_util.h"

namespace hc {
namespace {

using testing::gzip;
using ::testing::HasSubstr;

Status parse_status(std::string_view bytes, MeshFormat format,
                    const MeshReadOptions& options = {}) {
  auto r = parse_mesh(bytes, format, "bad", options);
  if (r.ok()) return {};
  return r.status();
}

// Expects kInvalidArgument whose message contains every one of `parts`.
void expect_invalid(std::string_view bytes, MeshFormat format,
                    std::initializer_list<std::string_view> parts,
                    const MeshReadOptions& options = {}) {
  const Status s = parse_status(bytes, format, options);
  ASSERT_FALSE(s.ok()) << "accepted: " << bytes.substr(0, 200);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << s.to_string();
  for (std::string_view p : parts) EXPECT_THAT(s.message(), HasSubstr(std::string(p)));
}

std::string le32(std::uint32_t v) {
  char b[4];
  std::memcpy(b, &v, 4);
  return {b, 4};
}
std::string le_float(float v) { return le32(std::bit_cast<std::uint32_t>(v)); }

std::string binary_stl(std::uint32_t declared, const std::vector<std::array<float, 9>>& tris) {
  std::string s(80, ' ');
  s += le32(declared);
  for (const auto& t : tris) {
    s += std::string(12, '\0');
    for (float f : t) s += le_float(f);
    s += std::string(2, '\0');
  }
  return s;
}

std::string fmt_byte(std::size_t offset) { return "byte " + std::to_string(offset) + ":"; }

// A mesh that came out of a reader must be usable: indices in range, coordinates finite.
void expect_consistent(const TriangleMesh& m) {
  EXPECT_TRUE(m.vertices.allFinite());
  if (m.num_triangles() > 0) {
    EXPECT_GE(m.triangles.minCoeff(), 0);
    EXPECT_LT(m.triangles.maxCoeff(), m.num_vertices());
  }
}

constexpr MeshFormat kAllReadable[] = {MeshFormat::kObj, MeshFormat::kStl, MeshFormat::kPly,
                                       MeshFormat::kOff};

// ---------------------------------------------------------------------------------------------
TEST(MeshIoMalformed, EmptyFileInEveryFormat) {
  for (const MeshFormat f : kAllReadable) {
    SCOPED_TRACE(std::string(to_string(f)));
    expect_invalid("", f, {"bad", "empty"});
  }
  // Whitespace and comments only: no geometry.
  expect_invalid("  \n# nothing\n", MeshFormat::kObj, {"no faces"});
  expect_invalid("# nothing\n\n", MeshFormat::kOff, {"no OFF header"});
  expect_invalid("\n\n", MeshFormat::kPly, {"bad:1:", "'ply'"});
  expect_invalid("   \n", MeshFormat::kStl, {"too short", "not an ASCII STL"});
}

// ---------------------------------------------------------------------------------------------
TEST(MeshIoMalformed, StlTruncatedBinary) {
  std::string stl = binary_stl(2, {{0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 0, 0, 0, 1, 0, 0, 0, 1}});
  stl.resize(stl.size() - 7);
  expect_invalid(stl, MeshFormat::kStl, {"2 triangles need 184 bytes", "has 177", "truncated"});
  // Starts with "solid" like many binary headers, yet the binary bytes rule out ASCII.
  std::string solid = stl;
  solid.replace(0, 5, "solid");
  expect_invalid(solid, MeshFormat::kStl, {"truncated", "binary bytes"});
  // Shorter than the 84-byte preamble.
  expect_invalid(std::string(40, '\x01'), MeshFormat::kStl, {"too short"});
}

TEST(MeshIoMalformed, StlBinaryNonFiniteAndEmpty) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  expect_invalid(binary_stl(1, {{0, 0, 0, 1, nan, 0, 0, 1, 0}}), MeshFormat::kStl,
                 {"byte 112", "triangle 0 corner 1", "non-finite"});
  const float inf = std::numeric_limits<float>::infinity();
  expect_invalid(binary_stl(1, {{0, 0, 0, 1, 0, 0, 0, 1, -inf}}), MeshFormat::kStl,
                 {"corner 2", "non-finite"});
  expect_invalid(binary_stl(0, {}), MeshFormat::kStl, {"0 triangles"});
  MeshReadOptions small;
  small.max_elements = 1;
  expect_invalid(binary_stl(2, {{0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 0, 0, 1, 0, 0, 0, 1, 0}}),
                 MeshFormat::kStl, {"max_elements"}, small);
}

TEST(MeshIoMalformed, StlAsciiStructure) {
  constexpr std::string_view kFacet =
      "solid x\n"
      " facet normal 0 0 1\n"
      "  outer loop\n"
      "   vertex 0 0 0\n"
      "   vertex 1 0 0\n"
      "   vertex 0 1 0\n"
      "  endloop\n"
      " endfacet\n";
  expect_invalid(kFacet, MeshFormat::kStl, {"endsolid"});
  expect_invalid(
      "solid x\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0 0\n"
      "  endloop\n endfacet\nendsolid x\n",
      MeshFormat::kStl, {"bad:6:", "facet has 2 vertices, expected 3"});
  expect_invalid("solid x\n facet normal 0 0 1\n  outer loop\n   vertex 0 zero 0\n",
                 MeshFormat::kStl, {"bad:4:", "'zero'"});
  expect_invalid(
      "solid x\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 nan\n   vertex 1 0 0\n"
      "   vertex 0 1 0\n  endloop\n endfacet\nendsolid x\n",
      MeshFormat::kStl, {"bad:4:", "not finite"});
  expect_invalid("solid x\n facet normal 0 0 1\n  outer loop\n   vertex 0 0\n", MeshFormat::kStl,
                 {"bad:4:", "2 coordinates"});
  expect_invalid("solid x\n facet normal 0 0 1\n  outer loop\n", MeshFormat::kStl,
                 {"file ends inside a facet"});
  expect_invalid("solid x\n facet 0 0 1\n", MeshFormat::kStl, {"bad:2:", "'normal'"});
  expect_invalid("solid x\n bogus\nendsolid\n", MeshFormat::kStl, {"bad:2:", "'bogus'"});
  expect_invalid("solid x\nendsolid x\n", MeshFormat::kStl, {"no facets"});
}

// ---------------------------------------------------------------------------------------------
TEST(MeshIoMalformed, ObjIndices) {
  constexpr std::string_view kTri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  expect_invalid(std::string(kTri) + "f 1 2 4\n", MeshFormat::kObj,
                 {"bad:4:", "vertex index 4 is out of range", "3 vertices"});
  expect_invalid(std::string(kTri) + "f 1 2 0\n", MeshFormat::kObj, {"bad:4:", "index 0"});
  expect_invalid(std::string(kTri) + "f -1 -2 -4\n", MeshFormat::kObj,
                 {"bad:4:", "-4", "before the first vertex"});
  expect_invalid(std::string(kTri) + "f 1 2\n", MeshFormat::kObj,
                 {"bad:4:", "2 vertices, expected at least 3"});
  expect_invalid(std::string(kTri) + "f 1 x 3\n", MeshFormat::kObj, {"bad:4:", "'x'"});
  expect_invalid(std::string(kTri) + "f 1 2 99999999999999999999\n", MeshFormat::kObj, {"bad:4:"});
}

TEST(MeshIoMalformed, ObjCoordinatesAndStatements) {
  expect_invalid("v 0 0 0\nv 1 nan 0\n", MeshFormat::kObj, {"bad:2:", "not finite"});
  expect_invalid("v 0 0 0\nv 1 inf 0\n", MeshFormat::kObj, {"bad:2:", "not finite"});
  expect_invalid("v 0 0 0\nv 1 1e999 0\n", MeshFormat::kObj, {"bad:2:", "not finite"});
  expect_invalid("v 0 0 0\nv 1 abc 0\n", MeshFormat::kObj,
                 {"bad:2:", "expected a number", "'abc'"});
  expect_invalid("v 0 0\n", MeshFormat::kObj, {"bad:1:", "2 coordinates"});
  expect_invalid("v 0 0 0\nbogus 1 2\n", MeshFormat::kObj, {"bad:2:", "unknown statement 'bogus'"});
  expect_invalid("v 0 0 0\nv 1 0 0\nv 0 1 0\n", MeshFormat::kObj, {"no faces"});
  MeshReadOptions small;
  small.max_elements = 2;
  expect_invalid("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", MeshFormat::kObj,
                 {"bad:3:", "max_elements"}, small);
}

// ---------------------------------------------------------------------------------------------
TEST(MeshIoMalformed, OffCountsLargerThanTheFile) {
  expect_invalid("OFF\n1000 1000 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", MeshFormat::kOff,
                 {"bad:2:", "1000 vertices and 1000 faces", "bytes follow"});
  expect_invalid("OFF\n999999999999 1 0\n0 0 0\n", MeshFormat::kOff,
                 {"bad:2:", "999999999999", "max_elements"});
  expect_invalid("OFF\n-3 1 0\n", MeshFormat::kOff, {"bad:2:", "vertex count"});
  expect_invalid("OFF\n3 x 0\n", MeshFormat::kOff, {"bad:2:", "face count", "'x'"});
  expect_invalid("OFF\n", MeshFormat::kOff, {"ends before the vertex count"});
  // Enough bytes (padding comment) but the vertices stop early.
  expect_invalid("OFF\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n# padding padding padding padding\n",
                 MeshFormat::kOff, {"file ends after"});
  expect_invalid("OFF\n3 0 0\n0 0 0\n1 0 0\n0 1 0\n", MeshFormat::kOff, {"0 faces"});
}

TEST(MeshIoMalformed, OffFacesAndCoordinates) {
  constexpr std::string_view kHead = "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n";
  expect_invalid(std::string(kHead) + "3 0 1 3\n", MeshFormat::kOff,
                 {"bad:6:", "face 0", "vertex index 3 is out of range", "0..2"});
  expect_invalid(std::string(kHead) + "3 0 -1 2\n", MeshFormat::kOff, {"bad:6:", "-1"});
  expect_invalid(std::string(kHead) + "2 0 1\n", MeshFormat::kOff,
                 {"bad:6:", "2 vertices, expected at least 3"});
  expect_invalid(std::string(kHead) + "3 0 1\n", MeshFormat::kOff, {"bad:6:", "2 vertex indices"});
  expect_invalid(std::string(kHead) + "4000000000 0 1 2\n", MeshFormat::kOff,
                 {"bad:6:", "more than the rest of the file"});
  expect_invalid("OFF\n3 1 0\n0 0 0\n1 NaN 0\n0 1 0\n3 0 1 2\n", MeshFormat::kOff,
                 {"bad:4:", "vertex 1", "not finite"});
  expect_invalid("OFF\n3 1 0\n0 0 0\n1 0\n0 1 0\n3 0 1 2\n", MeshFormat::kOff,
                 {"bad:4:", "vertex 1 has 2 coordinates"});
  expect_invalid("PLY\n3 1 0\n", MeshFormat::kOff, {"bad:1:", "OFF header"});
}

// ---------------------------------------------------------------------------------------------
constexpr std::string_view kPlyBinaryHead =
    "ply\nformat binary_little_endian 1.0\nelement vertex 3\n"
    "property float x\nproperty float y\nproperty float z\n"
    "element face 1\nproperty list uchar int vertex_indices\nend_header\n";

std::string ply_vertices(float bad = 0) {
  std::string s;
  for (float f : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, bad}) s += le_float(f);
  return s;
}
std::string ply_face(std::uint8_t n, std::initializer_list<std::int32_t> idx) {
  std::string s(1, static_cast<char>(n));
  for (auto i : idx) s += le32(static_cast<std::uint32_t>(i));
  return s;
}

TEST(MeshIoMalformed, PlyValidBaselineIsAccepted) {
  const std::string ok = std::string(kPlyBinaryHead) + ply_vertices() + ply_face(3, {0, 1, 2});
  EXPECT_TRUE(parse_status(ok, MeshFormat::kPly).ok())
      << parse_status(ok, MeshFormat::kPly).to_string();
}

TEST(MeshIoMalformed, PlyHugeAndWrongCounts) {
  expect_invalid(
      "ply\nformat binary_little_endian 1.0\nelement vertex 999999999999\nproperty float x\n"
      "property float y\nproperty float z\nelement face 1\n"
      "property list uchar int vertex_indices\nend_header\n",
      MeshFormat::kPly, {"bad:3:", "999999999999", "max_elements"});
  // Declares 1,000,000 vertices (12 MB) but holds 3.
  std::string wrong(kPlyBinaryHead);
  wrong.replace(wrong.find("vertex 3"), 8, "vertex 1000000");
  expect_invalid(wrong + ply_vertices() + ply_face(3, {0, 1, 2}), MeshFormat::kPly,
                 {"bad:3:", "'vertex'", "1000000", "12000000 bytes"});
  // ASCII: each value needs at least two bytes.
  expect_invalid(
      "ply\nformat ascii 1.0\nelement vertex 100000\nproperty float x\nproperty float y\n"
      "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
      "0 0 0\n",
      MeshFormat::kPly, {"bad:3:", "100000"});
  // More faces declared than present.
  std::string faces(kPlyBinaryHead);
  faces.replace(faces.find("face 1"), 6, "face 3");
  expect_invalid(faces + ply_vertices() + ply_face(3, {0, 1, 2}) + ply_face(3, {2, 1, 0}),
                 MeshFormat::kPly, {"byte", "face 2", "file ends"});
  expect_invalid("ply\nformat ascii 1.0\nelement vertex -1\nend_header\n", MeshFormat::kPly,
                 {"bad:3:", "non-negative"});
}

TEST(MeshIoMalformed, PlyBadFaces) {
  const std::string head(kPlyBinaryHead);
  const std::size_t face_at = head.size() + 36;
  expect_invalid(head + ply_vertices() + ply_face(3, {0, 1, 3}), MeshFormat::kPly,
                 {fmt_byte(face_at + 9), "face 0", "vertex index 3 is out of range"});
  expect_invalid(head + ply_vertices() + ply_face(3, {0, -1, 2}), MeshFormat::kPly,
                 {"vertex index -1"});
  expect_invalid(head + ply_vertices() + ply_face(2, {0, 1}), MeshFormat::kPly,
                 {"face 0 has 2 vertices"});
  expect_invalid(head + ply_vertices() + ply_face(200, {0, 1, 2}), MeshFormat::kPly,
                 {"list 'vertex_indices' declares 200 items"});
  const float nan = std::numeric_limits<float>::quiet_NaN();
  expect_invalid(head + ply_vertices(nan) + ply_face(3, {0, 1, 2}), MeshFormat::kPly,
                 {"vertex 2", "non-finite z"});
  expect_invalid(
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
      "0 0 0\n1 0 0\n0 1 0\n3 0 1 5\n",
      MeshFormat::kPly, {"bad:13:", "vertex index 5 is out of range"});
  expect_invalid(
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
      "0 0 0\n1 oops 0\n0 1 0\n3 0 1 2\n",
      MeshFormat::kPly, {"bad:11:", "'oops'"});
  expect_invalid(
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
      "0 0 0\n1 inf 0\n0 1 0\n3 0 1 2\n",
      MeshFormat::kPly, {"bad:11:", "not finite"});
}

TEST(MeshIoMalformed, PlyBadHeaders) {
  expect_invalid("ply\nformat binary_middle_endian 1.0\nend_header\n", MeshFormat::kPly,
                 {"bad:2:", "binary_middle_endian"});
  expect_invalid("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n", MeshFormat::kPly,
                 {"end_header"});
  expect_invalid("ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n",
                 MeshFormat::kPly, {"bad:4:", "'quad'"});
  expect_invalid("ply\nformat ascii 1.0\nproperty float x\nend_header\n", MeshFormat::kPly,
                 {"bad:3:", "before any 'element'"});
  expect_invalid(
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n"
      "0 0\n",
      MeshFormat::kPly, {"bad:3:", "'z'"});
  expect_invalid(
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
      "property float z\nend_header\n0 0 0\n",
      MeshFormat::kPly, {"no 'face' element"});
  expect_invalid(
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
      "property float z\nelement face 1\nproperty list uchar float vertex_indices\nend_header\n",
      MeshFormat::kPly, {"bad:7:", "floating-point"});
  expect_invalid("ply\nelement vertex 0\nend_header\n", MeshFormat::kPly, {"no 'format'"});
  expect_invalid("ply\nformat ascii 1.0\nwhatever\nend_header\n", MeshFormat::kPly,
                 {"bad:3:", "'whatever'"});
}

// ---------------------------------------------------------------------------------------------
TEST(MeshIoMalformed, GzipBombIsStoppedEarly) {
  // A valid little mesh followed by 64 MiB of zeros: ~64 KiB compressed. The header's counts allow
  // a few hundred bytes, so inflation must stop long before the 64 MiB.
  std::string bomb = std::string(kPlyBinaryHead) + ply_vertices() + ply_face(3, {0, 1, 2});
  bomb.resize(bomb.size() + (std::size_t{64} << 20), '\0');
  const std::string gz = gzip(bomb);
  ASSERT_LT(gz.size(), std::size_t{1} << 20);
  expect_invalid(gz, MeshFormat::kPly, {"bad", "gzip", "inflates to more than", "zip bomb"});

  // No header at all: only the header's size is allowed before giving up.
  expect_invalid(gzip(std::string(std::size_t{8} << 20, 'a')), MeshFormat::kPly,
                 {"no 'end_header'"});
}

TEST(MeshIoMalformed, GzipBombCapFollowsMaxElements) {
  // Honest counts but more than max_elements: refused from the header, before the body inflates.
  std::string many(kPlyBinaryHead);
  many.replace(many.find("vertex 3"), 8, "vertex 3000000");
  many.resize(many.size() + 36'000'000, '\0');
  MeshReadOptions small;
  small.max_elements = 1000;
  expect_invalid(gzip(many), MeshFormat::kPly, {"3000000", "max_elements"}, small);
}

TEST(MeshIoMalformed, GzipTruncatedOrCorrupt) {
  const std::string good =
      gzip(std::string(kPlyBinaryHead) + ply_vertices() + ply_face(3, {0, 1, 2}));
  ASSERT_TRUE(parse_status(good, MeshFormat::kPly).ok());
  expect_invalid(good.substr(0, good.size() / 2), MeshFormat::kPly, {"truncated"});
  std::string corrupt = good;
  for (std::size_t i = 12; i < 40 && i < corrupt.size(); ++i) corrupt[i] = '\xff';
  expect_invalid(corrupt, MeshFormat::kPly, {"gzip"});
  expect_invalid(good + "trailing", MeshFormat::kPly, {"after the end of the gzip stream"});
  expect_invalid(std::string("\x1f\x8b", 2), MeshFormat::kPly, {"gzip"});
}

// ---------------------------------------------------------------------------------------------
TEST(MeshIoMalformed, RandomGarbageNeverParses) {
  std::mt19937 rng(20240531);  // fixed seed: the same garbage every run
  std::uniform_int_distribution<int> byte(0, 255);
  std::uniform_int_distribution<int> len(1, 4096);
  for (int trial = 0; trial < 200; ++trial) {
    std::string junk(static_cast<std::size_t>(len(rng)), '\0');
    for (char& c : junk) c = static_cast<char>(byte(rng));
    for (const MeshFormat f : kAllReadable) {
      const Status s = parse_status(junk, f);
      ASSERT_FALSE(s.ok()) << to_string(f) << " accepted garbage, trial " << trial;
      EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
      EXPECT_THAT(s.message(), HasSubstr("bad"));
    }
  }
}

// Valid files with bytes flipped or cut short: whatever the reader says, it must not crash, and a
// mesh it accepts must be consistent.
TEST(MeshIoMalformed, MutatedValidFilesAreHandled) {
  const std::vector<std::pair<MeshFormat, std::string>> seeds = {
      {MeshFormat::kPly, std::string(kPlyBinaryHead) + ply_vertices() + ply_face(3, {0, 1, 2})},
      {MeshFormat::kStl, binary_stl(2, {{0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 0, 0, 1, 0, 0, 0, 0, 1}})},
      {MeshFormat::kOff, "OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n4 0 1 3 2\n"},
      {MeshFormat::kObj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1/1 -1 3 2\n"},
      {MeshFormat::kPly,
       "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
       "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
       "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"},
  };
  std::mt19937 rng(7);
  for (const auto& [format, seed] : seeds) {
    ASSERT_TRUE(parse_status(seed, format).ok()) << parse_status(seed, format).to_string();
    std::uniform_int_distribution<std::size_t> pos(0, seed.size() - 1);
    std::uniform_int_distribution<int> byte(0, 255);
    for (int trial = 0; trial < 2000; ++trial) {
      std::string m = seed;
      if (trial % 3 == 0) {
        m.resize(pos(rng));
      } else {
        for (int k = 0; k < 1 + trial % 4; ++k) m[pos(rng)] = static_cast<char>(byte(rng));
      }
      auto r = parse_mesh(m, format, "mutant");
      if (r.ok()) {
        expect_consistent(*r);
      } else {
        EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
        EXPECT_THAT(r.status().message(), HasSubstr("mutant"));
      }
      auto gz = parse_mesh(gzip(m), MeshFormat::kPly, "mutant.gz");
      if (gz.ok()) expect_consistent(*gz);
    }
  }
}

}  // namespace
}  // namespace hc
