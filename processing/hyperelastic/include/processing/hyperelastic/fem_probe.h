// processing/fem's rigid probes (sphere, flat cylinder, any closed mesh as a signed distance field)
// as a contact obstacle of the hyperelastic model: the same probe geometry drives both the
// co-rotational FEM and the reference model.
#pragma once

#include <memory>
#include <vector>

#include "common/status.h"
#include "processing/fem/contact_surface.h"
#include "processing/fem/probe.h"
#include "processing/hyperelastic/neo_hookean.h"

namespace hc::hyperelastic {

// Wraps a copy of `probe` (its current pose is depth 0; depth moves it along probe.direction()).
// A node at signed distance s < 0 (inside) gets the penalty energy k/2 s², k = stiffness_n_per_m,
// i.e. the force k |s| along the probe's outward normal; the Hessian is k (n nᵀ + s ∇n), with the
// surface's curvature ∇n for a fem::SphereProbe and Gauss–Newton k n nᵀ for the other probes
// (their distance fields give no curvature). Fails on a non-positive or non-finite stiffness.
Result<std::unique_ptr<RigidProbe>> make_fem_probe_contact(const fem::Probe& probe,
                                                           double stiffness_n_per_m);

// The same probe against the contact points of a tet mesh's boundary (fem/contact_surface.h: its
// nodes and, on faces coarser than the probe, points on the faces, so that the probe cannot pass
// between nodes), the contact rule of processing/fem's ContactSolver: point p at signed distance
// s < 0 gets k_p/2 s² (k_p = stiffness[p], N/m), its force reaches the face's nodes by the
// point's weights; Hessian k_p (w wᵀ ⊗ (n nᵀ + s ∇n)), ∇n as above. With penalty_scale > 0 (the
// stiffnesses are that times the block's own, ContactSurface::penalty_stiffness) the curvature
// part is left out where |s| > ρ / penalty_scale, far from equilibrium, where it would make the
// Hessian indefinite. Its correct_step() restores the penetration of the node points in contact
// (ContactPotential). Fails when `stiffness` does not have one entry per point, an entry is
// negative or not finite, or penalty_scale is negative or not finite.
Result<std::unique_ptr<RigidProbe>> make_fem_surface_contact(const fem::Probe& probe,
                                                             const fem::ContactSurface& surface,
                                                             std::vector<double> stiffness,
                                                             double penalty_scale = 0);

}  // namespace hc::hyperelastic
