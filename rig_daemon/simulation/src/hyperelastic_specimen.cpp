#include "rig_daemon/simulation/hyperelastic_specimen.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "common/log.h"
#include "processing/fem/contact.h"
#include "processing/fem/probe.h"
#include "processing/hyperelastic/neo_hookean.h"
#include "processing/hyperelastic/reference_indentation.h"
#include "processing/meshing/tetrahedralize.h"

namespace hc::devices::sim {

namespace hy = hc::hyperelastic;

Status MaterialLayer::read(ConfigNode node) {
  node.required("thickness_m", thickness_m, Bounds::positive());
  node.optional("youngs_modulus_pa", youngs_modulus_pa, Bounds::positive());
  node.optional("poisson_ratio", poisson_ratio, Bounds{0.0, 0.5, false, true});
  node.optional("stiffening", stiffening, Bounds::non_negative());
  return node.status();
}

Status HyperelasticSpecimenOptions::validate() const {
  hy::NeoHookeanMaterial m{youngs_modulus_pa, poisson_ratio, stiffening};
  HC_RETURN_IF_ERROR(m.validate());
  if (!(size_m.x() > 0 && size_m.y() > 0 && height_m > 0))
    return invalid_argument("hyperelastic specimen: sizes must be > 0");
  if (!(marker_spacing_m > 0) || !(marker_radius_m > 0) || 2 * marker_radius_m >= marker_spacing_m)
    return invalid_argument("hyperelastic specimen: bad marker spacing/radius");
  const double nx = size_m.x() / marker_spacing_m, ny = size_m.y() / marker_spacing_m;
  if (std::abs(nx - std::round(nx)) > 1e-6 || std::abs(ny - std::round(ny)) > 1e-6)
    return invalid_argument("hyperelastic specimen: size_m must be a multiple of marker_spacing_m");
  if (layers < 1 || depth_steps < 1 || !(max_depth_m > 0) || !(probe_radius_m > 0) ||
      !(location_grid_m > 0))
    return invalid_argument(
        "hyperelastic specimen: layers, depth_steps, max_depth_m, "
        "probe_radius_m, location_grid_m must be > 0");
  double total = 0;
  const double cell = height_m / layers;
  for (std::size_t i = 0; i < material_layers.size(); ++i) {
    const MaterialLayer& l = material_layers[i];
    const std::string where = "hyperelastic specimen: material_layers[" + std::to_string(i) + "]";
    const hy::NeoHookeanMaterial material{l.youngs_modulus_pa, l.poisson_ratio, l.stiffening};
    HC_RETURN_IF_ERROR(material.validate().with_context(where));
    const double cells = l.thickness_m / cell;
    if (!(l.thickness_m > 0) || std::abs(cells - std::round(cells)) > 1e-6 || cells < 0.5)
      return invalid_argument(where + ".thickness_m: " + std::to_string(l.thickness_m) +
                              " m is not a whole number of mesh cells (height_m / layers = " +
                              std::to_string(cell) + " m)");
    total += l.thickness_m;
  }
  if (!material_layers.empty() && std::abs(total - height_m) > 1e-9 * height_m + 1e-12)
    return invalid_argument("hyperelastic specimen: material_layers add up to " +
                            std::to_string(total) + " m, not height_m " + std::to_string(height_m));
  return {};
}

struct HyperelasticSpecimen::Curve {
  std::vector<double> depth_m;  // 0, [travel to first contact,] travel + d1, ..., travel + dK
  std::vector<double> force_n;  // at each depth
  std::vector<std::vector<Eigen::Vector3d>> markers;  // top nodes (world) at each depth
  bool converged = true;
  int depth_steps = 0;  // load steps solved (for the log)
  int newton_iterations = 0;
};

class HyperelasticSpecimen::Impl {
 public:
  hy::NeoHookeanModel model;
  std::vector<int> fixed_nodes;  // the bottom face
  std::vector<int> top_nodes;    // in marker order
  Eigen::Vector3d offset;        // mesh → world translation
  mutable std::mutex mutex;
  mutable std::map<std::pair<long, long>, std::unique_ptr<Curve>> curves;
  explicit Impl(hy::NeoHookeanModel m) : model(std::move(m)) {}
};

HyperelasticSpecimen::~HyperelasticSpecimen() = default;

Result<std::shared_ptr<HyperelasticSpecimen>> HyperelasticSpecimen::create(
    const HyperelasticSpecimenOptions& options) {
  HC_RETURN_IF_ERROR(options.validate());
  const Eigen::Vector3i cells(
      static_cast<int>(std::lround(options.size_m.x() / options.marker_spacing_m)),
      static_cast<int>(std::lround(options.size_m.y() / options.marker_spacing_m)), options.layers);
  HC_ASSIGN_OR_RETURN(
      TetMesh mesh,
      hc::meshing::structured_box(
          Eigen::Vector3d(options.size_m.x(), options.size_m.y(), options.height_m), cells));
  std::vector<hy::NeoHookeanMaterial> materials{
      {options.youngs_modulus_pa, options.poisson_ratio, options.stiffening}};
  if (!options.material_layers.empty()) {
    // Each tet takes the layer its centroid lies in (interfaces fall on cell boundaries).
    materials.clear();
    for (Eigen::Index t = 0; t < mesh.num_tets(); ++t) {
      double z = 0;
      for (int k = 0; k < 4; ++k) z += 0.25 * mesh.nodes(mesh.tets(t, k), 2);
      std::size_t layer = 0;
      double top = options.material_layers[0].thickness_m;
      while (z > top && layer + 1 < options.material_layers.size())
        top += options.material_layers[++layer].thickness_m;
      const MaterialLayer& l = options.material_layers[layer];
      materials.push_back({l.youngs_modulus_pa, l.poisson_ratio, l.stiffening});
    }
  }
  HC_ASSIGN_OR_RETURN(hy::NeoHookeanModel model,
                      hy::NeoHookeanModel::create(mesh, std::move(materials)));
  std::shared_ptr<HyperelasticSpecimen> s(new HyperelasticSpecimen());
  s->options_ = options;
  s->impl_ = std::make_unique<Impl>(std::move(model));
  Impl& impl = *s->impl_;
  impl.offset = Eigen::Vector3d(options.center_m.x() - 0.5 * options.size_m.x(),
                                options.center_m.y() - 0.5 * options.size_m.y(),
                                options.top_z_m - options.height_m);
  impl.fixed_nodes = hc::meshing::nodes_with_marker(impl.model.mesh(), hc::meshing::kMarkerBottom);
  std::vector<int> top = hc::meshing::nodes_with_marker(impl.model.mesh(), hc::meshing::kMarkerTop);
  // Marker order: by y then x, like marker_grid().
  const auto& nodes = impl.model.mesh().nodes;
  std::sort(top.begin(), top.end(), [&](int a, int b) {
    if (std::abs(nodes(a, 1) - nodes(b, 1)) > 1e-9) return nodes(a, 1) < nodes(b, 1);
    return nodes(a, 0) < nodes(b, 0);
  });
  impl.top_nodes = top;
  for (int n : top) s->markers_.push_back(nodes.row(n).transpose() + impl.offset);
  return s;
}

Eigen::AlignedBox2d HyperelasticSpecimen::footprint() const {
  return {options_.center_m - 0.5 * options_.size_m, options_.center_m + 0.5 * options_.size_m};
}

const HyperelasticSpecimen::Curve* HyperelasticSpecimen::curve_at(double x_m, double y_m) const {
  const long ix = std::lround(x_m / options_.location_grid_m);
  const long iy = std::lround(y_m / options_.location_grid_m);
  std::lock_guard lock(impl_->mutex);
  auto it = impl_->curves.find({ix, iy});
  if (it != impl_->curves.end()) return it->second.get();
  auto curve = std::make_unique<Curve>();
  const auto start = std::chrono::steady_clock::now();
  const Status st =
      solve_curve(ix * options_.location_grid_m, iy * options_.location_grid_m, curve.get());
  log::get("sim")->info(
      "hyperelastic specimen: location ({:.1f}, {:.1f}) mm solved in {:.2f} s ({} depth steps, {} "
      "Newton iterations){}{}",
      1e3 * ix * options_.location_grid_m, 1e3 * iy * options_.location_grid_m,
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
      curve->depth_steps, curve->newton_iterations,
      curve->converged ? "" : ", not converged: ", st.message());
  const Curve* out = curve.get();
  impl_->curves.emplace(std::make_pair(ix, iy), std::move(curve));
  return out;
}

Status HyperelasticSpecimen::solve_curve(double x_m, double y_m, Curve* curve) const {
  // Every curve starts unloaded at the rest shape; a failure leaves the steps that finished.
  auto record = [&](double depth, double force, const MatrixX3d& positions) {
    curve->depth_m.push_back(depth);
    curve->force_n.push_back(force);
    std::vector<Eigen::Vector3d> m;
    m.reserve(impl_->top_nodes.size());
    for (int n : impl_->top_nodes) m.push_back(positions.row(n).transpose() + impl_->offset);
    curve->markers.push_back(std::move(m));
  };
  const TetMesh& mesh = impl_->model.mesh();
  record(0.0, 0.0, mesh.nodes);
  curve->converged = false;
  // The sphere touching the undeformed top surface's plane at the grid point (mesh frame), moving
  // down: the reference indentation (and with it `simulate` and `synth`) measures depth from its
  // first contact with the specimen's contact points, which is this pose on the node grid.
  Result<std::unique_ptr<fem::Probe>> probe = fem::make_sphere_probe(
      options_.probe_radius_m,
      Eigen::Vector3d(x_m, y_m, options_.top_z_m + options_.probe_radius_m) - impl_->offset,
      -Eigen::Vector3d::UnitZ());
  if (!probe.ok()) return probe.status();
  hy::ReferenceIndentationOptions ro;
  ro.steps = options_.depth_steps;
  ro.record_steps = true;
  // Forces to 1e-6 of the load scale (the simulated F/T sensor's noise is far above that).
  ro.solve.relative_gradient_tolerance = 1e-6;
  const Result<hy::IndentationResult> r =
      hy::reference_indentation(impl_->model, impl_->fixed_nodes, **probe,
                                fem::Load{fem::LoadControl::kDepth, options_.max_depth_m}, ro);
  if (!r.ok()) return r.status();
  // World depth (top plane to the probe's lowest point) = travel to first contact + indentation
  // depth. Off the node grid the sphere first sinks between the nodes without force.
  const double travel = r->contact_travel_m;
  if (travel > 0) record(travel, 0.0, mesh.nodes);
  const std::vector<hy::IndentStep>& steps = r->summary.steps;
  for (std::size_t k = 0; k < steps.size() && k < r->step_positions_m.size(); ++k) {
    ++curve->depth_steps;
    curve->newton_iterations += steps[k].newton_iterations;
    record(travel + steps[k].depth_m, steps[k].force_n, r->step_positions_m[k]);
  }
  if (!r->summary.usable) return failed_precondition(r->summary.message);
  curve->converged = true;
  return {};
}

namespace {
// Index k and weight w with depth between depth[k] and depth[k+1] (w = 0 at k); past the last
// step, the last interval extrapolated.
std::pair<std::size_t, double> bracket(const std::vector<double>& depth, double d) {
  if (depth.size() < 2) return {0, 0.0};
  std::size_t k = 0;
  while (k + 2 < depth.size() && d > depth[k + 1]) ++k;
  return {k, (d - depth[k]) / (depth[k + 1] - depth[k])};
}
}  // namespace

double HyperelasticSpecimen::force_n(const Indentation& ind) const {
  if (!(ind.depth_m > 0.0)) return 0.0;
  if (!footprint().contains(Eigen::Vector2d(ind.center_x_m, ind.center_y_m))) return 0.0;
  const Curve* c = curve_at(ind.center_x_m, ind.center_y_m);
  if (c->depth_m.size() < 2) return 0.0;
  const auto [k, w] = bracket(c->depth_m, ind.depth_m);
  return std::max(0.0, c->force_n[k] + w * (c->force_n[k + 1] - c->force_n[k]));
}

Eigen::Vector3d HyperelasticSpecimen::displacement(const Eigen::Vector3d& p,
                                                   const Indentation& ind) const {
  if (!(ind.depth_m > 0.0)) return Eigen::Vector3d::Zero();
  if (!footprint().contains(Eigen::Vector2d(ind.center_x_m, ind.center_y_m)))
    return Eigen::Vector3d::Zero();
  // The marker at p (markers are the top nodes on the spacing grid).
  const Eigen::Vector2d rel =
      (p.head<2>() - (options_.center_m - 0.5 * options_.size_m)) / options_.marker_spacing_m;
  const long nx = std::lround(options_.size_m.x() / options_.marker_spacing_m) + 1;
  const long i = std::lround(rel.x()), j = std::lround(rel.y());
  if (i < 0 || j < 0 || i >= nx || j >= static_cast<long>(markers_.size()) / nx)
    return Eigen::Vector3d::Zero();
  const std::size_t m = static_cast<std::size_t>(j * nx + i);
  const Curve* c = curve_at(ind.center_x_m, ind.center_y_m);
  if (c->depth_m.size() < 2) return Eigen::Vector3d::Zero();
  const auto [k, w] = bracket(c->depth_m, ind.depth_m);
  const Eigen::Vector3d pos = c->markers[k][m] + w * (c->markers[k + 1][m] - c->markers[k][m]);
  return pos - markers_[m];
}

std::size_t HyperelasticSpecimen::solved_locations() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->curves.size();
}

bool HyperelasticSpecimen::all_converged() const {
  std::lock_guard lock(impl_->mutex);
  for (const auto& [key, c] : impl_->curves)
    if (!c->converged) return false;
  return true;
}

}  // namespace hc::devices::sim
