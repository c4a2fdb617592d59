// The depth-aware 3-D abstraction on generated intrusions (issue 16): holes, slots and grooves of
// widths {0.5, 1, 2} x F and depth/width {0.25, 1, 4}, in three orientations; only the narrow
// (0.5 F) and deep (ratio 1, 4 > tau 0.5) ones must close. The same suite through CGAL's alpha
// wrap for comparison; the Menger sponge's genus; the shared mesh corpus. These run for tens of
// seconds in Release, so they are skipped under AddressSanitizer (the Release stage runs them).
#include <gtest/gtest.h>

#include <algorithm>

#include <cstdio>
#include <filesystem>
#include <vector>

#include "sanitizer.h"
#include "common/mesh_io.h"
#include "fabrication/abstraction/abstraction.h"
#include "fabrication/abstraction/fidelity.h"
#include "fabrication/printability/mesh_check.h"
#include "fabrication/printability/mesh_repair.h"
#include "geometry/alpha_wrap.h"
#include "geometry/booleans.h"
#include "geometry/mesh_distance.h"
#include "shapes_3d.h"
#include "test_data.h"

namespace hc::abstraction {
namespace {

// The corpus meshes the corpus sweeps run by default: sharp features (fandisk) and genus 1 with
// thin parts (knot1); HARDCOPY_LONG_TESTS=1 runs every mesh of the corpus.
std::vector<std::filesystem::path> sweep_meshes() {
  std::vector<std::filesystem::path> out;
  for (const auto& p : testing::corpus_meshes())
    if (testing::long_tests() || p.filename() == "fandisk.off" || p.filename() == "knot1.off")
      out.push_back(p);
  return out;
}

constexpr double kF = 1.0;    // feature size
constexpr double kTau = 0.5;  // default depth ratio

struct Suite {
  TriangleMesh mesh;
  std::vector<testing::IntrusionSpec> specs;
};

// Nine intrusions (3 widths x 3 ratios) of one kind, cut into the top of one block.
Suite make_suite(testing::IntrusionKind kind) {
  Suite s;
  const double pitch = 8.0;
  const double widths[] = {0.5, 1.0, 2.0}, ratios[] = {0.25, 1.0, 4.0};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const double w = widths[i] * kF;
      const int k = 3 * i + j;
      // Holes and slots on a 3 x 3 grid; grooves side by side along x.
      const Eigen::Vector3d c = kind == testing::IntrusionKind::kGroove
                                    ? Eigen::Vector3d(4.0 + k * 5.0, 4.0, 10.0)
                                    : Eigen::Vector3d(pitch * (i + 0.5), pitch * (j + 0.5), 10.0);
      s.specs.push_back({w, ratios[j] * w, c});
    }
  const Eigen::Vector3d size = kind == testing::IntrusionKind::kGroove
                                   ? Eigen::Vector3d(46, 8, 10)
                                   : Eigen::Vector3d(24, 24, 10);
  auto m = testing::block_with_intrusions(kind, s.specs, size);
  EXPECT_TRUE(m.ok()) << m.status().to_string();
  if (m.ok()) s.mesh = std::move(*m);
  return s;
}

// Whether the solid fills the intrusion: the point half-way down its axis is inside.
bool filled(const geometry::MeshDistance& solid, const testing::IntrusionSpec& s, int axis) {
  const Eigen::Vector3d p = s.centre - Eigen::Vector3d(0, 0, 0.5 * s.depth);
  return solid.inside(testing::permute_point(p, axis));
}

const char* kind_name(testing::IntrusionKind k) {
  return k == testing::IntrusionKind::kHole   ? "hole"
         : k == testing::IntrusionKind::kSlot ? "slot"
                                              : "groove";
}

TEST(AbstractionSuite, NarrowDeepIntrusionsCloseTheRestStays) {
  HC_SKIP_WHEN_SANITIZED("3-D power crusts about ten times slower");
  int wrong = 0, wrap_wrong = 0;
  for (const auto kind : {testing::IntrusionKind::kHole, testing::IntrusionKind::kSlot,
                          testing::IntrusionKind::kGroove}) {
    // By default the holes in their first orientation (about 30 s in Release);
    // HARDCOPY_LONG_TESTS=1 runs every kind in every orientation.
    if (!testing::long_tests() && kind != testing::IntrusionKind::kHole) continue;
    const Suite suite = make_suite(kind);
    ASSERT_GT(suite.mesh.num_triangles(), 0);
    for (int axis = 0; axis < 3; ++axis) {
      if (!testing::long_tests() && axis != 0) continue;
      const TriangleMesh input = testing::permute_axes(suite.mesh, axis);
      AbstractionOptions o;
      o.feature_size = kF;
      o.depth_ratio = kTau;
      o.shape.sampling.r_min = kF / 8;
      o.shape.sampling.r_uniform = kF / 4;
      auto r = abstract_3d(input, o);
      ASSERT_TRUE(r.ok()) << kind_name(kind) << " axis " << axis << ": " << r.status().to_string();
      auto check = fabrication::check_mesh(r->shape);
      ASSERT_TRUE(check.ok());
      EXPECT_TRUE(check->printable) << kind_name(kind) << " axis " << axis;
      auto ours = geometry::MeshDistance::build(r->shape);
      ASSERT_TRUE(ours.ok());
      geometry::AlphaWrapOptions ao;
      ao.alpha = kF / 2;
      ao.offset = ao.alpha / 30;
      auto wrap = geometry::alpha_wrap(input, ao);
      ASSERT_TRUE(wrap.ok()) << wrap.status().to_string();
      auto wrapped = geometry::MeshDistance::build(*wrap);
      ASSERT_TRUE(wrapped.ok());
      for (const auto& s : suite.specs) {
        const bool expect_closed = s.width < kF && s.depth / s.width > kTau;
        const bool got = filled(*ours, s, axis), got_wrap = filled(*wrapped, s, axis);
        wrong += got != expect_closed;
        wrap_wrong += got_wrap != expect_closed;
        std::printf(
            "%-6s axis %d width %.2f F depth/width %.2f: expected %-6s ours %-6s alpha wrap %s\n",
            kind_name(kind), axis, s.width / kF, s.depth / s.width,
            expect_closed ? "closed" : "kept", got ? "closed" : "kept",
            got_wrap ? "closed" : "kept");
        EXPECT_EQ(got, expect_closed)
            << kind_name(kind) << " axis " << axis << " width " << s.width << " depth " << s.depth;
      }
      // Outside the closed regions the abstraction stays within the sampling tolerance.
      HausdorffOptions ho;
      ho.margin = 2 * o.shape.sampling.r_min;
      auto h = hausdorff_3d(input, r->shape, r->closed, ho);
      ASSERT_TRUE(h.ok());
      EXPECT_LT(h->symmetric(), 2 * o.shape.sampling.r_min) << kind_name(kind) << " axis " << axis;
    }
  }
  const int total = testing::long_tests() ? 81 : 9;
  std::printf("misclassified: ours %d of %d, alpha wrap (alpha = F/2) %d of %d\n", wrong, total,
              wrap_wrong, total);
}

TEST(AbstractionSuite, MengerSpongeGenusDropsByTheNarrowHoles) {
  HC_LONG_TEST_ONLY("about a minute in Release");
  HC_SKIP_WHEN_SANITIZED("3-D power crusts about ten times slower");
  // Level 2, unit voxels: tunnels 3 wide (kept at F = 2) and 1 wide (closed). Closing every
  // narrow tunnel leaves the level-1 sponge's topology (the same sponge at 3x voxels).
  const TriangleMesh sponge = testing::menger_sponge(2, 1.0);
  const TriangleMesh level1 = testing::menger_sponge(1, 3.0);
  auto g2 = fabrication::check_mesh(sponge);
  auto g1 = fabrication::check_mesh(level1);
  ASSERT_TRUE(g2.ok() && g1.ok() && g2->genus && g1->genus);
  ASSERT_TRUE(g2->printable);
  AbstractionOptions o;
  o.feature_size = 2.0;
  o.shape.sampling.r_min = 0.2;
  o.shape.sampling.r_uniform = 0.5;
  auto r = abstract_3d(sponge, o);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  auto g = fabrication::check_mesh(r->shape);
  ASSERT_TRUE(g.ok() && g->genus);
  EXPECT_TRUE(g->printable);
  std::printf(
      "Menger level 2 genus %ld, level 1 genus %ld, abstraction genus %ld (%zu intrusions "
      "closed)\n",
      *g2->genus, *g1->genus, *g->genus, r->summary.intrusions_closed);
  EXPECT_EQ(*g->genus, *g1->genus);
}

TEST(AbstractionSuite, EveryCorpusMeshGivesAPrintableAbstraction) {
  HC_SKIP_WHEN_SANITIZED("3-D power crusts about ten times slower");
  int tested = 0;
  for (const auto& path : sweep_meshes()) {
    auto mesh = read_mesh(path);
    ASSERT_TRUE(mesh.ok()) << path;
    fabrication::MeshRepairOptions ro;
    fabrication::MeshRepairSummary rs;
    ASSERT_TRUE(fabrication::repair_mesh(ro, &*mesh, &rs).ok()) << path;
    if (!rs.printable) {
      std::printf("%s: not printable after repair (skipped, as the CLI refuses it)\n",
                  path.filename().c_str());
      continue;
    }
    ++tested;
    const double diag = rs.after.bounding_box.diagonal().norm();
    AbstractionOptions o;
    o.feature_size = diag / 25;
    o.shape.sampling.r_min = o.feature_size / 8;
    o.shape.sampling.r_uniform = o.feature_size / 4;
    auto r = abstract_3d(*mesh, o);
    ASSERT_TRUE(r.ok()) << path << ": " << r.status().to_string();
    auto check = fabrication::check_mesh(r->shape);
    ASSERT_TRUE(check.ok());
    EXPECT_TRUE(check->printable) << path;
    std::printf("%s: %zu samples, %zu intrusions closed, %ld triangles, %.2f s\n",
                path.filename().c_str(), r->summary.samples, r->summary.intrusions_closed,
                static_cast<long>(r->shape.num_triangles()), r->summary.time_s);
  }
  EXPECT_GT(tested, 0) << "no printable mesh in the sweep";
}

TEST(AbstractionSuite, BooleansAgreeWithCorefinementOnTheCorpus) {
  HC_SKIP_WHEN_SANITIZED("3-D power crusts about ten times slower");
  // Each printable corpus mesh united with, cut by and intersected with a copy of itself moved by
  // a fifth of its bounding box: volumes against CGAL's exact corefinement of the same inputs.
  //
  // Where a crust is not a valid solid boolean_3d returns the exact corefinement
  // (summary.exact_fallback); the test prints how many (0 of 24 with the samples in Hilbert
  // order; 1, example001's intersection, with the perturbation their earlier order gave). About 2
  // minutes in Release: the default run covers booleans with Boolean3d.* (analytic cubes and
  // spheres, degenerate contacts).
  HC_LONG_TEST_ONLY("about 2 minutes in Release");
  int tested = 0, fallbacks = 0;
  for (const auto& path : sweep_meshes()) {
    auto mesh = read_mesh(path);
    ASSERT_TRUE(mesh.ok()) << path;
    fabrication::MeshRepairOptions ro;
    fabrication::MeshRepairSummary rs;
    ASSERT_TRUE(fabrication::repair_mesh(ro, &*mesh, &rs).ok()) << path;
    if (!rs.printable) continue;
    ++tested;
    TriangleMesh moved = *mesh;
    const Eigen::Vector3d shift = 0.2 * rs.after.bounding_box.sizes();
    moved.vertices.rowwise() += shift.transpose();
    const double diag = rs.after.bounding_box.diagonal().norm();
    ShapeOptions o;
    o.sampling.r_min = 2e-3 * diag;
    o.sampling.r_uniform = 1e-2 * diag;
    o.sampling.r_max = 2e-2 * diag;
    for (const auto op : {BooleanOp::kUnion, BooleanOp::kDifference, BooleanOp::kIntersection}) {
      OperationSummary sum;
      auto ours = boolean_3d(*mesh, moved, op, o, &sum);
      ASSERT_TRUE(ours.ok()) << path << " " << to_string(op) << ": " << ours.status().to_string();
      if (sum.exact_fallback) {
        ++fallbacks;
        std::printf("%s %s: exact fallback (%s)\n", path.filename().c_str(), to_string(op),
                    sum.fallback_reason.c_str());
        continue;
      }
      auto check = fabrication::check_mesh(*ours);
      ASSERT_TRUE(check.ok());
      EXPECT_TRUE(check->printable) << path << " " << to_string(op);
      auto ref = geometry::corefine_boolean(*mesh, moved, to_geometry(op));
      if (!ref.ok()) {
        std::printf("%s %s: corefinement failed (%s); ours %.6g printable\n",
                    path.filename().c_str(), to_string(op), ref.status().message().c_str(),
                    testing::signed_volume(*ours));
        continue;
      }
      const double v_ref = testing::signed_volume(*ref), v = testing::signed_volume(*ours);
      const double area = testing::surface_area(*ref);
      std::printf("%s %s: corefinement %.6g, ours %.6g (%.2f %%; mean offset %.3g r_min)\n",
                  path.filename().c_str(), to_string(op), v_ref, v, 100 * (v - v_ref) / v_ref,
                  (v - v_ref) / area / o.sampling.r_min);
      // 1 %: thin parts (candleStand's stand) are sampled at r_min = 0.2 % of the diagonal. A
      // thin result is held to its surface instead: a mean offset of a tenth of r_min. example001's
      // intersection is a sheet 2V/A = 0.22 mm thick (1.5 r_min): -6.2 % of its volume is a mean
      // offset of 0.045 r_min.
      EXPECT_NEAR(v, v_ref, std::max(0.01 * std::abs(v_ref), 0.1 * o.sampling.r_min * area))
          << path << " " << to_string(op);
    }
  }
  EXPECT_GT(tested, 0) << "no printable mesh in the sweep";
  std::printf("%d of %d booleans fell back to the exact corefinement\n", fallbacks, 3 * tested);
}

}  // namespace
}  // namespace hc::abstraction
