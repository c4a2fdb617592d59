// Scale-aware fabrication speed (issue 16), with CGAL's alpha wrap timed in the same run:
//  1. sampling + medial balls + power-crust reconstruction at ~100k samples (fandisk.off, r_max
//     and r_min set to land there: 100,190 samples); target <= 5 s. The validity check of the
//     crust (closed, manifold, self-intersections after rounding) is timed separately, and then
//     power_crust_3d as a caller runs it (with its retries and checks).
//  2. abstraction + engraving of a ~100k-triangle mesh (anchor_dense.off, 7,598 triangles,
//     subdivided 1-to-4 twice: 121,568); target <= 60 s. Next to it CGAL's alpha wrap on the same
//     input, alpha bisected until its output has about as many triangles as ours (the issue's
//     "a mesh of the same size"), each run timed.
//
//   bench_abstraction [SAMPLE_MESH] [ENGRAVE_MESH | -]     (- skips part 2)
#include <fmt/format.h>
#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <string>

#include "common/mesh_io.h"
#include "fabrication/abstraction/abstraction.h"
#include "fabrication/abstraction/power_crust.h"
#include "fabrication/printability/mesh_check.h"
#include "geometry/alpha_wrap.h"
#include "geometry/mesh_distance.h"
#include "synthetic_meshes.h"
#include "test_data.h"

namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

// Page faults of this process so far: fresh pages touched, which cost ~16 us each on the virtual
// machines we run on (regular_triangulation_3.cpp), counted apart from the noisy clock.
long faults() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_minflt + u.ru_majflt;
}

Eigen::AlignedBox3d box_of(const hc::TriangleMesh& m) {
  Eigen::AlignedBox3d b;
  for (Eigen::Index i = 0; i < m.num_vertices(); ++i) b.extend(m.vertices.row(i).transpose());
  return b;
}

int reconstruction(const std::string& path) {
  using namespace hc::abstraction;  // NOLINT
  auto mesh = hc::read_mesh(path);
  if (!mesh.ok()) return fmt::print(stderr, "{}\n", mesh.status().to_string()), 2;
  ShapeOptions o;
  o.sampling.r_max_fraction = 1e-2;
  o.sampling.r_min_fraction = 2.2e-3;
  o.sampling.r_uniform_fraction = 1e-2;
  long f = faults();
  auto t = Clock::now();
  SamplingSummary ss;
  auto samples = sample_mesh(*mesh, o.sampling, {}, &ss);
  if (!samples.ok()) return fmt::print(stderr, "{}\n", samples.status().to_string()), 2;
  const double t_sampling = since(t);
  const long f_sampling = faults() - f;
  auto dist = hc::geometry::MeshDistance::build(*mesh);
  f = faults();
  t = Clock::now();
  MedialSummary ms;
  auto balls = medial_balls_3d(
      *samples, [&](const Eigen::Vector3d& p) { return dist->inside(p); }, o.medial, &ms);
  if (!balls.ok()) return fmt::print(stderr, "{}\n", balls.status().to_string()), 2;
  const double t_balls = since(t);
  const long f_balls = faults() - f;
  f = faults();
  t = Clock::now();
  auto rt = hc::geometry::triangulate_3d(balls->centres, power_weights(*balls),
                                         {.centres_between = balls->interior});
  const double t_rt = since(t);
  const long f_rt = faults() - f;
  t = Clock::now();
  auto crust = crust_faces_3d(*rt, *balls);
  const double t_faces = since(t);
  t = Clock::now();
  CrustSummary cs;
  const hc::Status check = check_crust(1e-6 * box_of(*crust).diagonal().norm(), &*crust, &cs);
  const double t_check = since(t);
  const double total = t_sampling + t_balls + t_rt + t_faces;
  fmt::print("reconstruction of {} ({} triangles)\n", path, mesh->num_triangles());
  fmt::print("  samples {:>8}  (pool {}, uniform pass {})   {:6.2f} s  {:>7} page faults\n",
             ss.samples, ss.pool, ss.uniform_samples, t_sampling, f_sampling);
  fmt::print("  balls   {:>8}  (Delaunay, poles, labels)     {:6.2f} s  {:>7} page faults\n",
             balls->size(), t_balls, f_balls);
  fmt::print("          ({} poles of {} Voronoi vertices; {} interior)\n", ms.poles,
             ms.voronoi_vertices, ms.interior);
  fmt::print("  regular triangulation of the balls            {:6.2f} s  {:>7} page faults\n", t_rt,
             f_rt);
  fmt::print("  crust   {:>8} triangles                     {:6.2f} s\n", crust->num_triangles(),
             t_faces);
  fmt::print("  total (target <= 5 s)                         {:6.2f} s\n", total);
  fmt::print("  validity check: {} (closed {}, manifold {}, {} intersecting pairs)  {:6.2f} s\n",
             check.ok() ? "ok" : check.to_string(), cs.closed, cs.manifold,
             cs.self_intersecting_pairs, t_check);
  // What a caller runs: the triangulation, the crust with its retries where snapping made it
  // touch itself, and the checks.
  f = faults();
  t = Clock::now();
  CrustSummary whole;
  auto valid = power_crust_3d(*balls, &whole);
  fmt::print(
      "  power_crust_3d (triangulation, crust, retries, checks): {}, {} triangles, {} hidden "
      "balls  {:6.2f} s  {} page faults\n",
      valid.ok() ? "valid" : valid.status().to_string(), whole.triangles, whole.hidden_balls,
      since(t), faults() - f);
  fmt::print("  sampling + balls + power_crust_3d                 {:6.2f} s\n",
             t_sampling + t_balls + since(t));
  return 0;
}

int engraving(const std::string& path) {
  using namespace hc::abstraction;  // NOLINT
  auto input = hc::read_mesh(path);
  if (!input.ok()) return fmt::print(stderr, "{}\n", input.status().to_string()), 2;
  hc::TriangleMesh mesh =
      hc::testing::subdivide_midpoints(hc::testing::subdivide_midpoints(*input));
  const double diag = box_of(mesh).diagonal().norm();
  EngraveOptions o;
  o.abstraction.feature_size = diag / 30;
  o.depth = o.abstraction.feature_size / 4;
  o.abstraction.shape.sampling.r_min = o.abstraction.feature_size / 10;
  o.abstraction.shape.sampling.r_uniform = o.abstraction.feature_size / 4;
  auto t = Clock::now();
  auto r = engrave_3d(mesh, o);
  const double ours = since(t);
  if (!r.ok()) return fmt::print(stderr, "{}\n", r.status().to_string()), 2;
  fmt::print(
      "abstraction + engraving of {} subdivided twice ({} triangles), F = {:.4g}, d = {:.4g}\n",
      path, mesh.num_triangles(), o.abstraction.feature_size, o.depth);
  fmt::print(
      "  ours: {} intrusions closed, {} samples, output {} triangles   {:6.2f} s (target <= 60 "
      "s)\n",
      r->summary.intrusions_closed, r->summary.samples, r->shape.num_triangles(), ours);
  // Alpha wrap with alpha bisected (on a log scale) towards our output size.
  double lo = diag / 1000, hi = diag / 10, alpha = o.abstraction.feature_size / 2;
  for (int run = 0; run < 6; ++run) {
    hc::geometry::AlphaWrapOptions ao;
    ao.alpha = alpha;
    ao.offset = alpha / 30;
    t = Clock::now();
    auto w = hc::geometry::alpha_wrap(mesh, ao);
    const double tw = since(t);
    if (!w.ok()) return fmt::print(stderr, "{}\n", w.status().to_string()), 2;
    const double ratio =
        static_cast<double>(w->num_triangles()) / static_cast<double>(r->shape.num_triangles());
    fmt::print(
        "  alpha wrap alpha = {:.4g}: {} triangles ({:.2f}x ours)   {:6.2f} s  -> ours / wrap time "
        "{:.2f}\n",
        alpha, w->num_triangles(), ratio, tw, ours / tw);
    if (ratio > 0.8 && ratio < 1.25) break;
    (ratio > 1 ? lo : hi) = alpha;  // more triangles: alpha too small
    alpha = std::sqrt(lo * hi);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string sample_mesh =
      argc > 1 ? argv[1] : hc::testing::shared_data("meshes/fandisk.off").string();
  const std::string engrave_mesh =
      argc > 2 ? argv[2] : hc::testing::shared_data("meshes/anchor_dense.off").string();
  if (const int rc = reconstruction(sample_mesh); rc != 0) return rc;
  if (engrave_mesh == "-") return 0;
  return engraving(engrave_mesh);
}
