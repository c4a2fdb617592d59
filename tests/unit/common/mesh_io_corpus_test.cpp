// Property tests over every mesh in ../shared/data/meshes: known counts, and a round trip through
// every writer that keeps the counts and the signed volume.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <map>
#include <set>
#include <string>

#include "common/mesh_io.h"
#include "mesh_test_util.h"
#include "test_data.h"

namespace hc {
namespace {

using testing::signed_volume;
using testing::Volume;

struct Expected {
  Eigen::Index vertices;
  Eigen::Index triangles;
};

// Triangle counts: ../shared/data/MANIFEST.md ("meshes/"), and for the two files it does not list
// (ChineseDragon, blobby-shuffled) the face count of their OFF header, all faces being triangles.
// Vertex counts: the OFF headers ("OFF\nV F 0"); bunny.obj: its 1,839 "v" lines; the STL files:
// distinct corner positions after welding — candleStand agrees with Euler's formula for its genus
// 7 from the manifest (V = E - F + 2 - 2g = 12,096 - 8,064 + 2 - 14 = 4,020).
const std::map<std::string, Expected>& expected_counts() {
  static const std::map<std::string, Expected> kCounts = {
      {"ChineseDragon-10kv.off", {10000, 19994}},  // header "10000 19994 0"
      {"anchor_dense.off", {3793, 7598}},          // header "3793 7598 0"
      {"blobby-shuffled.off", {2027, 4050}},       // header "2027 4050 0"
      {"bunny.obj", {1839, 3674}},
      {"candleStand.stl", {4020, 8064}},
      {"couplingdown.off", {1841, 3714}},  // header "1841 3714 0"
      {"example001.stl", {624, 1264}},
      {"fandisk.off", {6475, 12946}},  // header "6475 12946 0"
      {"knot1.off", {3200, 6400}},     // header "3200 6400 0"
      {"pinion.off", {650, 1300}},     // header "650 1300 1950"
  };
  return kCounts;
}

// What an STL of this mesh welds back to: distinct positions among referenced vertices, compared
// as floats (binary) or doubles (ASCII). Computed independently of the reader's hash table.
template <typename T>
Eigen::Index distinct_referenced_positions(const TriangleMesh& m) {
  std::set<std::array<T, 3>> seen;
  for (Eigen::Index t = 0; t < m.num_triangles(); ++t)
    for (int c = 0; c < 3; ++c) {
      const int v = m.triangles(t, c);
      seen.insert({static_cast<T>(m.vertices(v, 0)), static_cast<T>(m.vertices(v, 1)),
                   static_cast<T>(m.vertices(v, 2))});
    }
  return static_cast<Eigen::Index>(seen.size());
}

std::string test_name(const std::filesystem::path& p) {
  std::string n = p.filename().string();
  for (char& c : n)
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  return n;
}

class MeshIoCorpus : public ::testing::TestWithParam<std::filesystem::path> {};

TEST_P(MeshIoCorpus, ReadsWithTheKnownCounts) {
  const auto& path = GetParam();
  const auto it = expected_counts().find(path.filename().string());
  ASSERT_NE(it, expected_counts().end())
      << path << " is new in the corpus: add its counts to expected_counts()";
  auto m = read_mesh(path);
  ASSERT_TRUE(m.ok()) << m.status().to_string();
  EXPECT_EQ(m->num_vertices(), it->second.vertices);
  EXPECT_EQ(m->num_triangles(), it->second.triangles);
  EXPECT_TRUE(m->vertices.allFinite());
  EXPECT_GE(m->triangles.minCoeff(), 0);
  EXPECT_LT(m->triangles.maxCoeff(), m->num_vertices());
}

struct Writer {
  std::string file;
  bool binary;
};

TEST_P(MeshIoCorpus, RoundTripThroughEveryWriterKeepsCountsAndVolume) {
  auto in = read_mesh(GetParam());
  ASSERT_TRUE(in.ok()) << in.status().to_string();
  const Volume volume = signed_volume(*in);
  ASSERT_GT(volume.magnitude, 0.0);
  testing::ScratchDir dir;
  for (const Writer& w : {Writer{"m.obj", false}, Writer{"m.off", false}, Writer{"m.ply", true},
                          Writer{"m.ply", false}, Writer{"m.ply.gz", true}, Writer{"m.stl", true},
                          Writer{"m.stl", false}}) {
    SCOPED_TRACE(w.file + (w.binary ? " binary" : " ascii"));
    MeshWriteOptions wo;
    wo.binary = w.binary;
    const Status written = write_mesh(dir / w.file, *in, wo);
    ASSERT_TRUE(written.ok()) << written.to_string();
    auto out = read_mesh(dir / w.file);
    ASSERT_TRUE(out.ok()) << out.status().to_string();
    EXPECT_EQ(out->num_triangles(), in->num_triangles());
    const bool is_stl = w.file == "m.stl";
    if (!is_stl) {
      // Double-precision formats give back the very same numbers.
      EXPECT_EQ(out->num_vertices(), in->num_vertices());
      EXPECT_EQ(out->vertices, in->vertices);
      EXPECT_EQ(out->triangles, in->triangles);
      EXPECT_NEAR(signed_volume(*out).signed_sum, volume.signed_sum, 1e-9 * volume.magnitude);
    } else {
      EXPECT_EQ(out->num_vertices(), w.binary ? distinct_referenced_positions<float>(*in)
                                              : distinct_referenced_positions<double>(*in));
      // Binary STL rounds coordinates to float (relative 6e-8 each).
      EXPECT_NEAR(signed_volume(*out).signed_sum, volume.signed_sum,
                  (w.binary ? 1e-6 : 1e-9) * volume.magnitude);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(MeshIoSharedData, MeshIoCorpus,
                         ::testing::ValuesIn(testing::corpus_meshes()),
                         [](const ::testing::TestParamInfo<std::filesystem::path>& param_info) {
                           return test_name(param_info.param);
                         });

TEST(MeshIoCorpusSet, EveryExpectedFileIsPresent) {
  std::set<std::string> present;
  for (const auto& p : testing::corpus_meshes()) present.insert(p.filename().string());
  for (const auto& [name, counts] : expected_counts()) EXPECT_TRUE(present.count(name)) << name;
}

#if HARDCOPY_HAVE_LIB3MF
// The whole corpus as one multi-part 3MF, read back by lib3mf: one object per mesh with its counts.
TEST(MeshIoCorpusSet, Lib3mfReadsTheCorpusAsOnePackage) {
  std::vector<MeshPart> parts;
  for (const auto& p : testing::corpus_meshes()) {
    auto m = read_mesh(p);
    ASSERT_TRUE(m.ok()) << m.status().to_string();
    parts.push_back(MeshPart{p.stem().string(), std::move(*m), parts.size() % 2 ? "PETG" : "PLA",
                             std::nullopt});
  }
  testing::ScratchDir dir;
  const auto path = dir / "corpus.3mf";
  const Status s = write_3mf(path, parts);
  ASSERT_TRUE(s.ok()) << s.to_string();

  NMR::PLib3MFModel* model = nullptr;
  NMR::PLib3MFModelReader* reader = nullptr;
  NMR::PLib3MFModelResourceIterator* it = nullptr;
  ASSERT_EQ(NMR::lib3mf_createmodel(&model), 0);
  ASSERT_EQ(NMR::lib3mf_model_queryreader(model, "3mf", &reader), 0);
  ASSERT_EQ(testing::read_3mf_file(reader, path), 0);
  ASSERT_EQ(NMR::lib3mf_model_getmeshobjects(model, &it), 0);
  std::size_t i = 0;
  BOOL has = 0;
  while (NMR::lib3mf_resourceiterator_movenext(it, &has) == 0 && has) {
    NMR::PLib3MFModelResource* res = nullptr;
    ASSERT_EQ(NMR::lib3mf_resourceiterator_getcurrent(it, &res), 0);
    ASSERT_LT(i, parts.size());
    DWORD nv = 0, nt = 0;
    NMR::lib3mf_meshobject_getvertexcount(res, &nv);
    NMR::lib3mf_meshobject_gettrianglecount(res, &nt);
    EXPECT_EQ(nv, static_cast<DWORD>(parts[i].mesh.num_vertices())) << parts[i].name;
    EXPECT_EQ(nt, static_cast<DWORD>(parts[i].mesh.num_triangles())) << parts[i].name;
    NMR::lib3mf_release(res);
    ++i;
  }
  EXPECT_EQ(i, parts.size());
  NMR::lib3mf_release(it);
  NMR::lib3mf_release(reader);
  NMR::lib3mf_release(model);
}
#endif  // HARDCOPY_HAVE_LIB3MF

}  // namespace
}  // namespace hc
