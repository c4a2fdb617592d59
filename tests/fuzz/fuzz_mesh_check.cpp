// libFuzzer target: builds a small mesh from the input bytes and runs check_mesh and repair_mesh
// on it. Coordinates come from a coarse half-unit grid so that coincident, collinear and coplanar
// corners (the hard cases for exact predicates and for orient_polygon_soup) are common.
// Aborts when a Status is wrong, when the repair summary disagrees with a fresh check of its
// output, or when a printable mesh comes out of the repair unprintable.
#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "common/mesh.h"
#include "fabrication/printability/mesh_check.h"
#include "fabrication/printability/mesh_repair.h"

namespace {

constexpr int kMaxVertices = 12;
constexpr int kMaxTriangles = 48;
constexpr double kTolerances[] = {0.0, 0.1, 0.5, 1.0};

void require(bool ok, const char* what, const hc::Status& status = {}) {
  if (!ok) {
    std::fprintf(stderr, "fuzz_mesh_check: %s %s\n", what, status.to_string().c_str());
    std::abort();
  }
}

// The triangles as corner positions, each rotated to start at its least corner (orientation kept),
// sorted: the geometry of a mesh independent of how its vertices are numbered.
std::vector<std::array<double, 9>> geometry(const hc::TriangleMesh& m) {
  std::vector<std::array<double, 9>> out;
  for (Eigen::Index t = 0; t < m.num_triangles(); ++t) {
    std::array<std::array<double, 3>, 3> c{};
    for (int k = 0; k < 3; ++k)
      for (int d = 0; d < 3; ++d) c[k][d] = m.vertices(m.triangles(t, k), d);
    std::rotate(c.begin(), std::min_element(c.begin(), c.end()), c.end());
    std::array<double, 9> flat{};
    for (int k = 0; k < 9; ++k) flat[k] = c[k / 3][k % 3];
    out.push_back(flat);
  }
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 2) return 0;
  const int nv = 1 + data[0] % kMaxVertices;
  const std::uint8_t flags = data[1];
  std::size_t at = 2;
  if (size < at + 3 * static_cast<std::size_t>(nv)) return 0;

  hc::TriangleMesh mesh;
  mesh.vertices.resize(nv, 3);
  for (int v = 0; v < nv; ++v)
    for (int k = 0; k < 3; ++k) mesh.vertices(v, k) = (data[at++] % 9 - 4) * 0.5;
  const int nf = static_cast<int>(std::min<std::size_t>((size - at) / 3, kMaxTriangles));
  mesh.triangles.resize(nf, 3);
  bool in_range = true;
  for (int t = 0; t < nf; ++t) {
    for (int k = 0; k < 3; ++k) {
      // 255 stands for an index out of range, which both functions must reject.
      const std::uint8_t b = data[at++];
      mesh.triangles(t, k) = b == 255 ? nv : b % nv;
      in_range = in_range && b != 255;
    }
  }

  hc::fabrication::MeshCheckOptions check_options;
  check_options.parallel = (flags & 1) != 0;
  check_options.max_self_intersecting_pairs = (flags >> 1) & 3;
  auto report = hc::fabrication::check_mesh(mesh, check_options);
  if (!in_range) {
    require(!report.ok() && report.status().code() == hc::StatusCode::kInvalidArgument,
            "out-of-range index accepted by check_mesh");
  } else {
    require(report.ok(), "check_mesh failed on a valid mesh:", report.status());
    const auto& r = *report;
    require(r.boundary_edges + r.non_manifold_edges <= r.edges, "edge counts exceed edges");
    require(!r.printable || (r.closed && r.manifold && r.consistently_oriented),
            "printable without being closed, manifold and oriented");
    require(!r.genus || (r.closed && r.manifold), "genus on an open or non-manifold mesh");
  }

  hc::fabrication::MeshRepairOptions options;
  options.weld_tolerance = kTolerances[(flags >> 3) & 3];
  options.orient = (flags & 0x20) == 0;
  options.remove_degenerate_triangles = (flags & 0x40) == 0;
  options.remove_duplicate_triangles = (flags & 0x80) == 0;
  hc::TriangleMesh repaired = mesh;
  hc::fabrication::MeshRepairSummary summary;
  const hc::Status status = hc::fabrication::repair_mesh(options, &repaired, &summary);
  if (!in_range) {
    require(status.code() == hc::StatusCode::kInvalidArgument,
            "out-of-range index accepted by repair_mesh");
    return 0;
  }
  require(status.ok(), "repair_mesh failed on a valid mesh:", status);
  auto after = hc::fabrication::check_mesh(repaired);
  require(after.ok(), "repair_mesh produced an invalid mesh:", after.status());
  require(after->closed == summary.closed && after->printable == summary.printable,
          "repair summary disagrees with a fresh check");
  require(after->triangles == summary.after.triangles, "repair summary has the wrong size");
  // Welding within a tolerance may legitimately collapse a part; exact welding may not.
  if (options.weld_tolerance == 0.0 && summary.before.printable)
    require(summary.printable, "repair made a printable mesh unprintable");
  // A second repair returns the same triangles. It reports nothing done (and keeps the vertex
  // numbering) unless it had to split a non-manifold vertex again: welding merges the copies the
  // first repair made. CGAL may leave collinear triangles it removes on another try.
  if (summary.after.degenerate_triangles == 0) {
    hc::TriangleMesh again = repaired;
    hc::fabrication::MeshRepairSummary second;
    require(hc::fabrication::repair_mesh(options, &again, &second).ok(), "second repair failed");
    require(geometry(again) == geometry(repaired), "second repair changed the triangles");
    if (second.split_non_manifold_vertices == 0) {
      require(!second.changed(), "second repair reports changes");
      require(again.vertices == repaired.vertices && again.triangles == repaired.triangles,
              "second repair renumbered the mesh");
    }
  }
  return 0;
}
