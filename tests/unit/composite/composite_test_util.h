// Fixtures for the composite tests: the thesis's blocks as structured tet meshes and synthetic
// force-displacement samples from processing/hyperelastic's (layered, stiffening, optionally
// fibre-reinforced) neo-Hookean reference model under a sphere probe — a different model from the
// co-rotational data-driven one that the base materials use.
#pragma once

#include <cstdint>
#include <cstdio>
#include <vector>

#include "../material/hyperelastic_reference.h"
#include "../material/material_test_util.h"
#include "processing/material/samples.h"
#include "processing/material/synth.h"

namespace hc::composite::testing {

using material::testing::bottom_nodes;
using material::testing::box_mesh;
using material::testing::fixture_check;

// Thesis Sec. 5.7.2 / Table 5.8.1: isotropic blocks 5 x 5 x 2.5 cm (printed ones 5 x 4 x 2.5 cm).
inline TetMesh block(int nx, int ny, int nz, double height_m = 0.025, double width_y_m = 0.05) {
  return box_mesh(nx, ny, nz, 0.05, width_y_m, height_m);
}

inline hyperelastic::NeoHookeanMaterial neo_hookean(double youngs_pa, double poisson,
                                                    double stiffening, double fibre_pa = 0) {
  hyperelastic::NeoHookeanMaterial m;
  m.youngs_pa = youngs_pa;
  m.poisson = poisson;
  m.stiffening = stiffening;
  m.fibre_pa = fibre_pa;
  return m;
}

struct SynthSpec {
  int examples = 9;
  double max_force_n = 15;
  std::vector<double> levels = {1.0 / 3, 2.0 / 3, 1.0};  // three force levels as in Table 5.8.1
  double probe_radius_m = 0.01;
  std::uint64_t seed = 7;
  int steps = 4;
};

// Samples of the reference model: layers (z ranges) of neo-Hookean materials, bottom fixed.
inline material::Samples reference_samples(const TetMesh& mesh,
                                           const std::vector<hyperelastic::MaterialLayer>& layers,
                                           const SynthSpec& spec = {}) {
  material::testing::HyperelasticReference ref{mesh, layers, spec.steps};
  material::SynthOptions o;
  o.examples = spec.examples;
  o.max_force_n = spec.max_force_n;
  o.force_levels = spec.levels;
  o.probe.shape = "sphere";
  o.probe.radius_m = spec.probe_radius_m;
  o.probe.direction = Eigen::Vector3d(0, 0, -1);
  o.fixed_nodes = bottom_nodes(mesh);
  o.seed = spec.seed;
  Result<material::Samples> s = material::synthesize_samples(mesh, ref.simulator(), o);
  if (!s.ok()) std::fprintf(stderr, "%s\n", s.status().to_string().c_str());
  fixture_check(s.ok(), "reference samples");
  return std::move(s).value();
}

// One homogeneous reference material over the whole block.
inline material::Samples reference_samples(const TetMesh& mesh,
                                           const hyperelastic::NeoHookeanMaterial& m,
                                           const SynthSpec& spec = {}) {
  const double top = mesh.nodes.col(2).maxCoeff();
  return reference_samples(mesh, {{-1.0, top + 1.0, m}}, spec);
}

}  // namespace hc::composite::testing
