// Probe contact (thesis Sec. 4.2.4): contact points of the specimen's boundary (its nodes and, on
// faces coarser than the probe, points on the faces; contact_surface.h) that penetrate the rigid
// probe get a linear (penalty) force field pulling them to the closest probe surface point,
// k n n^T (target - x) (frictionless: only the normal component), added implicitly to the
// co-rotational system; the active set, the surface targets and the rotations are re-evaluated
// until equilibrium. Loading is controlled by the probe's depth (travel beyond first contact with
// the undeformed specimen) or by the total contact force.
#pragma once

#include <Eigen/Core>
#include <memory>

#include "common/status.h"
#include "processing/fem/contact_surface.h"
#include "processing/fem/corotational.h"
#include "processing/fem/material_model.h"
#include "processing/fem/probe.h"

namespace hc::fem {

enum class LoadControl { kDepth, kForce };

struct Load {
  LoadControl control = LoadControl::kDepth;
  double value = 0;  // depth in m or force in N
};

struct ContactOptions {
  // Penalty stiffness of a boundary node (N/m) = penalty_scale * its mean diagonal entry of K at
  // the first assembly, or penalty_n_per_m when > 0; points on faces get the same per unit of
  // boundary area (ContactSurface::penalty_stiffness). Larger k = less residual penetration
  // (~ force / k), worse conditioning.
  double penalty_scale = 1e3;
  double penalty_n_per_m = 0;
  // Contact equilibrium iterations per solve (rotations, active set, targets).
  int max_iterations = 100;
  // Converged when the largest node position change of an iteration, or the change still to come
  // as estimated from the iteration's measured contraction, is below
  // tolerance_rel * (depth + 1e-3 * specimen size) and the active set did not change. (Hertz
  // scene, 12.9k tets, 10 steps: 1e-6 took 60 iterations, 1e-4 43, same force to 5 digits.)
  double tolerance_rel = 1e-4;
  // Force control: relative force tolerance and secant iterations on the depth.
  double force_tolerance_rel = 1e-4;
  int max_force_iterations = 60;
  // The probe must touch the specimen within this travel from its start pose ("unreachable"
  // otherwise); 0 = 10 x the specimen's bounding-box diagonal.
  double max_travel_m = 0;
  // Largest probe advance per internal sub-step (0 = auto: half the shortest mesh edge). The
  // closest- point projection of the distance field sends nodes that penetrate deeper than their
  // distance to a probe's side out sideways; advancing the probe in sub-steps keeps nodes on the
  // face they met.
  double max_depth_step_m = 0;
  // While at most this many points are in contact their penalties reach K's factorisation as a
  // low-rank update (one solve per point entering contact; a dense system of this size per
  // iteration), so contact changes do not make it stale; with more, or 0, K is factorised with
  // them whenever the factorisation has gone stale.
  int max_update_points = 400;
  // Where contact is evaluated: the boundary nodes plus, on faces coarser than the probe, a lattice
  // of points on the faces (contact_surface.h), so that a probe cannot slip between nodes.
  ContactSamplingOptions sampling;

  Status validate() const;
};

struct ContactSummary {
  double depth_m = 0;    // probe travel beyond first contact
  double force_n = 0;    // total contact force along the probe direction (> 0 when pushing)
  int active_nodes = 0;  // contact points in contact (boundary nodes and face points)
  int iterations = 0;    // equilibrium iterations (summed over secant steps under force control)
  int factorizations = 0;  // numeric factorisations of K among them
  double max_penetration_m = 0;
  bool converged = false;
};

class ContactSolver {
 public:
  // `fem` must outlive the solver and have parameters set; `probe` is copied and its current pose
  // is the start pose. Fails (invalid_argument, "the probe's path misses the specimen ...") when
  // moving the probe along its direction never touches a movable contact point of the rest shape
  // within max_travel_m.
  static Result<ContactSolver> create(CorotationalFem* fem, const Probe& probe,
                                      const ContactOptions& options = {});

  ContactSolver(ContactSolver&&) noexcept;
  ContactSolver& operator=(ContactSolver&&) noexcept;
  ~ContactSolver();

  // Travel from the start pose to the first contact with the undeformed specimen (m).
  double contact_travel() const;

  // When set, every equilibrium iteration first updates each element's (lambda, alpha) from its
  // current strain through the model (used by incremental loading); nullptr (default) keeps fem's
  // parameters.
  void set_material(const MaterialModel* material);

  // Equilibrium with the probe at `depth_m` beyond first contact. Warm-starts from fem's current
  // positions. failed_precondition when K is not positive definite or the iteration does not
  // converge.
  Status solve_depth(double depth_m, ContactSummary* summary);
  // Equilibrium at the depth where the total contact force equals force_n (> 0), by
  // secant/bisection.
  Status solve_force(double force_n, ContactSummary* summary);
  Status solve(const Load& load, ContactSummary* summary);

  // The probe at its current pose (after the last solve).
  const Probe& probe() const;
  // Contact forces on the nodes at the last solution, #N by 3 (N).
  MatrixX3d contact_forces() const;
  // Mean penalty stiffness of the boundary nodes in reach (N/m; after the first solve).
  double penalty_n_per_m() const;
  // The contact points.
  const ContactSurface& surface() const;

 private:
  struct Impl;
  explicit ContactSolver(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace hc::fem
