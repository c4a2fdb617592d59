// A scene's reference model (the neo-Hookean model of processing/hyperelastic with the scene's
// materials and fixed nodes) as the ReferenceSimulator that `hardcopy synth` and the material tests
// give to material::synthesize_samples: every example is hyperelastic::reference_indentation, the
// one reference indentation that `simulate` and the rig's simulated specimen use too.
#pragma once

#include <vector>

#include "common/status.h"
#include "common/tet_mesh.h"
#include "processing/hyperelastic/neo_hookean.h"
#include "processing/material/synth.h"
#include "processing/scene/scene.h"

namespace hc::scene {

// One neo-Hookean material per tet: a "neo_hookean" material as it is, a "linear" one as the
// neo-Hookean with the same small-strain constants, layers by tet centroid. invalid_argument for a
// material file (a data-driven material has no reference model) or a tet in no layer.
Result<std::vector<hyperelastic::NeoHookeanMaterial>> reference_materials(const MaterialSpec& m,
                                                                          const TetMesh& mesh);

// Simulates probe (sphere or flat, from the pose's shape, radius, position and direction) pushed
// to a force on `mesh` (copied) held at `fixed_nodes`, in `steps` increments. The simulator fails
// for "mesh"/"none" probes and when an indentation finds no equilibrium.
material::ReferenceSimulator reference_simulator(
    const TetMesh& mesh, std::vector<hyperelastic::NeoHookeanMaterial> materials,
    std::vector<int> fixed_nodes, int steps);

}  // namespace hc::scene
