#include "processing/fem/incremental.h"

#include <algorithm>
#include <chrono>
#include <limits>
#include <string>

namespace hc::fem {

Status IncrementalOptions::validate() const {
  if (steps < 1 || steps > 100000) {
    return invalid_argument("incremental loading: steps must be in [1, 100000], got " +
                            std::to_string(steps));
  }
  return contact.validate();
}

void update_params_from_strain(CorotationalFem* fem, const MaterialModel& material) {
  const Eigen::Index t = fem->num_elements();
  std::vector<LambdaAlpha> p(static_cast<size_t>(t));
  if (material.strain_dependent()) {
    for (Eigen::Index e = 0; e < t; ++e)
      p[static_cast<size_t>(e)] = material.params(e, fem->strain(e));
  } else {
    const Vector6d zero = Vector6d::Zero();
    for (Eigen::Index e = 0; e < t; ++e) p[static_cast<size_t>(e)] = material.params(e, zero);
  }
  // Sizes match by construction; non-finite material output is caught here.
  const Status st = fem->set_params(p);
  if (!st.ok()) fem->set_uniform_params(LambdaAlpha{});  // makes the next factorize() fail loudly
  if (!material.anisotropic()) {
    fem->clear_elasticity();
    return;
  }
  std::vector<Matrix6d> e(static_cast<size_t>(t));
  for (Eigen::Index i = 0; i < t; ++i) e[static_cast<size_t>(i)] = material.elasticity(i, fem->strain(i));
  if (!fem->set_elasticity(std::move(e)).ok()) {
    fem->clear_elasticity();
    fem->set_uniform_params(LambdaAlpha{});
  }
}

Status incremental_step(CorotationalFem* fem, const MaterialModel& material,
                        const MatrixX3d& forces) {
  fem->update_rotations();
  update_params_from_strain(fem, material);
  fem->assemble();
  HC_RETURN_IF_ERROR(fem->factorize());
  return fem->solve(forces);
}

namespace {

// Smallest under-relaxation factor of the nodal-force fixed point (run_incremental_forces).
constexpr double kMinRelaxation = 1.0 / 16;

double max_displacement(const CorotationalFem& fem) {
  return fem.displacements().rowwise().norm().maxCoeff();
}

Status check_material(const CorotationalFem& fem, const MaterialModel& material) {
  if (material.num_elements() >= 0 && material.num_elements() != fem.num_elements()) {
    return invalid_argument("material describes " + std::to_string(material.num_elements()) +
                            " elements, the mesh has " + std::to_string(fem.num_elements()));
  }
  return {};
}

}  // namespace

Status run_incremental(CorotationalFem* fem, const MaterialModel& material, const Probe& probe,
                       const Load& load, const IncrementalOptions& options,
                       IncrementalSummary* summary) {
  const auto t0 = std::chrono::steady_clock::now();
  HC_RETURN_IF_ERROR(options.validate());
  HC_RETURN_IF_ERROR(check_material(*fem, material));
  if (!std::isfinite(load.value) || load.value < 0) {
    return invalid_argument("load must be a finite number >= 0, got " + std::to_string(load.value));
  }
  *summary = IncrementalSummary{};
  HC_RETURN_IF_ERROR(fem->set_positions(fem->mesh().nodes));
  fem->set_rotations_identity();
  update_params_from_strain(fem, material);
  HC_ASSIGN_OR_RETURN(ContactSolver contact, ContactSolver::create(fem, probe, options.contact));
  if (options.update_within_step) contact.set_material(&material);
  ProgressTask task(options.progress, "load steps", static_cast<std::uint64_t>(options.steps));
  for (int k = 1; k <= options.steps; ++k) {
    // Explicit update: parameters from the strain of the last converged step (constant ones were
    // set above).
    if (material.strain_dependent()) {
      fem->update_rotations();
      update_params_from_strain(fem, material);
    }
    const Load step_load{load.control, load.value * k / options.steps};
    ContactSummary cs;
    const Status st = contact.solve(step_load, &cs);
    summary->total_iterations += cs.iterations;
    if (!st.ok()) return st.with_context("load step " + std::to_string(k));
    summary->steps.push_back({cs.depth_m, cs.force_n, cs.iterations});
    task.advance();
  }
  summary->max_displacement_m = max_displacement(*fem);
  summary->converged = true;
  summary->time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return {};
}

Status run_incremental_forces(CorotationalFem* fem, const MaterialModel& material,
                              const MatrixX3d& forces, const IncrementalOptions& options,
                              IncrementalSummary* summary) {
  const auto t0 = std::chrono::steady_clock::now();
  HC_RETURN_IF_ERROR(options.validate());
  HC_RETURN_IF_ERROR(check_material(*fem, material));
  if (forces.rows() != fem->num_nodes() || !forces.allFinite()) {
    return invalid_argument("nodal forces must be finite, one row per node");
  }
  *summary = IncrementalSummary{};
  HC_RETURN_IF_ERROR(fem->set_positions(fem->mesh().nodes));
  fem->set_rotations_identity();
  const double scale =
      fem->mesh().nodes.colwise().maxCoeff().norm() + fem->mesh().nodes.colwise().minCoeff().norm();
  const double tolerance = options.contact.tolerance_rel * 1e-3 * scale;
  bool all_converged = true;
  for (int k = 1; k <= options.steps; ++k) {
    const MatrixX3d fk = forces * (static_cast<double>(k) / options.steps);
    fem->update_rotations();
    update_params_from_strain(fem, material);
    int iterations = 0;
    bool converged = false;
    // Under-relaxation of the fixed point x <- K(p(eps(x)))^-1 f when parameters follow the strain
    // inside the step: for a strongly stiffening material the secant parameters are soft at small
    // and stiff at large strain, so the plain iteration overshoots and oscillates between the two
    // (it ended after max_iterations up to 30 % away from the fixed point, see
    // tests/unit/material/linear_comparison_test.cpp). The step is halved whenever the change
    // grows.
    double omega = 1.0;
    double last_change = std::numeric_limits<double>::infinity();
    for (; iterations < options.contact.max_iterations; ++iterations) {
      const MatrixX3d before = fem->positions();
      if (options.update_within_step || iterations == 0) {
        HC_RETURN_IF_ERROR(
            incremental_step(fem, material, fk).with_context("load step " + std::to_string(k)));
      } else {
        HC_RETURN_IF_ERROR(fem->step(fk).with_context("load step " + std::to_string(k)));
      }
      const double change = (fem->positions() - before).cwiseAbs().maxCoeff();
      if (change <= tolerance) {
        ++iterations;
        converged = true;
        break;
      }
      if (options.update_within_step) {
        if (change > last_change) omega = std::max(kMinRelaxation, 0.5 * omega);
        last_change = change;
        if (omega < 1) {
          const MatrixX3d relaxed = before + omega * (fem->positions() - before);
          HC_RETURN_IF_ERROR(fem->set_positions(relaxed));
        }
      }
    }
    all_converged = all_converged && converged;
    summary->total_iterations += iterations;
    summary->steps.push_back({0.0, fk.colwise().sum().norm(), iterations});
  }
  summary->max_displacement_m = max_displacement(*fem);
  summary->converged = all_converged;
  summary->time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return {};
}

}  // namespace hc::fem
