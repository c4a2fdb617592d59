#include "rig_daemon/devices/hyperelastic_specimen.h"

#include <algorithm>
#include <cmath>

#include "processing/fem/probe.h"
#include "processing/hyperelastic/neo_hookean.h"
#include "processing/hyperelastic/reference_indentation.h"
#include "processing/meshing/tetrahedralize.h"

namespace hc::devices::sim {

namespace hy = hc::hyperelastic;

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
        "hyperelastic specimen: layers, depth_steps, max_depth_m, probe_radius_m, "
        "location_grid_m must be > 0");
  return {};
}

struct HyperelasticSpecimen::Curve {
  std::vector<double> depth_m;                        // 0, d1, ..., dK
  std::vector<double> force_n;                        // at each depth
  std::vector<std::vector<Eigen::Vector3d>> markers;  // top nodes (world) at each depth
  bool converged = true;
};

class HyperelasticSpecimen::Impl {
 public:
  hy::NeoHookeanModel model;
  std::vector<int> fixed_nodes;
  std::vector<int> top_nodes;  // in marker order
  Eigen::Vector3d offset;      // mesh → world translation
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
  hy::NeoHookeanMaterial material{options.youngs_modulus_pa, options.poisson_ratio,
                                  options.stiffening};
  HC_ASSIGN_OR_RETURN(hy::NeoHookeanModel model, hy::NeoHookeanModel::create(mesh, {material}));
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
  // Solve this location: the sphere starts touching the top surface at the grid point.
  auto curve = std::make_unique<Curve>();
  const Eigen::Vector3d start =
      Eigen::Vector3d(ix * options_.location_grid_m, iy * options_.location_grid_m,
                      options_.top_z_m + options_.probe_radius_m) -
      impl_->offset;
  hc::hyperelastic::ReferenceIndentationOptions io;
  io.steps = options_.depth_steps;
  io.record_steps = true;
  Result<std::unique_ptr<hc::fem::Probe>> probe =
      hc::fem::make_sphere_probe(options_.probe_radius_m, start, -Eigen::Vector3d::UnitZ());
  Result<hc::hyperelastic::IndentationResult> ind =
      probe.ok() ? hc::hyperelastic::reference_indentation(
                       impl_->model, impl_->fixed_nodes, **probe,
                       {hc::fem::LoadControl::kDepth, options_.max_depth_m}, io)
                 : Result<hc::hyperelastic::IndentationResult>(probe.status());
  const auto record = [&](double depth, double force, const MatrixX3d& x) {
    curve->depth_m.push_back(depth);
    curve->force_n.push_back(force);
    std::vector<Eigen::Vector3d> m;
    m.reserve(impl_->top_nodes.size());
    for (int n : impl_->top_nodes) m.push_back(x.row(n).transpose() + impl_->offset);
    curve->markers.push_back(std::move(m));
  };
  record(0.0, 0.0, impl_->model.mesh().nodes);
  curve->converged = ind.ok() && ind->summary.usable;
  if (ind.ok())
    for (std::size_t k = 0; k < ind->step_positions_m.size(); ++k)
      record(ind->summary.steps[k].depth_m, ind->summary.steps[k].force_n,
             ind->step_positions_m[k]);
  const Curve* out = curve.get();
  impl_->curves.emplace(std::make_pair(ix, iy), std::move(curve));
  return out;
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
