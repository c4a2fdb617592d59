// Times check_mesh on a ~1M-triangle closed mesh: bunny.obj (3,674 triangles, MANIFEST.md)
// subdivided 1-to-4 at edge midpoints four times, 3,674 x 4^4 = 940,544 triangles. Midpoint
// subdivision keeps the surface closed, manifold and free of self-intersections (every new
// triangle lies inside an old one), so the check runs every stage to the end.
//
// Prints each stage's wall time, with the self-intersection sweep run in parallel (TBB) and
// sequentially. Target: total <= 10 s on the 2-core build machine.
//
//   bench_mesh_check [MESH] [LEVELS] [REPEATS]   defaults: shared bunny.obj, 4, 1
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

#include "common/mesh_io.h"
#include "fabrication/printability/mesh_check.h"
#include "test_data.h"

namespace {

// One level of 1-to-4 midpoint subdivision; each edge's midpoint is made once and shared.
hc::TriangleMesh subdivide(const hc::TriangleMesh& in) {
  hc::TriangleMesh out;
  const Eigen::Index nv = in.num_vertices();
  const Eigen::Index nf = in.num_triangles();
  out.vertices.resize(nv + 3 * nf / 2 + 1, 3);  // a closed mesh has 3F/2 edges
  out.vertices.topRows(nv) = in.vertices;
  Eigen::Index next = nv;
  std::unordered_map<std::uint64_t, int> midpoint;
  midpoint.reserve(static_cast<std::size_t>(3 * nf / 2));
  const auto mid = [&](int a, int b) {
    const std::uint64_t key = (static_cast<std::uint64_t>(std::min(a, b)) << 32) |
                              static_cast<std::uint32_t>(std::max(a, b));
    auto [it, inserted] = midpoint.try_emplace(key, static_cast<int>(next));
    if (inserted) {
      if (next >= out.vertices.rows()) out.vertices.conservativeResize(2 * next, 3);
      out.vertices.row(next++) = 0.5 * (in.vertices.row(a) + in.vertices.row(b));
    }
    return it->second;
  };
  out.triangles.resize(4 * nf, 3);
  for (Eigen::Index t = 0; t < nf; ++t) {
    const int a = in.triangles(t, 0);
    const int b = in.triangles(t, 1);
    const int c = in.triangles(t, 2);
    const int ab = mid(a, b);
    const int bc = mid(b, c);
    const int ca = mid(c, a);
    out.triangles.row(4 * t + 0) << a, ab, ca;
    out.triangles.row(4 * t + 1) << ab, b, bc;
    out.triangles.row(4 * t + 2) << ca, bc, c;
    out.triangles.row(4 * t + 3) << ab, bc, ca;
  }
  out.vertices.conservativeResize(next, 3);
  return out;
}

// Records when each unit of the self-intersection stage finishes (building the CGAL mesh, the
// sweep, the count), which splits that stage's time further.
class StepTimer : public hc::ProgressReporter {
 public:
  void begin(std::string_view, std::uint64_t) override {
    last_ = std::chrono::steady_clock::now();
    steps_.clear();
  }
  void update(std::uint64_t done) override {
    const auto now = std::chrono::steady_clock::now();
    steps_.emplace_back(done, std::chrono::duration<double>(now - last_).count());
    last_ = now;
  }
  void end(std::string_view) override {}
  const std::vector<std::pair<std::uint64_t, double>>& steps() const { return steps_; }

 private:
  std::chrono::steady_clock::time_point last_;
  std::vector<std::pair<std::uint64_t, double>> steps_;
};

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

int main(int argc, char** argv) {
  const std::string path =
      argc > 1 ? argv[1] : hc::testing::shared_data("meshes/bunny.obj").string();
  const int levels = argc > 2 ? std::atoi(argv[2]) : 4;
  const int repeats = argc > 3 ? std::max(1, std::atoi(argv[3])) : 1;

  auto read = hc::read_mesh(path);
  if (!read.ok()) {
    fmt::print(stderr, "cannot read {}: {}\n", path, read.status().to_string());
    return 2;
  }
  hc::TriangleMesh mesh = std::move(read).value();
  const auto build_start = std::chrono::steady_clock::now();
  for (int i = 0; i < levels; ++i) mesh = subdivide(mesh);
  fmt::print("mesh: {} subdivided {} times: {} vertices, {} triangles (built in {:.2f} s)\n", path,
             levels, mesh.num_vertices(), mesh.num_triangles(), seconds_since(build_start));

  for (const bool parallel : {true, false}) {
    for (int r = 0; r < repeats; ++r) {
      StepTimer steps;
      hc::fabrication::MeshCheckOptions options;
      options.parallel = parallel;
      options.progress = &steps;
      auto report = hc::fabrication::check_mesh(mesh, options);
      if (!report.ok()) {
        fmt::print(stderr, "check failed: {}\n", report.status().to_string());
        return 1;
      }
      fmt::print(
          "\nself-intersections {} (run {}/{}): printable {}, closed {}, genus {}, "
          "{} intersecting pairs\n",
          parallel ? "parallel" : "sequential", r + 1, repeats, report->printable ? "yes" : "no",
          report->closed ? "yes" : "no", report->genus ? std::to_string(*report->genus) : "-",
          report->self_intersecting_pairs);
      fmt::print("  {:<20}{:>10}\n", "stage", "seconds");
      for (const auto& [stage, s] : report->stage_seconds)
        fmt::print("  {:<20}{:>10.3f}\n", stage, s);
      // Units of the self-intersection stage (cgal_mesh_ops.h): 1 = Surface_mesh built,
      // 2 = box sweep and exact tests done, 3 = pairs counted.
      for (const auto& [done, s] : steps.steps())
        fmt::print("    {:<18}{:>10.3f}\n", fmt::format("step {}", done), s);
    }
  }
  return 0;
}
