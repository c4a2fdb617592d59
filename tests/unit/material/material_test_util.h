// Test fixtures for the material fitter: structured tet boxes and synthetic examples simulated with
// processing/fem's linear co-rotational model (per-element parameters known).
#pragma once

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <vector>

#include "common/tet_mesh.h"
#include "processing/fem/corotational.h"
#include "processing/fem/incremental.h"
#include "processing/fem/material_model.h"
#include "processing/material/material.h"
#include "processing/material/samples.h"
#include "processing/material/synth.h"

namespace hc::material::testing {

// Fixtures are shared with the benchmark (no gtest there): a broken fixture aborts loudly.
inline void fixture_check(bool ok, const char* what) {
  if (!ok) {
    std::fprintf(stderr, "material test fixture failed: %s\n", what);
    std::abort();
  }
}

// nx × ny × nz cubes over [0,sx]×[0,sy]×[0,sz], 6 tets per cube (Freudenthal/Kuhn split along the
// main diagonal, conforming), positively oriented.
inline TetMesh box_mesh(int nx, int ny, int nz, double sx, double sy, double sz) {
  TetMesh m;
  const auto id = [&](int i, int j, int k) { return (k * (ny + 1) + j) * (nx + 1) + i; };
  m.nodes.resize((nx + 1) * (ny + 1) * (nz + 1), 3);
  for (int k = 0; k <= nz; ++k)
    for (int j = 0; j <= ny; ++j)
      for (int i = 0; i <= nx; ++i)
        m.nodes.row(id(i, j, k)) << sx * i / nx, sy * j / ny, sz * k / nz;
  std::vector<std::array<int, 4>> tets;
  const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i)
        for (const auto& p : perms) {
          std::array<int, 3> c = {i, j, k};
          std::array<int, 4> t;
          t[0] = id(c[0], c[1], c[2]);
          for (int s = 0; s < 3; ++s) {
            ++c[static_cast<std::size_t>(p[s])];
            t[static_cast<std::size_t>(s) + 1] = id(c[0], c[1], c[2]);
          }
          const Eigen::Vector3d a = m.nodes.row(t[0]), b = m.nodes.row(t[1]), d = m.nodes.row(t[2]),
                                e = m.nodes.row(t[3]);
          if ((b - a).dot((d - a).cross(e - a)) < 0) std::swap(t[2], t[3]);
          tets.push_back(t);
        }
  m.tets.resize(static_cast<Eigen::Index>(tets.size()), 4);
  for (std::size_t t = 0; t < tets.size(); ++t)
    for (int c = 0; c < 4; ++c)
      m.tets(static_cast<Eigen::Index>(t), c) = tets[t][static_cast<std::size_t>(c)];
  return m;
}

inline std::vector<int> bottom_nodes(const TetMesh& m) {
  std::vector<int> out;
  for (Eigen::Index n = 0; n < m.num_nodes(); ++n)
    if (m.nodes(n, 2) < 1e-12) out.push_back(static_cast<int>(n));
  return out;
}

// Nodes on the top face within `radius` of (x, y) (horizontal distance).
inline std::vector<int> top_nodes_near(const TetMesh& m, double x, double y, double radius) {
  const double top = m.nodes.col(2).maxCoeff();
  std::vector<int> out;
  for (Eigen::Index n = 0; n < m.num_nodes(); ++n)
    if (m.nodes(n, 2) > top - 1e-12 && std::hypot(m.nodes(n, 0) - x, m.nodes(n, 1) - y) <= radius)
      out.push_back(static_cast<int>(n));
  return out;
}

// An example: `force` (N, total) spread equally over `loaded` nodes, bottom fixed, positions from
// processing/fem's co-rotational static solve with per-element `params`. All nodes visible.
inline Example simulate_example(const TetMesh& mesh, const std::vector<fem::LambdaAlpha>& params,
                                const std::vector<int>& loaded, const Eigen::Vector3d& force) {
  Example ex;
  ex.fixed_nodes = bottom_nodes(mesh);
  for (int n : loaded) ex.forces.push_back({n, force / static_cast<double>(loaded.size())});
  auto fem = fem::CorotationalFem::create(mesh, ex.fixed_nodes);
  fixture_check(fem.ok() && fem->set_params(params).ok(), "FEM setup");
  MatrixX3d f = MatrixX3d::Zero(mesh.num_nodes(), 3);
  for (const NodalForce& nf : ex.forces) f.row(nf.node) = nf.force_n.transpose();
  fixture_check(fem->solve_static(f, 200, 1e-14).ok(), "static solve");
  ex.positions_m = fem->positions();
  ex.visible.assign(static_cast<std::size_t>(mesh.num_nodes()), 1);
  ex.probe.shape = "none";
  return ex;
}

// A 4×4×2-cube block of 40 × 40 × 20 mm (192 tets): a soft top layer (50 kPa) over a stiff
// bottom (200 kPa), ν 0.3; example() presses it at (x, y) with `force` on the top nodes within
// 11 mm.
struct TwoLayerBlock {
  TetMesh mesh = box_mesh(4, 4, 2, 0.04, 0.04, 0.02);
  std::vector<fem::LambdaAlpha> truth;
  TwoLayerBlock() {
    for (Eigen::Index e = 0; e < mesh.num_tets(); ++e) {
      double z = 0;
      for (int k = 0; k < 4; ++k) z += mesh.nodes(mesh.tets(e, k), 2) / 4;
      truth.push_back(fem::lambda_alpha_from_youngs_poisson(z > 0.01 ? 50e3 : 200e3, 0.3));
    }
  }
  Example example(double x, double y, const Eigen::Vector3d& force) const {
    return simulate_example(mesh, truth, top_nodes_near(mesh, x, y, 0.011), force);
  }
  // The truth with every element's λ scaled by U(0.7, 1.4) and α set to λ · 0.25 · U(0.7, 1.4)
  // (a point away from the minimum, for Jacobian checks).
  std::vector<fem::LambdaAlpha> perturbed(std::mt19937* rng) const {
    std::uniform_real_distribution<double> u(0.7, 1.4);
    std::vector<fem::LambdaAlpha> p = truth;
    for (auto& x : p) {
      x.lambda *= u(*rng);
      x.alpha = x.lambda * 0.25 * u(*rng);
    }
    return p;
  }
};

// Stiffening reference: lambda, alpha grow with compression (eps_zz < 0) of each element.
struct StiffeningReference {
  TetMesh mesh;
  explicit StiffeningReference(TetMesh m = box_mesh(4, 4, 2, 0.04, 0.04, 0.02))
      : mesh(std::move(m)) {}
  fem::LambdaAlpha p0 = fem::lambda_alpha_from_youngs_poisson(60e3, 0.3);
  fem::LinearStrainMaterial material{p0,
                                     (fem::Vector6d() << 0, 0, -20 * p0.lambda, 0, 0, 0).finished(),
                                     (fem::Vector6d() << 0, 0, -20 * p0.alpha, 0, 0, 0).finished()};

  // The "probe" is a pressure patch: the force spread equally over the top nodes within the probe
  // radius of its axis (keeps this test independent of contact convergence), simulated by
  // incremental loading with the stiffening material.
  ReferenceSimulator simulator() const {
    return [this](const ProbePose& pose, double force_n) -> Result<ReferenceIndentation> {
      HC_ASSIGN_OR_RETURN(fem::CorotationalFem f,
                          fem::CorotationalFem::create(mesh, bottom_nodes(mesh)));
      const std::vector<int> loaded =
          top_nodes_near(mesh, pose.position_m.x(), pose.position_m.y(), pose.radius_m);
      if (loaded.empty()) return invalid_argument("probe misses the top nodes");
      MatrixX3d forces = MatrixX3d::Zero(mesh.num_nodes(), 3);
      for (int n : loaded) forces.row(n) = force_n / loaded.size() * pose.direction.transpose();
      fem::IncrementalOptions io;
      io.steps = 6;
      io.update_within_step = true;
      fem::IncrementalSummary is;
      HC_RETURN_IF_ERROR(fem::run_incremental_forces(&f, material, forces, io, &is));
      ReferenceIndentation out;
      out.positions_m = f.positions();
      out.contact_forces_n = forces;
      return out;
    };
  }
  SynthOptions synth_options(int examples, double noise) const {
    SynthOptions o;
    o.examples = examples;
    o.noise = noise;
    o.seed = 11;
    o.probe.shape = "sphere";
    o.probe.radius_m = 0.011;
    o.max_force_n = 4.0;
    o.fixed_nodes = bottom_nodes(mesh);
    return o;
  }
};

}  // namespace hc::material::testing
