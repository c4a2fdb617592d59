#include "fabrication/composite/composite.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "processing/fem/corotational.h"
#include "processing/fem/incremental.h"

namespace hc::composite {
namespace {

// Relative tolerance for layer thicknesses adding up to the specimen's height.
constexpr double kHeightTolerance = 1e-6;

Status check_axis(const std::vector<double>& v, char axis) {
  if (v.size() < 2)
    return invalid_argument(fmt::format("cells: axis {} needs at least 2 boundaries", axis));
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (!std::isfinite(v[i]))
      return invalid_argument(fmt::format("cells: axis {} boundary {} is not finite", axis, i));
    if (i > 0 && !(v[i] > v[i - 1]))
      return invalid_argument(fmt::format(
          "cells: axis {} boundaries must increase, got {} after {}", axis, v[i], v[i - 1]));
  }
  return {};
}

std::vector<double> uniform(double lo, double hi, int n) {
  std::vector<double> out(static_cast<std::size_t>(n) + 1);
  for (int i = 0; i <= n; ++i) out[static_cast<std::size_t>(i)] = lo + (hi - lo) * i / n;
  out.back() = hi;
  return out;
}

int locate(const std::vector<double>& v, double x) {
  const auto it = std::upper_bound(v.begin() + 1, v.end() - 1, x);
  return static_cast<int>(it - v.begin()) - 1;
}

}  // namespace

Result<CellGrid> CellGrid::from_boundaries(std::vector<double> x_m, std::vector<double> y_m,
                                           std::vector<double> z_m) {
  HC_RETURN_IF_ERROR(check_axis(x_m, 'x'));
  HC_RETURN_IF_ERROR(check_axis(y_m, 'y'));
  HC_RETURN_IF_ERROR(check_axis(z_m, 'z'));
  CellGrid g;
  g.x_m_ = std::move(x_m);
  g.y_m_ = std::move(y_m);
  g.z_m_ = std::move(z_m);
  return g;
}

Result<CellGrid> CellGrid::layers(const Eigen::AlignedBox3d& box,
                                  const std::vector<double>& thickness_m) {
  if (thickness_m.empty()) return invalid_argument("layers: no thicknesses given");
  std::vector<double> z{box.min().z()};
  double total = 0;
  for (std::size_t i = 0; i < thickness_m.size(); ++i) {
    const double t = thickness_m[i];
    if (!(std::isfinite(t) && t > 0))
      return invalid_argument(fmt::format("layers: thickness {} is {} m, expected > 0", i, t));
    total += t;
    z.push_back(box.min().z() + total);
  }
  const double height = box.sizes().z();
  if (std::abs(total - height) > kHeightTolerance * height)
    return invalid_argument(fmt::format(
        "layers: thicknesses add up to {:.6g} m but the specimen is {:.6g} m high (thicknesses "
        "are in metres)",
        total, height));
  z.back() = box.max().z();
  return from_boundaries({box.min().x(), box.max().x()}, {box.min().y(), box.max().y()},
                         std::move(z));
}

Result<CellGrid> CellGrid::equal_layers(const Eigen::AlignedBox3d& box, int count) {
  if (count < 1) return invalid_argument(fmt::format("layers: count must be >= 1, got {}", count));
  return from_boundaries({box.min().x(), box.max().x()}, {box.min().y(), box.max().y()},
                         uniform(box.min().z(), box.max().z(), count));
}

Result<CellGrid> CellGrid::voxels(const Eigen::AlignedBox3d& box, const Eigen::Vector3i& counts) {
  if ((counts.array() < 1).any())
    return invalid_argument(fmt::format("cells: counts must be >= 1, got {} {} {}", counts.x(),
                                        counts.y(), counts.z()));
  return from_boundaries(uniform(box.min().x(), box.max().x(), counts.x()),
                         uniform(box.min().y(), box.max().y(), counts.y()),
                         uniform(box.min().z(), box.max().z(), counts.z()));
}

Eigen::Vector3i CellGrid::counts() const {
  return {static_cast<int>(x_m_.size()) - 1, static_cast<int>(y_m_.size()) - 1,
          static_cast<int>(z_m_.size()) - 1};
}

int CellGrid::num_cells() const { return counts().prod(); }

Eigen::AlignedBox3d CellGrid::box() const {
  return {Eigen::Vector3d(x_m_.front(), y_m_.front(), z_m_.front()),
          Eigen::Vector3d(x_m_.back(), y_m_.back(), z_m_.back())};
}

Eigen::AlignedBox3d CellGrid::cell_box(int cell) const {
  const Eigen::Vector3i n = counts();
  const int i = cell % n.x(), j = (cell / n.x()) % n.y(), k = cell / (n.x() * n.y());
  const auto ui = static_cast<std::size_t>(i), uj = static_cast<std::size_t>(j),
             uk = static_cast<std::size_t>(k);
  return {Eigen::Vector3d(x_m_[ui], y_m_[uj], z_m_[uk]),
          Eigen::Vector3d(x_m_[ui + 1], y_m_[uj + 1], z_m_[uk + 1])};
}

int CellGrid::cell_of(const Eigen::Vector3d& p) const {
  const Eigen::Vector3i n = counts();
  return locate(x_m_, p.x()) + n.x() * (locate(y_m_, p.y()) + n.y() * locate(z_m_, p.z()));
}

std::vector<int> element_cells(const TetMesh& mesh, const CellGrid& grid) {
  std::vector<int> out(static_cast<std::size_t>(mesh.num_tets()));
  for (Eigen::Index t = 0; t < mesh.num_tets(); ++t) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (int k = 0; k < 4; ++k) c += mesh.nodes.row(mesh.tets(t, k)).transpose() / 4.0;
    out[static_cast<std::size_t>(t)] = grid.cell_of(c);
  }
  return out;
}

Eigen::AlignedBox3d mesh_box(const TetMesh& mesh) {
  Eigen::AlignedBox3d b;
  for (Eigen::Index i = 0; i < mesh.num_nodes(); ++i) b.extend(mesh.nodes.row(i).transpose());
  return b;
}

CompositeMaterial::CompositeMaterial(std::vector<const BaseMaterial*> per_element)
    : per_element_(std::move(per_element)) {
  for (const BaseMaterial* m : per_element_)
    anisotropic_ = anisotropic_ || m->model() == BaseModel::kTransverse;
}

fem::LambdaAlpha CompositeMaterial::params(Eigen::Index element, const Vector6d& strain) const {
  return isotropic_stand_in(elasticity(element, strain));
}

Matrix6d CompositeMaterial::elasticity(Eigen::Index element, const Vector6d& strain) const {
  return per_element_[static_cast<std::size_t>(element)]->elasticity(strain);
}

Result<CompositeMaterial> make_composite(const std::vector<BaseMaterial>& library,
                                         const std::vector<int>& element_cell,
                                         const std::vector<int>& design, int num_cells) {
  if (static_cast<int>(design.size()) != num_cells)
    return invalid_argument(
        fmt::format("design has {} cells, the cell grid {}", design.size(), num_cells));
  for (std::size_t c = 0; c < design.size(); ++c)
    if (design[c] < 0 || design[c] >= static_cast<int>(library.size()))
      return invalid_argument(fmt::format("design cell {}: material {} is out of range ({} base "
                                          "materials)",
                                          c, design[c], library.size()));
  std::vector<const BaseMaterial*> per(element_cell.size());
  for (std::size_t e = 0; e < element_cell.size(); ++e) {
    const int c = element_cell[e];
    if (c < 0 || c >= num_cells)
      return invalid_argument(fmt::format("element {} lies in no cell", e));
    per[e] = &library[static_cast<std::size_t>(design[static_cast<std::size_t>(c)])];
  }
  return CompositeMaterial(std::move(per));
}

Status ForwardOptions::validate() const {
  if (steps < 1) return invalid_argument(fmt::format("steps must be >= 1, got {}", steps));
  if (!(tolerance_rel > 0 && tolerance_rel < 1))
    return invalid_argument(fmt::format("tolerance_rel must be in (0, 1), got {}", tolerance_rel));
  if (max_iterations < 1)
    return invalid_argument(fmt::format("max_iterations must be >= 1, got {}", max_iterations));
  return {};
}

Status simulate_forces(fem::CorotationalFem* fem, const fem::MaterialModel& material,
                       const MatrixX3d& forces, const ForwardOptions& options) {
  fem::IncrementalOptions io;
  io.steps = options.steps;
  io.update_within_step = true;  // parameters consistent with the final strain of each increment
  io.contact.tolerance_rel = options.tolerance_rel;
  io.contact.max_iterations = options.max_iterations;
  fem::IncrementalSummary summary;
  return fem::run_incremental_forces(fem, material, forces, io, &summary);
}

MatrixX3d example_forces(const material::Example& example, Eigen::Index num_nodes) {
  MatrixX3d f = MatrixX3d::Zero(num_nodes, 3);
  for (const material::NodalForce& nf : example.forces) f.row(nf.node) += nf.force_n.transpose();
  return f;
}

ExampleError example_error(const material::Example& example, const MatrixX3d& positions) {
  ExampleError e;
  std::vector<char> fixed(static_cast<std::size_t>(positions.rows()), 0);
  for (int f : example.fixed_nodes) fixed[static_cast<std::size_t>(f)] = 1;
  for (Eigen::Index k = 0; k < positions.rows(); ++k) {
    const auto uk = static_cast<std::size_t>(k);
    if (!example.visible[uk] || fixed[uk]) continue;
    const double d = (positions.row(k) - example.positions_m.row(k)).norm();
    e.sum_sq_m2 += d * d;
    e.max_m = std::max(e.max_m, d);
    ++e.nodes;
  }
  return e;
}

struct ExampleSimulator::Impl {
  const material::Samples* samples = nullptr;
  ForwardOptions options;
  std::vector<fem::CorotationalFem> fems;
  std::vector<MatrixX3d> forces;
};

ExampleSimulator::ExampleSimulator(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
ExampleSimulator::ExampleSimulator(ExampleSimulator&&) noexcept = default;
ExampleSimulator& ExampleSimulator::operator=(ExampleSimulator&&) noexcept = default;
ExampleSimulator::~ExampleSimulator() = default;

Result<ExampleSimulator> ExampleSimulator::create(const material::Samples& samples,
                                                  const ForwardOptions& options) {
  HC_RETURN_IF_ERROR(options.validate());
  auto impl = std::make_unique<Impl>();
  impl->samples = &samples;
  impl->options = options;
  for (std::size_t i = 0; i < samples.examples.size(); ++i) {
    const material::Example& ex = samples.examples[i];
    Result<fem::CorotationalFem> f = fem::CorotationalFem::create(samples.mesh, ex.fixed_nodes);
    if (!f.ok()) return f.status().with_context(fmt::format("examples[{}]", i));
    impl->fems.push_back(std::move(f).value());
    impl->forces.push_back(example_forces(ex, samples.mesh.num_nodes()));
  }
  return ExampleSimulator(std::move(impl));
}

std::size_t ExampleSimulator::num_examples() const { return impl_->fems.size(); }

Result<MatrixX3d> ExampleSimulator::simulate(std::size_t i, const fem::MaterialModel& material) {
  fem::CorotationalFem& f = impl_->fems[i];
  const Status st = simulate_forces(&f, material, impl_->forces[i], impl_->options);
  if (!st.ok()) return st.with_context(fmt::format("examples[{}]", i));
  return f.positions();
}

Result<std::vector<MatrixX3d>> ExampleSimulator::simulate_all(const fem::MaterialModel& material,
                                                              double* rms_m) {
  std::vector<MatrixX3d> out;
  double sum = 0;
  Eigen::Index nodes = 0;
  for (std::size_t i = 0; i < num_examples(); ++i) {
    HC_ASSIGN_OR_RETURN(MatrixX3d x, simulate(i, material));
    const ExampleError e = example_error(impl_->samples->examples[i], x);
    sum += e.sum_sq_m2;
    nodes += e.nodes;
    out.push_back(std::move(x));
  }
  if (rms_m != nullptr) *rms_m = nodes > 0 ? std::sqrt(sum / static_cast<double>(nodes)) : 0.0;
  return out;
}

}  // namespace hc::composite
