// check_mesh and repair_mesh on every mesh of the shared corpus (../shared/data/meshes). Expected
// verdicts, triangle counts and genera come from MANIFEST.md ("meshes/" section) unless a row of
// corpus_facts() says otherwise.
#include <gtest/gtest.h>

#include <filesystem>
#include <map>
#include <optional>
#include <string>

#include "common/mesh_io.h"
#include "fabrication/printability/mesh_check.h"
#include "fabrication/printability/mesh_repair.h"
#include "printability_test_util.h"
#include "sanitizer.h"
#include "test_data.h"

namespace hc::fabrication {
namespace {

using testing::check;

// What is known of a corpus mesh, each fact with its source; unset fields are not known.
struct Expected {
  bool closed = true;
  bool printable = true;
  std::optional<std::int64_t> triangles;
  std::optional<std::int64_t> genus;
  std::optional<std::int64_t> self_intersecting_pairs;
};

// Sources: [M] MANIFEST.md "meshes/"; [C] CGAL 5.5.1 alone (CGAL::IO::read_polygon_soup,
// merge_duplicate_points_in_polygon_soup, polygon_soup_to_polygon_mesh, then
// PMP::self_intersections), run outside Hardcopy; [A] analytic, stated at the row.
constexpr std::nullopt_t kUnknown = std::nullopt;

const std::map<std::string, Expected>& corpus_facts() {
  // clang-format off
  static const std::map<std::string, Expected> kFacts = {
      //                          closed printable triangles genus     intersecting pairs
      {"fandisk.off",            {true,  true,     12946,    kUnknown, kUnknown}},  // [M]
      {"anchor_dense.off",       {true,  true,     7598,     4,        kUnknown}},  // [M]
      {"couplingdown.off",       {true,  true,     3714,     9,        kUnknown}},  // [M]
      {"pinion.off",             {true,  true,     1300,     1,        kUnknown}},  // [M]
      // [M]; genus [A]: a tube around a knot is a torus.
      {"knot1.off",              {true,  true,     6400,     1,        kUnknown}},
      // [M] not closed; pairs [C].
      {"ChineseDragon-10kv.off", {false, false,    kUnknown, kUnknown, 38}},
      // [M] closed but misoriented.
      {"blobby-shuffled.off",    {true,  false,    kUnknown, kUnknown, kUnknown}},
      {"bunny.obj",              {true,  true,     3674,     0,        kUnknown}},  // [M]
      // [M]; genus [A]: example001.scad is a sphere minus three perpendicular through-bores
      // meeting at the centre, six openings joined in one junction: genus 6 - 1 = 5.
      {"example001.stl",         {true,  true,     1264,     5,        kUnknown}},
      // [M] closed, 8,064 triangles, genus 7; but 10 intersecting pairs [C]: the ASCII STL's
      // 6-digit coordinates fold a sliver triangle (area 4e-7) over its neighbours at z = 3.
      {"candleStand.stl",        {true,  false,    8064,     7,        10}},
  };
  // clang-format on
  return kFacts;
}

TriangleMesh read(const std::filesystem::path& path) {
  auto mesh = read_mesh(path);
  EXPECT_TRUE(mesh.ok()) << mesh.status().to_string();
  return mesh.ok() ? std::move(mesh).value() : TriangleMesh{};
}

TEST(MeshCorpus, EveryMeshIsKnown) {
  const auto meshes = testing::corpus_meshes();
  EXPECT_EQ(meshes.size(), corpus_facts().size());
  for (const auto& path : meshes)
    EXPECT_TRUE(corpus_facts().contains(path.filename().string())) << path;
}

TEST(MeshCorpus, VerdictsMatchKnownFacts) {
  for (const auto& path : testing::corpus_meshes()) {
    SCOPED_TRACE(path.filename().string());
    const auto it = corpus_facts().find(path.filename().string());
    if (it == corpus_facts().end()) continue;  // reported by EveryMeshIsKnown
    const Expected& expected = it->second;
    const MeshCheckReport r = check(read(path));
    EXPECT_EQ(r.closed, expected.closed) << to_text(r);
    EXPECT_EQ(r.printable, expected.printable) << to_text(r);
    if (expected.triangles) {
      EXPECT_EQ(r.triangles, *expected.triangles);
    }
    if (expected.genus) {
      ASSERT_TRUE(r.genus.has_value()) << to_text(r);
      EXPECT_EQ(*r.genus, *expected.genus);
    }
    if (expected.self_intersecting_pairs) {
      EXPECT_EQ(r.self_intersecting_pairs, *expected.self_intersecting_pairs);
    }
    if (expected.printable) {
      // [M]: "closed, manifold" for every mesh not singled out.
      EXPECT_TRUE(r.manifold);
      EXPECT_GT(r.volume, 0.0);
      EXPECT_EQ(r.self_intersecting_pairs, 0);
      EXPECT_TRUE(r.problems.empty()) << to_text(r);
    }
  }
}

TEST(MeshCorpus, ChineseDragonHasSixBoundaryEdges) {
  const MeshCheckReport r = check(read(testing::shared_data("meshes/ChineseDragon-10kv.off")));
  EXPECT_FALSE(r.closed);
  EXPECT_EQ(r.boundary_edges, 6);  // MANIFEST.md
  EXPECT_FALSE(r.genus.has_value());
  EXPECT_FALSE(r.printable);
}

TEST(MeshCorpus, BlobbyShuffledIsClosedButMisoriented) {
  const MeshCheckReport r = check(read(testing::shared_data("meshes/blobby-shuffled.off")));
  EXPECT_TRUE(r.closed);
  EXPECT_TRUE(r.manifold);
  EXPECT_EQ(r.misoriented_edges, 3069);  // MANIFEST.md
  EXPECT_FALSE(r.consistently_oriented);
  EXPECT_FALSE(r.printable);
}

TEST(MeshCorpus, RepairMakesBlobbyShuffledPrintable) {
  TriangleMesh mesh = read(testing::shared_data("meshes/blobby-shuffled.off"));
  MeshRepairSummary s;
  ASSERT_TRUE(repair_mesh({}, &mesh, &s).ok());
  EXPECT_GT(s.flipped_triangles, 0);
  EXPECT_TRUE(s.after.consistently_oriented);
  EXPECT_GT(s.after.volume, 0.0);
  EXPECT_TRUE(s.printable) << to_text(s);
  EXPECT_EQ(s.after.triangles, s.before.triangles);  // only orientation was wrong
}

// Property over the whole corpus: repair never turns a printable mesh unprintable, its summary
// agrees with a fresh check of its output, and a second repair finds nothing to do.
TEST(MeshCorpus, RepairIsSafeTruthfulAndIdempotent) {
  HC_SKIP_WHEN_SANITIZED("~1 min: the whole corpus");
  for (const auto& path : testing::corpus_meshes()) {
    SCOPED_TRACE(path.filename().string());
    TriangleMesh mesh = read(path);
    MeshRepairSummary first;
    ASSERT_TRUE(repair_mesh({}, &mesh, &first).ok());
    if (first.before.printable) {
      EXPECT_TRUE(first.printable) << to_text(first);
    }

    const MeshCheckReport fresh = check(mesh);
    EXPECT_EQ(first.closed, fresh.closed);
    EXPECT_EQ(first.printable, fresh.printable);
    EXPECT_EQ(first.after.triangles, mesh.num_triangles());

    const TriangleMesh once = mesh;
    MeshRepairSummary second;
    ASSERT_TRUE(repair_mesh({}, &mesh, &second).ok());
    EXPECT_FALSE(second.changed()) << to_text(second);
    EXPECT_EQ(mesh.vertices, once.vertices);
    EXPECT_EQ(mesh.triangles, once.triangles);
  }
}

// The opt-in self-intersection stage over the corpus: it touches only meshes the earlier steps
// leave intersecting, what it keeps has fewer pairs, what it fails on is returned as the earlier
// steps made it, its summary agrees with a fresh check, and a second run finds nothing to do.
TEST(MeshCorpus, ResolvingSelfIntersectionsIsSafeTruthfulAndIdempotent) {
  HC_SKIP_WHEN_SANITIZED("~2 min: the whole corpus");
  MeshRepairOptions resolve;
  resolve.resolve_self_intersections = true;
  for (const auto& path : testing::corpus_meshes()) {
    SCOPED_TRACE(path.filename().string());
    TriangleMesh plain = read(path);
    MeshRepairSummary without;
    ASSERT_TRUE(repair_mesh({}, &plain, &without).ok());
    TriangleMesh mesh = read(path);
    MeshRepairSummary first;
    ASSERT_TRUE(repair_mesh(resolve, &mesh, &first).ok());
    const SelfIntersectionStage& stage = first.self_intersections;
    EXPECT_EQ(stage.attempted, without.after.self_intersecting_pairs > 0);
    EXPECT_EQ(stage.pairs_before, without.after.self_intersecting_pairs);
    EXPECT_EQ(first.resolved_self_intersecting_pairs, stage.pairs_before - stage.pairs_after);
    if (!stage.attempted || stage.failed) {
      EXPECT_EQ(mesh.vertices, plain.vertices);
      EXPECT_EQ(mesh.triangles, plain.triangles);
      EXPECT_EQ(first.resolved_self_intersecting_pairs, 0);
    } else {
      EXPECT_LT(stage.pairs_after, stage.pairs_before);
      EXPECT_GE(first.closed, without.closed);
    }
    if (without.printable) {
      EXPECT_TRUE(first.printable) << to_text(first);
    }

    const MeshCheckReport fresh = check(mesh);
    EXPECT_EQ(first.closed, fresh.closed);
    EXPECT_EQ(first.printable, fresh.printable);
    EXPECT_EQ(first.after.self_intersecting_pairs, fresh.self_intersecting_pairs);
    EXPECT_EQ(stage.pairs_after, fresh.self_intersecting_pairs);

    const TriangleMesh once = mesh;
    MeshRepairSummary second;
    ASSERT_TRUE(repair_mesh(resolve, &mesh, &second).ok());
    EXPECT_FALSE(second.changed()) << to_text(second);
    EXPECT_EQ(mesh.vertices, once.vertices);
    EXPECT_EQ(mesh.triangles, once.triangles);
  }
}

}  // namespace
}  // namespace hc::fabrication
