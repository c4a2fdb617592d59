#include "fabrication/composite/base_fit.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>

#include "common/clock.h"
#include "fit_example.h"
#include "processing/fem/blas_threads.h"

namespace hc::composite {
namespace {

using Clock = std::chrono::steady_clock;

// Examples whose total forces lie within this relative distance share a force level (Table 5.8.1).
constexpr double kForceLevelTolerance = 0.05;
// Forces count as parallel when every nodal force's component perpendicular to the total is below
// this fraction of the force.
constexpr double kParallelTolerance = 1e-6;
// The Levenberg-Marquardt damping: start, growth on a rejected step, largest before giving up.
constexpr double kLmInitialDamping = 1e-3;
constexpr double kLmDampingGrowth = 10;
constexpr double kLmMaxDamping = 1e12;

Eigen::VectorXd flatten(const Eigen::MatrixXd& v) {
  Eigen::VectorXd out(v.size());
  for (Eigen::Index j = 0; j < v.rows(); ++j) out.segment(j * v.cols(), v.cols()) = v.row(j);
  return out;
}
Eigen::MatrixXd unflatten(const Eigen::VectorXd& x, Eigen::Index rows, Eigen::Index cols) {
  Eigen::MatrixXd v(rows, cols);
  for (Eigen::Index j = 0; j < rows; ++j) v.row(j) = x.segment(j * cols, cols).transpose();
  return v;
}

struct LmResult {
  int iterations = 0;
  double cost = 0;
};

// Levenberg-Marquardt with Marquardt's diagonal scaling (so the Pa-sized parameters of different
// magnitudes need no manual scaling) and a projection of the iterate after every step.
// Small and specific (projection, parallel example evaluation) so written here rather than bent
// into Ceres, which cannot project between iterations.
Result<LmResult> levenberg_marquardt(std::vector<FitExample>& examples, BaseMaterial* material,
                                     const BaseFitOptions& options) {
  const Eigen::Index p = material->num_centres();
  const Eigen::Index k = parameter_count(material->model());
  // The stacked residuals, and the Jacobian when j is given.
  const auto stack = [&](Eigen::VectorXd* r, Eigen::MatrixXd* j) -> Status {
    std::vector<Status> st(examples.size());
    std::vector<Eigen::VectorXd> rs(examples.size());
    std::vector<Eigen::MatrixXd> js(examples.size());
    tbb::parallel_for(std::size_t{0}, examples.size(), [&](std::size_t i) {
      st[i] = examples[i].residual(*material, &rs[i]);
      if (st[i].ok() && j != nullptr) st[i] = examples[i].jacobian(*material, &js[i]);
    });
    Eigen::Index rows = 0;
    for (std::size_t i = 0; i < examples.size(); ++i) {
      HC_RETURN_IF_ERROR(st[i]);
      rows += rs[i].size();
    }
    r->resize(rows);
    if (j != nullptr) j->resize(rows, p * k);
    Eigen::Index at = 0;
    for (std::size_t i = 0; i < examples.size(); ++i) {
      r->segment(at, rs[i].size()) = rs[i];
      if (j != nullptr) j->middleRows(at, rs[i].size()) = js[i];
      at += rs[i].size();
    }
    return {};
  };
  Eigen::VectorXd r;
  Eigen::MatrixXd jac;
  HC_RETURN_IF_ERROR(stack(&r, &jac));
  LmResult out;
  out.cost = 0.5 * r.squaredNorm();
  double damping = kLmInitialDamping;
  for (int it = 0; it < options.max_iterations; ++it) {
    const Eigen::MatrixXd jtj = jac.transpose() * jac;
    const Eigen::VectorXd g = jac.transpose() * r;
    const Eigen::VectorXd d = jtj.diagonal().cwiseMax(1e-300);
    bool accepted = false;
    while (damping <= kLmMaxDamping) {
      Eigen::MatrixXd a = jtj;
      a.diagonal() += damping * d;
      const Eigen::VectorXd step = a.ldlt().solve(-g);
      const Eigen::VectorXd x = flatten(material->values()) + step;
      BaseMaterial trial = material->with_values(unflatten(x, p, k));
      std::swap(*material, trial);
      Eigen::VectorXd r2;
      const Status st = stack(&r2, nullptr);
      const double cost = st.ok() ? 0.5 * r2.squaredNorm() : std::numeric_limits<double>::max();
      if (cost < out.cost) {
        const double decrease = (out.cost - cost) / out.cost;
        out.cost = cost;
        damping = std::max(damping / kLmDampingGrowth, 1e-12);
        accepted = true;
        ++out.iterations;
        if (decrease < options.function_tolerance) return out;
        HC_RETURN_IF_ERROR(stack(&r, &jac));
        break;
      }
      std::swap(*material, trial);  // reject: back to the previous values
      damping *= kLmDampingGrowth;
    }
    if (!accepted) break;  // no step lowers the cost: converged to the damping's resolution
  }
  // Leave every example solved at the final values (the Jacobian pass above may be stale).
  HC_RETURN_IF_ERROR(stack(&r, nullptr));
  return out;
}

// Centres: the zero strain, then farthest-point sampling of the examples' strain features, the
// farthest outlier_fraction by norm left out.
Eigen::MatrixXd select_centres(BaseModel model, const std::vector<FitExample>& examples, int count,
                               double outlier_fraction) {
  const int d = feature_count(model);
  std::vector<Eigen::VectorXd> pts;
  for (const FitExample& ex : examples)
    for (const Eigen::VectorXd& f : ex.features()) pts.push_back(f);
  std::vector<double> norms(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) norms[i] = pts[i].norm();
  std::vector<double> sorted = norms;
  std::sort(sorted.begin(), sorted.end());
  const double cut = sorted.empty() ? 0.0
                                    : sorted[static_cast<std::size_t>(std::floor(
                                          (1.0 - outlier_fraction) * (sorted.size() - 1)))];
  std::vector<Eigen::VectorXd> candidates;
  for (std::size_t i = 0; i < pts.size(); ++i)
    if (norms[i] <= cut) candidates.push_back(pts[i]);
  std::vector<Eigen::VectorXd> centres{Eigen::VectorXd::Zero(d)};
  std::vector<double> dist(candidates.size());
  for (std::size_t i = 0; i < candidates.size(); ++i) dist[i] = candidates[i].norm();
  // Centres closer than this to the others would make the RBF system near-singular.
  const double min_separation = 1e-6 * std::max(cut, 1e-300);
  while (static_cast<int>(centres.size()) < count && !candidates.empty()) {
    const auto best = std::max_element(dist.begin(), dist.end()) - dist.begin();
    if (!(dist[static_cast<std::size_t>(best)] > min_separation)) break;
    const Eigen::VectorXd c = candidates[static_cast<std::size_t>(best)];
    centres.push_back(c);
    for (std::size_t i = 0; i < candidates.size(); ++i)
      dist[i] = std::min(dist[i], (candidates[i] - c).norm());
  }
  Eigen::MatrixXd out(static_cast<Eigen::Index>(centres.size()), d);
  for (std::size_t i = 0; i < centres.size(); ++i)
    out.row(static_cast<Eigen::Index>(i)) = centres[i].transpose();
  return out;
}

// The homogeneous start: a unit material's linear displacements scaled onto the measured ones.
Result<Eigen::VectorXd> stiffness_guess(BaseModel model, std::vector<FitExample>& examples) {
  constexpr double kPoisson = 0.3;
  Eigen::VectorXd unit(2);
  unit << kPoisson / ((1 + kPoisson) * (1 - 2 * kPoisson)), 0.5 / (1 + kPoisson);  // E = 1 Pa
  HC_ASSIGN_OR_RETURN(BaseMaterial m,
                      BaseMaterial::create(BaseModel::kIsotropic, Eigen::MatrixXd::Zero(1, 3),
                                           unit.transpose(), FeasibilityLimits{}));
  double uu = 0, um = 0;
  for (FitExample& ex : examples) {
    HC_ASSIGN_OR_RETURN(const auto dots, ex.unit_displacement_dots(m));
    uu += dots.first;
    um += dots.second;
  }
  if (!(um > 0))
    return invalid_argument(
        "the measured displacements do not follow the forces (a unit material's displacements "
        "point the other way): check the force signs and units");
  const double e = uu / um;  // displacements scale with 1/E
  Eigen::VectorXd p = e * unit;
  if (model == BaseModel::kIsotropic) return p;
  Eigen::VectorXd t(5);
  t << p(0) + 2 * p(1), p(0), p(0), p(0) + 2 * p(1), p(1);
  return t;
}

double floor_modulus(BaseModel model, const Eigen::VectorXd& p) {
  if (model == BaseModel::kIsotropic) {
    const double lambda = p(0), mu = p(1);
    return mu * (3 * lambda + 2 * mu) / (lambda + mu);
  }
  Eigen::Matrix2d m;
  m << p(0) + p(1), 1.4142135623730951 * p(2), 1.4142135623730951 * p(2), p(3);
  return std::min({p(0) - p(1), p(4),
                   Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(m).eigenvalues().minCoeff()});
}

Status simulate_state(std::vector<FitExample>& examples, const BaseMaterial& material) {
  std::vector<Status> st(examples.size());
  tbb::parallel_for(std::size_t{0}, examples.size(),
                    [&](std::size_t i) { st[i] = examples[i].simulate_full(material); });
  for (const Status& s : st) HC_RETURN_IF_ERROR(s);
  return {};
}

}  // namespace

Status BaseFitOptions::validate() const {
  if (centres < 0) return invalid_argument(fmt::format("centres must be >= 0, got {}", centres));
  if (passes < 1) return invalid_argument(fmt::format("passes must be >= 1, got {}", passes));
  if (max_iterations < 1)
    return invalid_argument(fmt::format("max_iterations must be >= 1, got {}", max_iterations));
  if (!(function_tolerance > 0)) return invalid_argument("function_tolerance must be > 0");
  if (!(outlier_fraction >= 0 && outlier_fraction < 0.5))
    return invalid_argument(
        fmt::format("outlier_fraction must be in [0, 0.5), got {}", outlier_fraction));
  if (!(min_modulus_fraction > 0 && min_modulus_fraction < 1))
    return invalid_argument("min_modulus_fraction must be in (0, 1)");
  const FeasibilityLimits limits{1.0, min_poisson, max_poisson};
  HC_RETURN_IF_ERROR(limits.validate().with_context("limits"));
  return forward.validate();
}

std::vector<ForceLevelError> force_level_errors(const material::Samples& samples,
                                                const std::vector<MatrixX3d>& positions) {
  struct Item {
    double force;
    std::size_t example;
  };
  std::vector<Item> items;
  for (std::size_t i = 0; i < samples.examples.size(); ++i) {
    const material::Example& ex = samples.examples[i];
    Eigen::Vector3d total = Eigen::Vector3d::Zero();
    for (const material::NodalForce& f : ex.forces) total += f.force_n;
    // The force a probe's sensor measures: along the probe (the contact forces' sideways parts
    // on a few nodes need not cancel); the whole force without a probe.
    const double force =
        ex.probe.shape == "none" ? total.norm() : std::abs(total.dot(ex.probe.direction));
    items.push_back({force, i});
  }
  std::sort(items.begin(), items.end(),
            [](const Item& a, const Item& b) { return a.force < b.force; });
  std::vector<ForceLevelError> out;
  std::size_t start = 0;
  while (start < items.size()) {
    std::size_t end = start + 1;
    while (end < items.size() &&
           items[end].force <= items[start].force * (1 + kForceLevelTolerance) + 1e-12)
      ++end;
    ForceLevelError level;
    std::vector<double> d;
    for (std::size_t i = start; i < end; ++i) {
      const material::Example& ex = samples.examples[items[i].example];
      level.force_n += items[i].force / static_cast<double>(end - start);
      ++level.examples;
      std::vector<char> fixed(static_cast<std::size_t>(samples.mesh.num_nodes()), 0);
      for (int f : ex.fixed_nodes) fixed[static_cast<std::size_t>(f)] = 1;
      const MatrixX3d& x = positions[items[i].example];
      for (Eigen::Index n = 0; n < x.rows(); ++n)
        if (ex.visible[static_cast<std::size_t>(n)] && !fixed[static_cast<std::size_t>(n)])
          d.push_back((x.row(n) - ex.positions_m.row(n)).norm());
    }
    level.nodes = static_cast<Eigen::Index>(d.size());
    if (!d.empty()) {
      for (double v : d) level.avg_m += v / static_cast<double>(d.size());
      for (double v : d) level.std_m += (v - level.avg_m) * (v - level.avg_m);
      level.std_m = std::sqrt(level.std_m / static_cast<double>(d.size()));
      level.max_m = *std::max_element(d.begin(), d.end());
    }
    out.push_back(level);
    start = end;
  }
  return out;
}

Result<BaseEvaluation> evaluate_base_material(const BaseMaterial& material,
                                              const material::Samples& samples,
                                              const ForwardOptions& options) {
  HC_RETURN_IF_ERROR(material::validate_samples(samples));
  HC_ASSIGN_OR_RETURN(ExampleSimulator sim, ExampleSimulator::create(samples, options));
  const CompositeMaterial composite(std::vector<const BaseMaterial*>(
      static_cast<std::size_t>(samples.mesh.num_tets()), &material));
  BaseEvaluation out;
  HC_ASSIGN_OR_RETURN(out.positions, sim.simulate_all(composite, &out.rms_error_m));
  for (std::size_t i = 0; i < out.positions.size(); ++i)
    out.max_error_m =
        std::max(out.max_error_m, example_error(samples.examples[i], out.positions[i]).max_m);
  out.max_displacement_m = samples.max_displacement_m();
  out.levels = force_level_errors(samples, out.positions);
  return out;
}

Result<BaseMaterial> fit_base_material(const std::vector<const material::Samples*>& samples,
                                       const BaseFitOptions& options, BaseFitSummary* summary) {
  const auto t0 = Clock::now();
  HC_RETURN_IF_ERROR(options.validate());
  if (samples.empty()) return invalid_argument("fit base: no samples");
  std::vector<FitExample> examples;
  for (std::size_t s = 0; s < samples.size(); ++s) {
    HC_RETURN_IF_ERROR(
        material::validate_samples(*samples[s]).with_context(fmt::format("samples {}", s)));
    for (std::size_t i = 0; i < samples[s]->examples.size(); ++i) {
      Result<FitExample> ex = FitExample::create(*samples[s], i, options.model, options.forward);
      if (!ex.ok()) return ex.status().with_context(fmt::format("samples {}, examples[{}]", s, i));
      examples.push_back(std::move(ex).value());
    }
  }
  std::optional<fem::SingleThreadedBlasScope> blas;  // examples run in parallel
  if (examples.size() > 1) blas.emplace();
  BaseFitSummary local;
  BaseFitSummary& sum = summary != nullptr ? *summary : local;
  sum = BaseFitSummary{};
  const BaseModel model = options.model;
  const int centres = options.centres > 0 ? options.centres : default_centres(model);

  // 1. Homogeneous linear material, rotations at rest.
  HC_ASSIGN_OR_RETURN(Eigen::VectorXd guess, stiffness_guess(model, examples));
  FeasibilityLimits limits{options.min_modulus_fraction * floor_modulus(model, guess),
                           options.min_poisson, options.max_poisson};
  HC_ASSIGN_OR_RETURN(BaseMaterial mat,
                      BaseMaterial::create(model, Eigen::MatrixXd::Zero(1, feature_count(model)),
                                           guess.transpose(), limits));
  if (options.progress) options.progress->begin("fit base material", options.passes + 2);
  for (FitExample& ex : examples) ex.hold_state(mat, /*at_rest=*/true);
  HC_ASSIGN_OR_RETURN(LmResult lm, levenberg_marquardt(examples, &mat, options));
  sum.iterations += lm.iterations;

  // 2. Missing tangential forces, then the homogeneous fit again with them.
  for (FitExample& ex : examples) {
    const bool parallel = ex.forces_parallel(kParallelTolerance);
    if (options.tangential == TangentialForces::kOn ||
        (options.tangential == TangentialForces::kAuto && parallel)) {
      HC_RETURN_IF_ERROR(ex.recover_tangential_forces(mat));
      ++sum.tangential_examples;
    }
  }
  if (sum.tangential_examples > 0) {
    HC_ASSIGN_OR_RETURN(lm, levenberg_marquardt(examples, &mat, options));
    sum.iterations += lm.iterations;
  }
  sum.homogeneous = mat.values().row(0).transpose();
  limits.min_modulus_pa = options.min_modulus_fraction * floor_modulus(model, sum.homogeneous);
  HC_ASSIGN_OR_RETURN(mat, BaseMaterial::create(model, mat.centres(), mat.values(), limits));
  if (options.progress) options.progress->update(1);

  // 3. Passes: full simulation, centres over the strains, LM at the held state.
  HC_RETURN_IF_ERROR(simulate_state(examples, mat));
  sum.homogeneous_rms_error_m = FitExample::rms_error(examples);
  // The passes need not improve monotonically (new centres, new held state): keep the best.
  BaseMaterial best = mat;
  double best_rms = sum.homogeneous_rms_error_m;
  bool best_is_state = true;  // the examples' states are the best material's
  for (int pass = 0; pass < options.passes; ++pass) {
    const Eigen::MatrixXd c = select_centres(model, examples, centres, options.outlier_fraction);
    Eigen::MatrixXd values(c.rows(), parameter_count(model));
    for (Eigen::Index j = 0; j < c.rows(); ++j)
      values.row(j) = mat.params_at_features(c.row(j).transpose()).transpose();
    HC_ASSIGN_OR_RETURN(mat, BaseMaterial::create(model, c, values, limits));
    for (FitExample& ex : examples) ex.hold_state(mat, /*at_rest=*/false);
    HC_ASSIGN_OR_RETURN(lm, levenberg_marquardt(examples, &mat, options));
    sum.iterations += lm.iterations;
    HC_RETURN_IF_ERROR(simulate_state(examples, mat));
    sum.pass_rms_error_m.push_back(FitExample::rms_error(examples));
    best_is_state = sum.pass_rms_error_m.back() < best_rms;
    if (best_is_state) {
      best_rms = sum.pass_rms_error_m.back();
      best = mat;
    }
    ++sum.passes;
    if (options.progress) options.progress->update(static_cast<std::uint64_t>(pass) + 2);
  }

  // 4. Report from the full simulations of the best material.
  mat = std::move(best);
  if (!best_is_state) HC_RETURN_IF_ERROR(simulate_state(examples, mat));
  sum.centres = static_cast<int>(mat.num_centres());
  sum.rms_error_m = FitExample::rms_error(examples);
  std::size_t at = 0;
  for (const material::Samples* s : samples) {
    std::vector<MatrixX3d> pos;
    for (std::size_t i = 0; i < s->examples.size(); ++i) pos.push_back(examples[at++].state());
    for (std::size_t i = 0; i < pos.size(); ++i)
      sum.max_error_m = std::max(sum.max_error_m, example_error(s->examples[i], pos[i]).max_m);
    std::vector<ForceLevelError> levels = force_level_errors(*s, pos);
    sum.levels.insert(sum.levels.end(), levels.begin(), levels.end());
  }
  sum.time_s = seconds_since(t0);
  if (options.progress) options.progress->end(fmt::format("rms {:.3g} m", sum.rms_error_m));
  return mat;
}

}  // namespace hc::composite
