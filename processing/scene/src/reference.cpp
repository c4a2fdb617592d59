#include "processing/scene/reference.h"

#include <fmt/format.h>

#include <memory>

#include "processing/fem/probe.h"
#include "processing/hyperelastic/reference_indentation.h"

namespace hc::scene {

Result<std::vector<hyperelastic::NeoHookeanMaterial>> reference_materials(const MaterialSpec& m,
                                                                          const TetMesh& mesh) {
  switch (m.kind) {
    case MaterialKind::kLinear:
    case MaterialKind::kNeoHookean:
      return std::vector<hyperelastic::NeoHookeanMaterial>(
          static_cast<std::size_t>(mesh.num_tets()), {m.youngs_pa, m.poisson, m.stiffening});
    case MaterialKind::kLayered: {
      std::vector<hyperelastic::MaterialLayer> layers;
      for (const LayerSpec& l : m.layers)
        layers.push_back({l.z_min_m, l.z_max_m, {l.youngs_pa, l.poisson, l.stiffening}});
      return hyperelastic::layered_materials(mesh, layers);
    }
    case MaterialKind::kFile:
      break;
  }
  return invalid_argument(
      "a material file has no reference model: give a neo_hookean, linear or layered material");
}

material::ReferenceSimulator reference_simulator(
    const TetMesh& mesh, std::vector<hyperelastic::NeoHookeanMaterial> materials,
    std::vector<int> fixed_nodes, int steps) {
  auto model = std::make_shared<Result<hyperelastic::NeoHookeanModel>>(
      hyperelastic::NeoHookeanModel::create(mesh, std::move(materials)));
  return [model, fixed = std::move(fixed_nodes), steps](
             const material::ProbePose& pose,
             double force_n) -> Result<material::ReferenceIndentation> {
    if (!model->ok()) return model->status();
    Result<std::unique_ptr<fem::Probe>> probe =
        pose.shape == "sphere" ? fem::make_sphere_probe(pose.radius_m, pose.position_m,
                                                        pose.direction)
        : pose.shape == "flat"
            ? fem::make_flat_probe(pose.radius_m, pose.position_m, pose.direction)
            : Result<std::unique_ptr<fem::Probe>>(invalid_argument(fmt::format(
                  "the reference model indents with sphere and flat probes, not \"{}\"",
                  pose.shape)));
    if (!probe.ok()) return probe.status();
    hyperelastic::ReferenceIndentationOptions options;
    options.steps = steps;
    HC_ASSIGN_OR_RETURN(hyperelastic::IndentationResult ind,
                        hyperelastic::reference_indentation(
                            **model, fixed, **probe, {fem::LoadControl::kForce, force_n}, options));
    if (!ind.summary.usable)
      return failed_precondition("reference indentation: " + ind.summary.message);
    return material::ReferenceIndentation{std::move(ind.positions_m),
                                          std::move(ind.contact_forces_n)};
  };
}

}  // namespace hc::scene
