#include "processing/hyperelastic/reference_indentation.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "processing/fem/contact_surface.h"
#include "processing/fem/corotational.h"
#include "processing/fem/material_model.h"
#include "processing/hyperelastic/fem_probe.h"

namespace hc::hyperelastic {

Status ReferenceIndentationOptions::validate() const {
  if (steps < 1) return invalid_argument(fmt::format("steps {} must be >= 1", steps));
  if (!(std::isfinite(penalty_scale) && penalty_scale > 0))
    return invalid_argument("penalty_scale must be > 0");
  HC_RETURN_IF_ERROR(sampling.validate());
  return hyperelastic::validate(solve);
}

Result<IndentationResult> reference_indentation(const NeoHookeanModel& model,
                                                const std::vector<int>& fixed_nodes,
                                                const fem::Probe& probe, const fem::Load& load,
                                                const ReferenceIndentationOptions& options) {
  HC_RETURN_IF_ERROR(options.validate());
  const TetMesh& mesh = model.mesh();
  if (!(std::isfinite(load.value) && load.value > 0))
    return invalid_argument(fmt::format("indentation load {} must be > 0 and finite", load.value));
  for (int f : fixed_nodes)
    if (f < 0 || f >= mesh.num_nodes())
      return invalid_argument(fmt::format("fixed node {} out of range (mesh has {} nodes)", f,
                                          mesh.num_nodes()));
  // The contact points and their penalty stiffness: the co-rotational FEM's rule, on the
  // small-strain stiffness of the same materials (neo-Hookean at small strain = linear (E, ν)).
  HC_ASSIGN_OR_RETURN(fem::CorotationalFem linear, fem::CorotationalFem::create(mesh, fixed_nodes));
  std::vector<fem::LambdaAlpha> params;
  params.reserve(model.materials().size());
  for (const NeoHookeanMaterial& m : model.materials())
    params.push_back(fem::lambda_alpha_from_youngs_poisson(m.youngs_pa, m.poisson));
  HC_RETURN_IF_ERROR(linear.set_params(params));
  linear.assemble();
  HC_ASSIGN_OR_RETURN(fem::ContactSurface surface,
                      fem::ContactSurface::create(mesh, probe, options.sampling));
  std::vector<char> fixed(static_cast<std::size_t>(mesh.num_nodes()), 0);
  for (int f : fixed_nodes) fixed[static_cast<std::size_t>(f)] = 1;
  const double size = (mesh.nodes.colwise().maxCoeff() - mesh.nodes.colwise().minCoeff()).norm();
  IndentationResult out;
  HC_ASSIGN_OR_RETURN(out.contact_travel_m,
                      surface.travel_to_contact(probe, mesh.nodes, fixed, 10 * size));
  std::unique_ptr<fem::Probe> start = probe.clone();
  start->advance(out.contact_travel_m);
  HC_ASSIGN_OR_RETURN(std::unique_ptr<RigidProbe> contact,
                      make_fem_surface_contact(
                          *start, surface, surface.penalty_stiffness(linear, options.penalty_scale),
                          options.penalty_scale));
  Boundary boundary;
  boundary.fixed_nodes = fixed_nodes;  // indent() adds the probe's contact itself
  IndentOptions io;
  io.steps = options.steps;
  io.force_control = load.control == fem::LoadControl::kForce;
  (io.force_control ? io.force_n : io.depth_m) = load.value;
  io.record_positions = options.record_steps;
  io.solve = options.solve;
  Eigen::VectorXd x = model.rest_positions();
  HC_RETURN_IF_ERROR(indent(model, boundary, *contact, io, &x, &out.summary));
  out.positions_m = Eigen::Map<const MatrixX3d>(x.data(), mesh.num_nodes(), 3);
  out.contact_forces_n = contact_forces(*contact, x);
  for (const Eigen::VectorXd& p : out.summary.positions)
    out.step_positions_m.push_back(Eigen::Map<const MatrixX3d>(p.data(), mesh.num_nodes(), 3));
  out.summary.positions.clear();
  return out;
}

}  // namespace hc::hyperelastic
