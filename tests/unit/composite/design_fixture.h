// The design tests' setting (thesis Sec. 5.8.3): a 5 x 5 x 2.5 cm block in 5 layers, 9 base
// materials from soft to stiff with different strain stiffening, and 5 force-displacement pairs
// (loads on patches of the top face). Targets are designs simulated with the full model.
#pragma once

#include <random>
#include <vector>

#include "composite_test_util.h"
#include "fabrication/composite/base_material.h"
#include "fabrication/composite/composite.h"
#include "processing/material/samples.h"

namespace hc::composite::testing {

// An isotropic base material with Young's modulus E0 and Poisson's ratio nu at zero strain that
// stiffens by the factor (1 + s k) at three strain-feature centres (compression with shear, shear,
// strong compression with shear), k = 1, 1, 3.
inline BaseMaterial stiffening_base(double youngs_pa, double poisson, double s) {
  const double lambda = youngs_pa * poisson / ((1 + poisson) * (1 - 2 * poisson));
  const double mu = youngs_pa / (2 * (1 + poisson));
  Eigen::MatrixXd c(4, 3);
  c << 0, 0, 0, -0.1, 0.06, -0.04, 0, 0.12, 0, -0.2, 0.12, -0.08;
  const double k[4] = {0, 1, 1, 3};
  Eigen::MatrixXd v(4, 2);
  for (int i = 0; i < 4; ++i) v.row(i) << lambda * (1 + s * k[i]), mu * (1 + s * k[i]);
  FeasibilityLimits limits;
  limits.min_modulus_pa = 1e-3 * youngs_pa;
  Result<BaseMaterial> m = BaseMaterial::create(BaseModel::kIsotropic, c, v, limits);
  fixture_check(m.ok(), "stiffening base material");
  return std::move(m).value();
}

// Nine base materials: Young's moduli 60 kPa .. 2.5 MPa, Poisson's ratios 0.2 .. 0.45, stiffening
// 0 .. 3.
inline std::vector<BaseMaterial> nine_base_materials() {
  const double e[9] = {60e3, 100e3, 160e3, 250e3, 400e3, 650e3, 1000e3, 1600e3, 2500e3};
  const double nu[9] = {0.30, 0.25, 0.40, 0.30, 0.35, 0.20, 0.45, 0.30, 0.35};
  const double s[9] = {2.0, 0.5, 1.5, 0.0, 1.0, 3.0, 0.5, 2.0, 0.0};
  std::vector<BaseMaterial> out;
  for (int i = 0; i < 9; ++i) out.push_back(stiffening_base(e[i], nu[i], s[i]));
  return out;
}

// Five load cases on the top face of `mesh` (bottom fixed): total downward forces 2..6 N spread
// over the top nodes within 1 cm of five points; positions start at the rest shape.
inline material::Samples load_cases(const TetMesh& mesh) {
  material::Samples s;
  s.mesh = mesh;
  const double points[5][2] = {{0.025, 0.025}, {0.015, 0.015}, {0.035, 0.02}, {0.02, 0.035},
                               {0.033, 0.033}};
  for (int k = 0; k < 5; ++k) {
    material::Example ex;
    ex.name = "load" + std::to_string(k);
    ex.fixed_nodes = bottom_nodes(mesh);
    const std::vector<int> patch =
        material::testing::top_nodes_near(mesh, points[k][0], points[k][1], 0.01);
    fixture_check(!patch.empty(), "load patch");
    const Eigen::Vector3d total(0, 0, -(2.0 + k));
    for (int n : patch) ex.forces.push_back({n, total / static_cast<double>(patch.size())});
    ex.positions_m = mesh.nodes;
    ex.visible.assign(static_cast<std::size_t>(mesh.num_nodes()), 1);
    s.examples.push_back(std::move(ex));
  }
  return s;
}

// `loads` with the positions of a full simulation of `design`.
inline material::Samples simulated_target(const material::Samples& loads, const CellGrid& grid,
                                          const std::vector<BaseMaterial>& library,
                                          const std::vector<int>& design) {
  Result<CompositeMaterial> m =
      make_composite(library, element_cells(loads.mesh, grid), design, grid.num_cells());
  fixture_check(m.ok(), "composite");
  Result<ExampleSimulator> sim = ExampleSimulator::create(loads, ForwardOptions{});
  fixture_check(sim.ok(), "simulator");
  Result<std::vector<MatrixX3d>> x = sim->simulate_all(*m);
  fixture_check(x.ok(), "target simulation");
  material::Samples out = loads;
  for (std::size_t i = 0; i < out.examples.size(); ++i) out.examples[i].positions_m = (*x)[i];
  return out;
}

inline std::vector<std::vector<int>> random_designs(int count, int cells, int materials,
                                                    std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> pick(0, materials - 1);
  std::vector<std::vector<int>> out;
  for (int k = 0; k < count; ++k) {
    std::vector<int> d(static_cast<std::size_t>(cells));
    for (int& v : d) v = pick(rng);
    out.push_back(std::move(d));
  }
  return out;
}

}  // namespace hc::composite::testing
