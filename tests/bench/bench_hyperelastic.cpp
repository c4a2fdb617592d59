// Neo-Hookean reference model: energy + gradient + Hessian assembly, and a full equilibrium solve
// (Newton, CHOLMOD) of a 50 × 50 × 25 mm block (the thesis's specimen, Sec. 4.4) stretched 10 %
// on rollers, at about 1.7k, 10k and 50k tets (structured Freudenthal boxes: 6 tets per cell).
//
//   bench_hyperelastic [--benchmark_filter=...]
#include <benchmark/benchmark.h>

#include "processing/hyperelastic/neo_hookean.h"
#include "processing/meshing/tetrahedralize.h"

namespace {

using hc::hyperelastic::NeoHookeanMaterial;
using hc::hyperelastic::NeoHookeanModel;

// cells (n, n, n/2): 6 n³/2 tets: n = 8 → 1,536; 14 → 8,232; 24 → 41,472.
NeoHookeanModel block(int n) {
  const Eigen::Vector3d size(0.05, 0.05, 0.025);
  hc::TetMesh mesh = *hc::meshing::structured_box(size, Eigen::Vector3i(n, n, n / 2));
  return *NeoHookeanModel::create(mesh, {NeoHookeanMaterial{1e5, 0.45, 0}});
}

void BM_EnergyGradientHessian(benchmark::State& state) {
  const NeoHookeanModel m = block(static_cast<int>(state.range(0)));
  Eigen::VectorXd x = m.rest_positions() * 1.01;
  Eigen::VectorXd g;
  Eigen::SparseMatrix<double> H;
  for (auto _ : state) {
    benchmark::DoNotOptimize(m.energy_gradient_hessian(x, &g, &H));
  }
  state.counters["tets"] = static_cast<double>(m.mesh().num_tets());
}
BENCHMARK(BM_EnergyGradientHessian)->Arg(8)->Arg(14)->Arg(24)->Unit(benchmark::kMillisecond);

void BM_StretchSolve(benchmark::State& state) {
  const NeoHookeanModel m = block(static_cast<int>(state.range(0)));
  const hc::TetMesh& mesh = m.mesh();
  hc::hyperelastic::Boundary b;
  for (Eigen::Index i = 0; i < mesh.num_nodes(); ++i) {
    const Eigen::Vector3d p = mesh.nodes.row(i).transpose();
    if (p.z() == 0 || p.z() == 0.025) b.fixed_dofs.push_back(static_cast<int>(3 * i + 2));
    if (p.z() == 0 && p.x() == 0 && p.y() == 0) {
      b.fixed_dofs.push_back(static_cast<int>(3 * i));
      b.fixed_dofs.push_back(static_cast<int>(3 * i + 1));
    }
    if (p.z() == 0 && p.x() == 0.05 && p.y() == 0)
      b.fixed_dofs.push_back(static_cast<int>(3 * i + 1));
  }
  int iterations = 0;
  for (auto _ : state) {
    Eigen::VectorXd x = m.rest_positions();
    for (Eigen::Index i = 0; i < mesh.num_nodes(); ++i) x[3 * i + 2] *= 1.1;
    hc::hyperelastic::SolveSummary s;
    (void)hc::hyperelastic::solve_equilibrium(m, b, {}, &x, &s);
    iterations = s.iterations;
  }
  state.counters["tets"] = static_cast<double>(mesh.num_tets());
  state.counters["newton_iterations"] = iterations;
}
BENCHMARK(BM_StretchSolve)->Arg(8)->Arg(14)->Arg(24)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
