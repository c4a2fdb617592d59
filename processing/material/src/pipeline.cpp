// The heterogeneous fitting pipeline (thesis Sec. 4.3) and the evaluation of a material against
// samples (Sec. 4.5's error measure).
#include <fmt/format.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <mutex>
#include <optional>

#include "common/clock.h"
#include "processing/fem/blas_threads.h"
#include "processing/fem/incremental.h"
#include "processing/material/fit.h"
#include "processing/material/rbf_fit.h"

namespace hc::material {
namespace {
using Clock = std::chrono::steady_clock;
}  // namespace

Status HeterogeneousFitOptions::validate() const {
  HC_RETURN_IF_ERROR(parameters.validate());
  if (!(rbf.tolerance >= 0)) return invalid_argument("rbf.tolerance: must be >= 0");
  if (rbf.max_basis < 1) return invalid_argument("rbf.max_basis: must be >= 1");
  if (threads < 0) return invalid_argument("threads: must be >= 0");
  HC_RETURN_IF_ERROR(joint.validate());
  return {};
}

Result<Material> fit_heterogeneous(const Samples& samples, const HeterogeneousFitOptions& options,
                                   HeterogeneousFitSummary* summary) {
  HC_RETURN_IF_ERROR(options.validate());
  HC_RETURN_IF_ERROR(validate_samples(samples));
  const auto t0 = Clock::now();
  const std::size_t n = samples.examples.size();
  const Eigen::Index t = samples.mesh.num_tets();
  // One factorisation per example on every core: OpenBLAS's threads would oversubscribe them
  // (one example keeps them: nothing else runs beside its factorisations).
  std::optional<fem::SingleThreadedBlasScope> blas;
  if (n > 1) blas.emplace();
  if (options.joint.enabled && options.parameters.solver == FitSolver::kDense) {
    // Fail before the per-example fits when the dense joint fit's Jacobian would be too large.
    double rows = 0;
    for (const Example& ex : samples.examples)
      for (std::size_t k = 0; k < ex.visible.size(); ++k)
        if (ex.visible[k] &&
            !std::binary_search(ex.fixed_nodes.begin(), ex.fixed_nodes.end(), static_cast<int>(k)))
          rows += 3;
    const double bytes = 8.0 * rows * options.joint.parameters_per_tet() * static_cast<double>(t);
    if (bytes > options.joint.max_jacobian_bytes)
      return failed_precondition(fmt::format(
          "joint material fit: its dense Jacobian would take {:.1f} GB (limit {:.1f} GB); use "
          "the matrix-free solver",
          bytes / 1e9, options.joint.max_jacobian_bytes / 1e9));
  }

  // The regulariser and the preconditioner's coarse space, the same for every example.
  HC_ASSIGN_OR_RETURN(const std::shared_ptr<const ExampleFitSetup> setup,
                      make_example_fit_setup(samples.mesh, options.parameters));
  std::vector<std::optional<ExampleProblem>> problems(n);
  std::vector<std::vector<LambdaAlpha>> params(n);
  std::vector<Eigen::Matrix<double, Eigen::Dynamic, 6>> strains(n);
  std::vector<ParameterFitSummary> fits(n);
  std::vector<Status> statuses(n);
  std::atomic<std::uint64_t> done{0};
  if (options.progress) options.progress->begin("fit examples", n);

  std::optional<tbb::global_control> limit;
  if (options.threads > 0)
    limit.emplace(tbb::global_control::max_allowed_parallelism,
                  static_cast<std::size_t>(options.threads));
  tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
    const auto run = [&]() -> Status {
      Result<ExampleProblem> p = ExampleProblem::create(samples.mesh, samples.examples[i],
                                                        options.parameters.initial_poisson);
      if (!p.ok()) return p.status();
      problems[i].emplace(std::move(p).value());
      ExampleProblem& problem = *problems[i];
      // Per-example uniform start (2 parameters), then the per-element fit from there.
      Result<LambdaAlpha> uniform = fit_homogeneous({&problem}, options.parameters);
      if (!uniform.ok()) return uniform.status();
      HC_RETURN_IF_ERROR(
          fit_example(&problem, {*uniform}, options.parameters, &params[i], &fits[i], setup.get()));
      Eigen::VectorXd r;
      HC_RETURN_IF_ERROR(problem.simulate(params[i], &r));
      strains[i] = problem.strains();
      // Frees the FEM and its factorisation unless the joint material fit needs it again.
      if (!options.joint.enabled) problems[i].reset();
      return {};
    };
    Status st = run();
    if (!st.ok()) st = st.with_context(fmt::format("examples[{}]", i));
    statuses[i] = st;
    if (options.progress) options.progress->update(++done);
  });
  if (options.progress) options.progress->end("");
  for (const Status& st : statuses) HC_RETURN_IF_ERROR(st);
  const double parameter_time = seconds_since(t0);

  // Per element: greedy RBF over the examples' (strain, parameters).
  const auto t1 = Clock::now();
  Material material;
  material.kind = MaterialKind::kHeterogeneous;
  material.rbfs.resize(static_cast<std::size_t>(t));
  std::vector<int> basis(static_cast<std::size_t>(t), 0);
  std::vector<Status> rbf_status(static_cast<std::size_t>(t));
  RbfFitOptions rbf_options;
  rbf_options.tolerance = options.rbf.tolerance;
  rbf_options.max_basis = options.rbf.max_basis;
  rbf_options.lambda_floor_fraction = options.rbf.lambda_floor_fraction;
  rbf_options.max_poisson = options.parameters.max_poisson;
  tbb::parallel_for(Eigen::Index{0}, t, [&](Eigen::Index e) {
    std::vector<Vector6d> s(n);
    std::vector<Eigen::Vector2d> p(n);
    for (std::size_t i = 0; i < n; ++i) {
      s[i] = strains[i].row(e).transpose();
      const LambdaAlpha& pe = params[i][static_cast<std::size_t>(e)];
      p[i] = Eigen::Vector2d(pe.lambda, pe.alpha);
    }
    RbfFitSummary rs;
    Result<StrainRbf> rbf = fit_strain_rbf(s, p, rbf_options, &rs);
    if (!rbf.ok()) {
      rbf_status[static_cast<std::size_t>(e)] = rbf.status().with_context(fmt::format("tet {}", e));
      return;
    }
    material.rbfs[static_cast<std::size_t>(e)] = std::move(rbf).value();
    basis[static_cast<std::size_t>(e)] = rs.basis_size;
  });
  for (const Status& st : rbf_status) HC_RETURN_IF_ERROR(st);
  const double rbf_time = seconds_since(t1);

  const auto t2 = Clock::now();
  ParameterFitSummary joint;
  if (options.joint.enabled) {
    std::vector<ExampleProblem*> ptrs;
    for (auto& p : problems) ptrs.push_back(&*p);
    JointRefinementOptions joint_options = options.joint;
    if (joint_options.progress == nullptr) joint_options.progress = options.progress;
    Result<Material> joint_material =
        fit_joint_material(ptrs, &strains, params, options.parameters, joint_options, &joint);
    if (!joint_material.ok()) return joint_material.status().with_context("joint material fit");
    material = std::move(joint_material).value();
    for (Eigen::Index e = 0; e < t; ++e)
      basis[static_cast<std::size_t>(e)] =
          static_cast<int>(material.rbfs[static_cast<std::size_t>(e)].size());
    problems.clear();
  }

  if (summary) {
    *summary = HeterogeneousFitSummary{};
    double sum = 0, nodes = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const double k = static_cast<double>(samples.examples[i].visible.size());
      sum += fits[i].rms_error_m * fits[i].rms_error_m * k;
      nodes += k;
      summary->max_error_m = std::max(summary->max_error_m, fits[i].max_error_m);
    }
    summary->rms_error_m = std::sqrt(sum / std::max(nodes, 1.0));
    double b = 0;
    for (int x : basis) b += x;
    summary->mean_basis_size = b / static_cast<double>(std::max<Eigen::Index>(t, 1));
    summary->parameter_time_s = parameter_time;
    summary->rbf_time_s = rbf_time;
    summary->joint_time_s = seconds_since(t2);
    summary->joint = joint;
    summary->time_s = seconds_since(t0);
    summary->examples = std::move(fits);
  }
  return material;
}

Result<EvaluateSummary> evaluate_material(const fem::MaterialModel& material,
                                          const Samples& samples, const EvaluateOptions& options) {
  HC_RETURN_IF_ERROR(validate_samples(samples));
  if (options.steps < 1) return invalid_argument("steps: must be >= 1");
  if (options.threads < 0) return invalid_argument("threads: must be >= 0");
  if (material.num_elements() >= 0 && material.num_elements() != samples.mesh.num_tets())
    return invalid_argument(fmt::format("the material describes {} elements, the mesh has {} tets",
                                        material.num_elements(), samples.mesh.num_tets()));
  const auto t0 = Clock::now();
  const std::size_t n = samples.examples.size();
  std::optional<fem::SingleThreadedBlasScope> blas;  // as in fit_heterogeneous
  if (n > 1) blas.emplace();
  EvaluateSummary out;
  out.example_rms_error_m.assign(n, 0);
  out.positions.resize(n);
  std::vector<Status> statuses(n);
  std::vector<double> sums(n, 0), maxes(n, 0);
  std::vector<Eigen::Index> counts(n, 0);
  std::atomic<std::uint64_t> done{0};
  if (options.progress) options.progress->begin("evaluate examples", n);
  std::optional<tbb::global_control> limit;
  if (options.threads > 0)
    limit.emplace(tbb::global_control::max_allowed_parallelism,
                  static_cast<std::size_t>(options.threads));
  tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
    const Example& ex = samples.examples[i];
    const auto run = [&]() -> Status {
      HC_ASSIGN_OR_RETURN(fem::CorotationalFem f,
                          fem::CorotationalFem::create(samples.mesh, ex.fixed_nodes));
      MatrixX3d forces = MatrixX3d::Zero(samples.mesh.num_nodes(), 3);
      for (const NodalForce& nf : ex.forces) forces.row(nf.node) += nf.force_n.transpose();
      fem::IncrementalOptions io;
      io.steps = options.steps;
      // Parameters consistent with the final strain (as the samples were fitted), not lagged.
      io.update_within_step = true;
      fem::IncrementalSummary is;
      HC_RETURN_IF_ERROR(fem::run_incremental_forces(&f, material, forces, io, &is));
      out.positions[i] = f.positions();
      for (Eigen::Index k = 0; k < samples.mesh.num_nodes(); ++k) {
        if (!ex.visible[static_cast<std::size_t>(k)] || f.is_fixed(k)) continue;
        const double d = (f.positions().row(k) - ex.positions_m.row(k)).norm();
        sums[i] += d * d;
        maxes[i] = std::max(maxes[i], d);
        ++counts[i];
      }
      return {};
    };
    statuses[i] = run();
    if (!statuses[i].ok()) statuses[i] = statuses[i].with_context(fmt::format("examples[{}]", i));
    if (options.progress) options.progress->update(++done);
  });
  if (options.progress) options.progress->end("");
  for (const Status& st : statuses) HC_RETURN_IF_ERROR(st);
  double sum = 0;
  Eigen::Index count = 0;
  for (std::size_t i = 0; i < n; ++i) {
    sum += sums[i];
    count += counts[i];
    out.max_error_m = std::max(out.max_error_m, maxes[i]);
    out.example_rms_error_m[i] =
        counts[i] ? std::sqrt(sums[i] / static_cast<double>(counts[i])) : 0.0;
  }
  out.rms_error_m = count ? std::sqrt(sum / static_cast<double>(count)) : 0.0;
  out.max_displacement_m = samples.max_displacement_m();
  out.error_rel_max_disp =
      out.max_displacement_m > 0 ? out.rms_error_m / out.max_displacement_m : 0.0;
  out.time_s = seconds_since(t0);
  return out;
}

}  // namespace hc::material
