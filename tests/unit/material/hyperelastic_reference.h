// The "ground-truth physics" for the material tests: processing/hyperelastic's compressible
// (optionally strain-stiffening) neo-Hookean model, layered in z, indented by a sphere probe under
// force control through the reference indentation every tool uses. A different model from the
// co-rotational one the fitter uses (issue 3).
#pragma once

#include <vector>

#include "material_test_util.h"
#include "processing/hyperelastic/neo_hookean.h"
#include "processing/material/synth.h"
#include "processing/scene/reference.h"

namespace hc::material::testing {

struct HyperelasticReference {
  TetMesh mesh;
  std::vector<hyperelastic::MaterialLayer> layers;
  int steps = 4;

  // processing's one reference indentation (scene/reference.h), fixed at the bottom nodes.
  ReferenceSimulator simulator() const {
    Result<std::vector<hyperelastic::NeoHookeanMaterial>> per_tet =
        hyperelastic::layered_materials(mesh, layers);
    fixture_check(per_tet.ok(), "layered materials");
    return scene::reference_simulator(mesh, std::move(per_tet).value(), bottom_nodes(mesh), steps);
  }
};

}  // namespace hc::material::testing
