#include "fabrication/articulation/fabrication_mesh.h"

#include <fmt/format.h>

#include <chrono>
#include <numeric>
#include <vector>

#include "fabrication/articulation/carving.h"
#include "fabrication/printability/mesh_check.h"
#include "fabrication/printability/mesh_repair.h"
#include "geometry/alpha_wrap.h"
#include "geometry/csg_sequence.h"
#include "geometry/mesh_distance.h"

namespace hc::articulation {
namespace {

// Why a component cannot enter a union as a solid, or empty when it can.
std::string solid_defect(const TriangleMesh& component) {
  fabrication::MeshCheckOptions check;
  check.parallel = false;
  Result<fabrication::MeshCheckReport> r = fabrication::check_mesh(component, check);
  if (!r.ok()) return r.status().message();
  if (!r->closed) return fmt::format("{} boundary edges", r->boundary_edges);
  if (!r->manifold)
    return fmt::format("{} non-manifold edges, {} non-manifold vertices", r->non_manifold_edges,
                       r->non_manifold_vertices);
  if (r->self_intersecting_pairs > 0)
    return fmt::format("{} self-intersecting triangle pairs", r->self_intersecting_pairs);
  if (!(r->volume > 0)) return "no positive volume";
  return {};
}

}  // namespace

Status FabricationMeshOptions::validate() const {
  if (!(weld_fraction >= 0) || !(wrap_alpha_m > 0) || !(wrap_offset_m >= 0))
    return invalid_argument("fabrication mesh: weld fraction >= 0, wrap alpha > 0, offset >= 0");
  return {};
}

Result<Eigen::MatrixXd> transfer_weights(const TriangleMesh& source,
                                         const Eigen::MatrixXd& source_weights,
                                         const MatrixX3d& points) {
  HC_ASSIGN_OR_RETURN(const geometry::MeshDistance tree, geometry::MeshDistance::build(source));
  Eigen::MatrixXd out(points.rows(), source_weights.cols());
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    Eigen::Index t = -1;
    const Eigen::Vector3d p = tree.closest_point(points.row(i).transpose(), &t);
    const Eigen::Vector3d a = source.vertices.row(source.triangles(t, 0));
    const Eigen::Vector3d b = source.vertices.row(source.triangles(t, 1));
    const Eigen::Vector3d c = source.vertices.row(source.triangles(t, 2));
    // Barycentric coordinates of p in (a, b, c), clamped for degenerate triangles.
    const Eigen::Vector3d v0 = b - a, v1 = c - a, v2 = p - a;
    const double d00 = v0.dot(v0), d01 = v0.dot(v1), d11 = v1.dot(v1);
    const double d20 = v2.dot(v0), d21 = v2.dot(v1), den = d00 * d11 - d01 * d01;
    double v = 0, w = 0;
    if (den > 1e-30) v = (d11 * d20 - d01 * d21) / den, w = (d00 * d21 - d01 * d20) / den;
    v = std::clamp(v, 0.0, 1.0), w = std::clamp(w, 0.0, 1.0 - v);
    out.row(i) = (1 - v - w) * source_weights.row(source.triangles(t, 0)) +
                 v * source_weights.row(source.triangles(t, 1)) +
                 w * source_weights.row(source.triangles(t, 2));
    const double sum = out.row(i).sum();
    if (sum > 0) out.row(i) /= sum;
  }
  return out;
}

Result<FabricationMesh> build_fabrication_mesh(const SkinnedCharacter& character,
                                               const FabricationMeshOptions& options) {
  HC_RETURN_IF_ERROR(options.validate());
  const auto start = std::chrono::steady_clock::now();
  FabricationMesh out;
  FabricationMeshSummary& s = out.summary;
  TriangleMesh mesh = character.mesh;
  const double diagonal =
      (mesh.vertices.colwise().maxCoeff() - mesh.vertices.colwise().minCoeff()).norm();
  fabrication::MeshRepairOptions repair;
  repair.weld_tolerance = options.weld_fraction * diagonal;
  repair.progress = options.progress;
  fabrication::MeshRepairSummary repaired;
  HC_RETURN_IF_ERROR(fabrication::repair_mesh(repair, &mesh, &repaired));
  s.merged_vertices = repaired.merged_vertices;
  std::vector<TriangleMesh> components = split_components(mesh);
  s.input_components = static_cast<std::int64_t>(components.size());

  std::string defect;
  for (std::size_t c = 0; c < components.size() && defect.empty(); ++c) {
    const std::string d = solid_defect(components[c]);
    if (!d.empty()) defect = fmt::format("component {} of {}: {}", c + 1, components.size(), d);
  }
  if (options.force_wrap) defect = "wrap forced";
  if (defect.empty() && components.size() == 1) {
    s.method = repaired.changed() ? "repaired" : "as is";
  } else if (defect.empty()) {
    // Several closed solids (a body and its eyes, a shirt over a torso): their exact union.
    std::vector<geometry::CsgStep> steps;
    for (std::size_t c = 1; c < components.size(); ++c)
      steps.push_back(
          {geometry::BooleanOperation::kUnion, components[c], fmt::format("component {}", c + 1)});
    geometry::CsgOptions csg;
    csg.check_operands = false;  // checked above
    csg.progress = options.progress;
    geometry::CsgSummary summary;
    Result<TriangleMesh> united = geometry::csg_sequence(components[0], steps, csg, &summary);
    if (united.ok() && summary.closed && summary.self_intersecting_pairs_after_rounding == 0) {
      mesh = std::move(united).value();
      s.method = "union";
    } else {
      defect =
          united.ok() ? "the union's rounding left self-intersections" : united.status().message();
    }
  }
  if (!defect.empty()) {
    geometry::AlphaWrapOptions wrap;
    wrap.alpha = options.wrap_alpha_m;
    wrap.offset = options.wrap_offset_m > 0 ? options.wrap_offset_m : options.wrap_alpha_m / 10;
    HC_ASSIGN_OR_RETURN(mesh, geometry::alpha_wrap(character.mesh, wrap));
    s.method = "alpha wrap";
    s.why_wrapped = defect;
  }
  HC_ASSIGN_OR_RETURN(out.weights,
                      transfer_weights(character.mesh, character.dense_weights(), mesh.vertices));
  fabrication::MeshCheckOptions check;
  HC_ASSIGN_OR_RETURN(const fabrication::MeshCheckReport report,
                      fabrication::check_mesh(mesh, check));
  s.triangles = report.triangles;
  s.volume_m3 = report.volume;
  s.closed = report.closed;
  s.manifold = report.manifold;
  s.self_intersecting_pairs = report.self_intersecting_pairs;
  out.mesh = std::move(mesh);
  s.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace hc::articulation
