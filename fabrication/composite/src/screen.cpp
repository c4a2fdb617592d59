#include "fabrication/composite/screen.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <random>

#include "common/clock.h"
#include "processing/fem/blas_threads.h"
#include "processing/fem/corotational.h"
#include "processing/fem/incremental.h"

namespace hc::composite {
namespace {

using Clock = std::chrono::steady_clock;

// Per example: the reduced model and the target in reduced coordinates.
struct ReducedExample {
  Eigen::MatrixXd basis;               // ndof by r (free dofs of the FEM)
  std::vector<Eigen::MatrixXd> cell;   // [c * M + m]: r by r
  Eigen::VectorXd load;                // V^T F
  Eigen::MatrixXd measure;             // P = S V: measured coordinates by r
  std::vector<int> measured_dofs;      // free-dof index per measured coordinate
  Eigen::VectorXd rest;                // rest coordinate per measured coordinate
  // Target: G = P^T P, h = P^T ubar, c = |ubar|^2.
  Eigen::VectorXd target;              // ubar
  Eigen::MatrixXd gram;
  Eigen::MatrixXd gram_factor_t;       // L^T with gram = L L^T
  Eigen::VectorXd cross;
  double constant = 0;
  Eigen::Index nodes = 0;
};

// Stiffness of the materials at zero strain: the trace of E (for ordering from soft to stiff).
double small_strain_stiffness(const BaseMaterial& m) { return m.elasticity(Vector6d::Zero()).trace(); }

}  // namespace

Status ScreenOptions::validate() const {
  if (!(basis_tolerance > 0 && basis_tolerance < 1))
    return invalid_argument(fmt::format("basis_tolerance must be in (0, 1), got {}", basis_tolerance));
  if (max_basis < 1) return invalid_argument("max_basis must be >= 1");
  if (random_snapshots < 0) return invalid_argument("random_snapshots must be >= 0");
  return forward.validate();
}

struct Screen::Impl {
  int cells = 0;
  int materials = 0;
  std::vector<ReducedExample> ex;
  Eigen::Index nodes = 0;
  Eigen::VectorXd target_all;
  double setup_time_s = 0;
  const material::Samples* samples = nullptr;

  // |P y - ubar|^2 = y^T G y - 2 h^T y + c with y = A^-1 b; `llt` and `y` are reused workspaces.
  double example_error(std::size_t i, const Eigen::MatrixXd& a, Eigen::LLT<Eigen::MatrixXd>* llt,
                       Eigen::VectorXd* y) const {
    const ReducedExample& r = ex[i];
    llt->compute(a);
    *y = r.load;
    llt->solveInPlace(*y);
    const double gyy = (r.gram_factor_t * *y).squaredNorm();
    return std::max(0.0, gyy - 2.0 * r.cross.dot(*y) + r.constant);
  }
};

Screen::Screen(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Screen::Screen(Screen&&) noexcept = default;
Screen& Screen::operator=(Screen&&) noexcept = default;
Screen::~Screen() = default;

namespace {

// The snapshot designs: uniform blocks, each cell with each material in a block of the middle
// material, and random designs.
std::vector<std::vector<int>> snapshot_designs(int cells, const std::vector<BaseMaterial>& library,
                                               const ScreenOptions& options) {
  const int m = static_cast<int>(library.size());
  std::vector<int> by_stiffness(static_cast<std::size_t>(m));
  for (int i = 0; i < m; ++i) by_stiffness[static_cast<std::size_t>(i)] = i;
  std::sort(by_stiffness.begin(), by_stiffness.end(), [&](int a, int b) {
    return small_strain_stiffness(library[static_cast<std::size_t>(a)]) <
           small_strain_stiffness(library[static_cast<std::size_t>(b)]);
  });
  const int middle = by_stiffness[static_cast<std::size_t>(m / 2)];
  std::vector<std::vector<int>> out;
  for (int j = 0; j < m; ++j) out.emplace_back(static_cast<std::size_t>(cells), j);
  if (cells > 1) {
    for (int c = 0; c < cells; ++c)
      for (int j = 0; j < m; ++j) {
        if (j == middle) continue;
        std::vector<int> d(static_cast<std::size_t>(cells), middle);
        d[static_cast<std::size_t>(c)] = j;
        out.push_back(std::move(d));
      }
    std::mt19937_64 rng(options.seed);
    std::uniform_int_distribution<int> pick(0, m - 1);
    const int random = options.random_snapshots > 0 ? options.random_snapshots : std::max(10, cells);
    for (int k = 0; k < random; ++k) {
      std::vector<int> d(static_cast<std::size_t>(cells));
      for (int& v : d) v = pick(rng);
      out.push_back(std::move(d));
    }
  }
  return out;
}

// Secant elasticity of every element of the uniform block of each material under the example's
// forces (a full simulation each).
Result<std::vector<std::vector<Matrix6d>>> uniform_secants(
    const material::Samples& samples, std::size_t i, const std::vector<BaseMaterial>& library,
    const ForwardOptions& forward) {
  const material::Example& example = samples.examples[i];
  HC_ASSIGN_OR_RETURN(fem::CorotationalFem f,
                      fem::CorotationalFem::create(samples.mesh, example.fixed_nodes));
  const MatrixX3d forces = example_forces(example, samples.mesh.num_nodes());
  const auto t = static_cast<std::size_t>(samples.mesh.num_tets());
  std::vector<std::vector<Matrix6d>> out;
  for (const BaseMaterial& m : library) {
    const CompositeMaterial uniform(std::vector<const BaseMaterial*>(t, &m));
    HC_RETURN_IF_ERROR(simulate_forces(&f, uniform, forces, forward));
    f.update_rotations();
    std::vector<Matrix6d> e(t);
    for (std::size_t k = 0; k < t; ++k) e[k] = m.elasticity(f.strain(static_cast<Eigen::Index>(k)));
    out.push_back(std::move(e));
  }
  return out;
}

Status reduce_example(const material::Samples& samples, std::size_t i,
                      const std::vector<int>& element_cell, int cells,
                      const std::vector<BaseMaterial>& library, const ScreenOptions& options,
                      const std::vector<std::vector<int>>& snapshots, ReducedExample* out) {
  const material::Example& example = samples.examples[i];
  HC_ASSIGN_OR_RETURN(const auto secants, uniform_secants(samples, i, library, options.forward));
  fem::CorotationalOptions linear;
  linear.corotational = false;
  HC_ASSIGN_OR_RETURN(fem::CorotationalFem f,
                      fem::CorotationalFem::create(samples.mesh, example.fixed_nodes, linear));
  const MatrixX3d forces = example_forces(example, samples.mesh.num_nodes());
  const Eigen::Index ndof = f.num_free_dofs();
  const auto t = static_cast<std::size_t>(samples.mesh.num_tets());
  // Snapshots: linear solves of the frozen-secant model.
  Eigen::MatrixXd u(ndof, static_cast<Eigen::Index>(snapshots.size()));
  for (std::size_t s = 0; s < snapshots.size(); ++s) {
    std::vector<Matrix6d> e(t);
    for (std::size_t k = 0; k < t; ++k)
      e[k] = secants[static_cast<std::size_t>(snapshots[s][static_cast<std::size_t>(element_cell[k])])][k];
    HC_RETURN_IF_ERROR(f.set_elasticity(std::move(e)));
    HC_RETURN_IF_ERROR(f.set_positions(samples.mesh.nodes));
    f.set_rotations_identity();
    f.assemble();
    HC_RETURN_IF_ERROR(f.factorize());
    HC_RETURN_IF_ERROR(f.solve(forces));
    for (Eigen::Index n = 0; n < samples.mesh.num_nodes(); ++n)
      for (int c = 0; c < 3; ++c)
        if (const int d = f.dof(n, c); d >= 0)
          u(d, static_cast<Eigen::Index>(s)) = f.positions()(n, c) - samples.mesh.nodes(n, c);
  }
  // POD basis by the method of snapshots (Sirovich 1987): the eigenvectors z_i of the snapshots' Gram
  // matrix u^T u give the left singular vectors u z_i / sigma_i. Squaring the Gram matrix's condition
  // loses directions whose sigma_i / sigma_0 is below ~sqrt(eps), so the threshold is at least 1e-7.
  // (Eigen's BDCSVD of u would do the same job but costs ~45 s of compile time per build.)
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> gram_eigen(u.transpose() * u);
  const Eigen::Index s_count = u.cols();
  const Eigen::VectorXd sigma2 = gram_eigen.eigenvalues().reverse();  // descending
  const double cutoff = std::max(options.basis_tolerance, 1e-7);
  const double sigma0 = std::sqrt(std::max(sigma2(0), 0.0));
  Eigen::Index r = 0;
  while (r < s_count && r < options.max_basis && std::sqrt(std::max(sigma2(r), 0.0)) > cutoff * sigma0) ++r;
  r = std::max<Eigen::Index>(r, 1);
  out->basis.resize(ndof, r);
  for (Eigen::Index j = 0; j < r; ++j) {
    const Eigen::VectorXd z = gram_eigen.eigenvectors().col(s_count - 1 - j);
    out->basis.col(j) = u * z;
    const double norm = out->basis.col(j).norm();
    if (norm > 0) out->basis.col(j) /= norm;
  }
  // Reduced cell matrices.
  const int m = static_cast<int>(library.size());
  out->cell.assign(static_cast<std::size_t>(cells * m), Eigen::MatrixXd::Zero(r, r));
  for (std::size_t k = 0; k < t; ++k) {
    const auto e = static_cast<Eigen::Index>(k);
    const std::array<int, 12> dofs = f.element_dofs(e);
    Eigen::Matrix<double, 12, Eigen::Dynamic> ve(12, r);
    for (int a = 0; a < 12; ++a) {
      if (dofs[static_cast<std::size_t>(a)] >= 0)
        ve.row(a) = out->basis.row(dofs[static_cast<std::size_t>(a)]);
      else
        ve.row(a).setZero();
    }
    const fem::Matrix6x12d b = f.b_matrix(e);
    for (int j = 0; j < m; ++j) {
      const fem::Matrix12d ke = f.volume(e) * b.transpose() * secants[static_cast<std::size_t>(j)][k] * b;
      out->cell[static_cast<std::size_t>(element_cell[k] * m + j)].noalias() +=
          ve.transpose() * (ke * ve);
    }
  }
  Eigen::VectorXd fvec = Eigen::VectorXd::Zero(ndof);
  for (Eigen::Index n = 0; n < samples.mesh.num_nodes(); ++n)
    for (int c = 0; c < 3; ++c)
      if (const int d = f.dof(n, c); d >= 0) fvec(d) = forces(n, c);
  out->load = out->basis.transpose() * fvec;
  // Measured coordinates.
  std::vector<double> rest;
  for (Eigen::Index n = 0; n < samples.mesh.num_nodes(); ++n) {
    if (!example.visible[static_cast<std::size_t>(n)] || f.is_fixed(n)) continue;
    for (int c = 0; c < 3; ++c) {
      out->measured_dofs.push_back(f.dof(n, c));
      rest.push_back(samples.mesh.nodes(n, c));
    }
  }
  out->rest = Eigen::Map<const Eigen::VectorXd>(rest.data(), static_cast<Eigen::Index>(rest.size()));
  out->measure.resize(static_cast<Eigen::Index>(out->measured_dofs.size()), r);
  for (std::size_t q = 0; q < out->measured_dofs.size(); ++q)
    out->measure.row(static_cast<Eigen::Index>(q)) = out->basis.row(out->measured_dofs[q]);
  return {};
}

}  // namespace

Result<Screen> Screen::create(const material::Samples& samples, const CellGrid& grid,
                              const std::vector<BaseMaterial>& library,
                              const ScreenOptions& options) {
  const auto t0 = Clock::now();
  HC_RETURN_IF_ERROR(options.validate());
  HC_RETURN_IF_ERROR(material::validate_samples(samples));
  if (library.empty()) return invalid_argument("screen: the library has no base materials");
  auto impl = std::make_unique<Impl>();
  impl->cells = grid.num_cells();
  impl->materials = static_cast<int>(library.size());
  impl->samples = &samples;
  const std::vector<int> element_cell = element_cells(samples.mesh, grid);
  const std::vector<std::vector<int>> snapshots = snapshot_designs(impl->cells, library, options);
  const std::size_t n = samples.examples.size();
  impl->ex.resize(n);
  std::vector<Status> st(n);
  std::optional<fem::SingleThreadedBlasScope> blas;
  if (n > 1) blas.emplace();
  if (options.progress) options.progress->begin("screen setup", n);
  std::atomic<std::uint64_t> done{0};
  tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
    st[i] = reduce_example(samples, i, element_cell, impl->cells, library, options, snapshots,
                           &impl->ex[i]);
    if (options.progress) options.progress->update(++done);
  });
  if (options.progress) options.progress->end("");
  for (std::size_t i = 0; i < n; ++i)
    HC_RETURN_IF_ERROR(st[i].with_context(fmt::format("screen: examples[{}]", i)));
  Screen screen(std::move(impl));
  HC_RETURN_IF_ERROR(screen.set_target(samples));
  screen.impl_->setup_time_s = seconds_since(t0);
  return screen;
}

Status Screen::set_target(const material::Samples& samples) {
  Impl& s = *impl_;
  if (samples.examples.size() != s.ex.size() ||
      samples.mesh.num_nodes() != s.samples->mesh.num_nodes() ||
      samples.mesh.num_tets() != s.samples->mesh.num_tets())
    return invalid_argument("target: a different specimen or example count than the screen's");
  std::vector<Eigen::VectorXd> parts;
  Eigen::Index total = 0;
  s.nodes = 0;
  for (std::size_t i = 0; i < s.ex.size(); ++i) {
    ReducedExample& r = s.ex[i];
    const material::Example& e = samples.examples[i];
    const material::Example& base = s.samples->examples[i];
    if (e.fixed_nodes != base.fixed_nodes || e.forces.size() != base.forces.size())
      return invalid_argument(fmt::format("target examples[{}]: different forces or fixed nodes", i));
    for (std::size_t k = 0; k < e.forces.size(); ++k)
      if (e.forces[k].node != base.forces[k].node ||
          (e.forces[k].force_n - base.forces[k].force_n).norm() > 1e-12 * base.forces[k].force_n.norm())
        return invalid_argument(fmt::format("target examples[{}]: different forces", i));
    if (e.visible != base.visible)
      return invalid_argument(fmt::format("target examples[{}]: different visible nodes", i));
    r.target.resize(static_cast<Eigen::Index>(r.measured_dofs.size()));
    Eigen::Index q = 0;
    for (Eigen::Index nd = 0; nd < samples.mesh.num_nodes(); ++nd) {
      if (!e.visible[static_cast<std::size_t>(nd)]) continue;
      if (std::binary_search(e.fixed_nodes.begin(), e.fixed_nodes.end(), static_cast<int>(nd)))
        continue;
      for (int c = 0; c < 3; ++c, ++q) r.target(q) = e.positions_m(nd, c) - r.rest(q);
    }
    r.gram = r.measure.transpose() * r.measure;
    // A pivoted factor (P may have fewer rows than columns when few nodes are measured).
    {
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(r.gram);
      r.gram_factor_t = es.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal() *
                        es.eigenvectors().transpose();
    }
    r.cross = r.measure.transpose() * r.target;
    r.constant = r.target.squaredNorm();
    r.nodes = r.target.size() / 3;
    s.nodes += r.nodes;
    total += r.target.size();
    parts.push_back(r.target);
  }
  s.target_all.resize(total);
  Eigen::Index at = 0;
  for (const Eigen::VectorXd& p : parts) {
    s.target_all.segment(at, p.size()) = p;
    at += p.size();
  }
  return {};
}

int Screen::num_cells() const { return impl_->cells; }
int Screen::num_materials() const { return impl_->materials; }
std::size_t Screen::num_examples() const { return impl_->ex.size(); }
Eigen::Index Screen::basis_size(std::size_t example) const { return impl_->ex[example].basis.cols(); }
Eigen::Index Screen::measured_coordinates() const { return impl_->target_all.size(); }
Eigen::Index Screen::measured_nodes() const { return impl_->nodes; }
const Eigen::VectorXd& Screen::target_displacements() const { return impl_->target_all; }
double Screen::setup_time_s() const { return impl_->setup_time_s; }

void Screen::evaluate(const std::vector<int>& design, double* error, Eigen::VectorXd* z,
                      Eigen::VectorXd* w) const {
  const Impl& s = *impl_;
  double sum = 0;
  Eigen::LLT<Eigen::MatrixXd> llt;
  Eigen::VectorXd y;
  if (z != nullptr) z->resize(s.target_all.size());
  if (w != nullptr) {
    Eigen::Index n = 0;
    for (const ReducedExample& r : s.ex) n += r.basis.cols();
    w->resize(n);
  }
  Eigen::Index at_z = 0, at_w = 0;
  for (std::size_t i = 0; i < s.ex.size(); ++i) {
    const ReducedExample& r = s.ex[i];
    Eigen::MatrixXd a = Eigen::MatrixXd::Zero(r.basis.cols(), r.basis.cols());
    for (int c = 0; c < s.cells; ++c)
      a += r.cell[static_cast<std::size_t>(c * s.materials + design[static_cast<std::size_t>(c)])];
    sum += s.example_error(i, a, &llt, &y);
    if (z != nullptr) z->segment(at_z, r.measure.rows()) = r.measure * y;
    if (w != nullptr) w->segment(at_w, y.size()) = r.gram_factor_t * y;
    at_z += r.measure.rows();
    at_w += y.size();
  }
  if (error != nullptr) *error = s.nodes > 0 ? std::sqrt(sum / static_cast<double>(s.nodes)) : 0.0;
}

double Screen::error(const std::vector<int>& design) const {
  double e = 0;
  evaluate(design, &e, nullptr, nullptr);
  return e;
}

Eigen::VectorXd Screen::displacements(const std::vector<int>& design) const {
  Eigen::VectorXd z;
  evaluate(design, nullptr, &z, nullptr);
  return z;
}

void Screen::enumerate(const std::vector<int>& order,
                       const std::function<void(const std::vector<int>&, double)>& visit) const {
  const Impl& s = *impl_;
  const int n = s.cells;
  const int m = s.materials;
  tbb::parallel_for(0, m, [&](int first) {
    std::vector<int> design(static_cast<std::size_t>(n), 0);
    // partial[l][i]: example i's sum over the first l + 1 cells of `order`.
    std::vector<std::vector<Eigen::MatrixXd>> partial(static_cast<std::size_t>(n));
    for (auto& level : partial)
      for (const ReducedExample& r : s.ex)
        level.push_back(Eigen::MatrixXd::Zero(r.basis.cols(), r.basis.cols()));
    std::vector<Eigen::LLT<Eigen::MatrixXd>> llt(s.ex.size());
    Eigen::VectorXd y;
    std::vector<int> choice(static_cast<std::size_t>(n), 0);
    choice[0] = first;
    int level = 0;
    // Iterative depth-first walk: set level l's material, update its partial sums, descend.
    while (level >= 0) {
      const int c = order[static_cast<std::size_t>(level)];
      design[static_cast<std::size_t>(c)] = choice[static_cast<std::size_t>(level)];
      for (std::size_t i = 0; i < s.ex.size(); ++i) {
        const Eigen::MatrixXd& add =
            s.ex[i].cell[static_cast<std::size_t>(c * m + choice[static_cast<std::size_t>(level)])];
        if (level == 0)
          partial[0][i] = add;
        else
          partial[static_cast<std::size_t>(level)][i] = partial[static_cast<std::size_t>(level) - 1][i] + add;
      }
      if (level == n - 1) {
        double sum = 0;
        for (std::size_t i = 0; i < s.ex.size(); ++i)
          sum += s.example_error(i, partial[static_cast<std::size_t>(level)][i], &llt[i], &y);
        visit(design, s.nodes > 0 ? std::sqrt(sum / static_cast<double>(s.nodes)) : 0.0);
        // Next sibling, or back up.
        while (level >= 0) {
          if (level == 0) {
            level = -1;  // the first cell is fixed per task
            break;
          }
          if (++choice[static_cast<std::size_t>(level)] < m) break;
          choice[static_cast<std::size_t>(level)] = 0;
          --level;
        }
      } else {
        ++level;
        choice[static_cast<std::size_t>(level)] = 0;
      }
    }
  });
}

}  // namespace hc::composite
