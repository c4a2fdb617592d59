// One incremental-loading step (update rotations and per-element parameters from strain, assemble
// by the scatter map, numeric factorisation, solve) on box meshes of ~1.7k, 10k and 100k tets,
// timed next to CHOLMOD's own numeric factorise + solve of the same matrix with the same symbolic
// analysis (the lower bound for any step that refactorises). Counters: step_ms, cholmod_ms, ratio =
// step / cholmod. Targets (issue 3): 1,691 tets >= 100 Hz, 10k <= 30 ms, 100k <= 1 s, ratio <= 1.5.
// And the default-settings Hertz scene of `hardcopy simulate` (issue 13).
#include <benchmark/benchmark.h>
#include <suitesparse/cholmod.h>

#include <chrono>

#include "common/openmp.h"
#include "processing/fem/corotational.h"
#include "processing/fem/incremental.h"
#include "processing/fem/material_model.h"
#include "processing/fem/verification.h"
#include "processing/scene/scene.h"

namespace {

using hc::fem::CorotationalFem;

struct Cells {
  int x, y, z;
};

// 50 x 50 x 25 mm blocks (the thesis's specimen size); 6 tets per cell.
Cells cells_for(int64_t target_tets) {
  if (target_tets <= 2000) return {8, 7, 5};     // 1,680 tets (thesis pillow: 1,691)
  if (target_tets <= 20000) return {16, 13, 8};  // 9,984 tets
  return {32, 26, 20};                           // 99,840 tets
}

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

void BM_FemIncrementalStep(benchmark::State& state) {
  const Cells c = cells_for(state.range(0));
  const hc::TetMesh mesh = hc::fem::structured_box_mesh(
      hc::fem::uniform_coordinates(0, 0.05, c.x), hc::fem::uniform_coordinates(0, 0.05, c.y),
      hc::fem::uniform_coordinates(0, 0.025, c.z));
  auto fem = CorotationalFem::create(mesh, hc::fem::nodes_on_plane(mesh, 2, 0.0, 1e-9));
  if (!fem.ok()) {
    state.SkipWithError(fem.status().to_string().c_str());
    return;
  }
  // A strain-dependent material so that the parameter update does real work every step.
  hc::fem::Vector6d dl = hc::fem::Vector6d::Zero(), da = hc::fem::Vector6d::Zero();
  dl.head<3>().setConstant(-2e6);
  const hc::fem::LinearStrainMaterial material(hc::fem::lambda_alpha_from_youngs_poisson(1e5, 0.4),
                                               dl, da);
  hc::MatrixX3d f = hc::MatrixX3d::Zero(mesh.num_nodes(), 3);
  for (int i : hc::fem::nodes_on_plane(mesh, 2, 0.025, 1e-9))
    f(i, 2) = -0.5 / (c.x + 1) / (c.y + 1);
  if (!hc::fem::incremental_step(&*fem, material, f).ok()) {
    state.SkipWithError("first step failed");
    return;
  }
  // CHOLMOD baseline on the very matrix the step assembles, symbolic analysis done once outside.
  cholmod_common cm;
  cholmod_start(&cm);
  // The same LL^T, orderings and serial OpenMP as hc::fem::SparseCholesky: the baseline is CHOLMOD
  // at its best on this machine.
  cm.final_ll = 1;
  cm.nmethods = 3;
  cm.method[0].ordering = CHOLMOD_AMD;
  cm.method[1].ordering = CHOLMOD_METIS;
  cm.method[2].ordering = CHOLMOD_NESDIS;
  const hc::fem::SparseMatrix& k = fem->stiffness();
  cholmod_sparse a{};
  a.nrow = a.ncol = static_cast<size_t>(k.rows());
  a.nzmax = static_cast<size_t>(k.nonZeros());
  a.p = const_cast<int*>(k.outerIndexPtr());
  a.i = const_cast<int*>(k.innerIndexPtr());
  a.x = const_cast<double*>(k.valuePtr());
  a.stype = 1;
  a.itype = CHOLMOD_INT;
  a.xtype = CHOLMOD_REAL;
  a.dtype = CHOLMOD_DOUBLE;
  a.sorted = a.packed = 1;
  cholmod_factor* l = cholmod_analyze(&a, &cm);
  cholmod_dense* b = cholmod_ones(a.nrow, 1, CHOLMOD_REAL, &cm);
  {
    // Warm-up, as the step's own factor was warmed by the first step above: the first numeric
    // factorisation also allocates (and page-faults) the factor's memory.
    const hc::SerialOpenMpScope serial;
    cholmod_factorize(&a, l, &cm);
  }
  double step_ms = 0, chol_ms = 0;
  int64_t n = 0;
  for (auto _ : state) {
    auto t0 = std::chrono::steady_clock::now();
    const hc::Status st = hc::fem::incremental_step(&*fem, material, f);
    step_ms += ms_since(t0);
    if (!st.ok()) {
      state.SkipWithError(st.to_string().c_str());
      break;
    }
    t0 = std::chrono::steady_clock::now();
    cholmod_dense* x = nullptr;
    {
      const hc::SerialOpenMpScope serial;
      cholmod_factorize(&a, l, &cm);
      x = cholmod_solve(CHOLMOD_A, l, b, &cm);
    }
    chol_ms += ms_since(t0);
    cholmod_free_dense(&x, &cm);
    ++n;
  }
  const bool supernodal = l->is_super != 0;
  cholmod_free_dense(&b, &cm);
  cholmod_free_factor(&l, &cm);
  cholmod_finish(&cm);
  if (n == 0) return;
  state.counters["tets"] = static_cast<double>(mesh.num_tets());
  state.counters["dofs"] = static_cast<double>(fem->num_free_dofs());
  state.counters["step_ms"] = step_ms / static_cast<double>(n);
  state.counters["cholmod_ms"] = chol_ms / static_cast<double>(n);
  state.counters["ratio"] = step_ms / chol_ms;
  state.counters["step_hz"] = 1000.0 * static_cast<double>(n) / step_ms;
  state.counters["factor_mflop"] = cm.fl / 1e6;
  state.counters["factor_nnz"] = cm.lnz;
  state.counters["supernodal"] = supernodal ? 1 : 0;
}
BENCHMARK(BM_FemIncrementalStep)->Arg(1691)->Arg(10000)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_FemIncrementalStep)->Arg(100000)->Iterations(3)->Unit(benchmark::kMillisecond);

// `hardcopy simulate` of the issue's Hertz scene on default settings (no mesh keys: the specimen
// is meshed for the contact, contact_meshing.h): E 0.5 MPa, ν 0.4, a 10 mm sphere 0.5 mm deep in a
// 100 x 100 x 50 mm block, 10 load steps. Counters: force and its error against Sneddon's exact
// sphere (0.8829 N; Hertz 0.887 N), tets, mesh and total time. Target (issue 13): within 5 % in
// <= 2 s.
void BM_DefaultHertzScene(benchmark::State& state) {
  constexpr const char* kScene = R"({
    "specimen": {"box_m": [0.1, 0.1, 0.05]},
    "material": {"linear": {"youngs_pa": 5e5, "poisson": 0.4}},
    "fixed": "bottom",
    "probe": {"shape": "sphere", "radius_m": 0.01, "position_m": [0.05, 0.05, 0.0605]},
    "load": {"depth_m": 5e-4}})";
  constexpr double kSneddon = 0.88289;  // ANALYTIC_BENCHMARKS.md §2 for these values
  auto scene = hc::scene::parse_scene(kScene, "hertz.json", "/tmp");
  if (!scene.ok()) {
    state.SkipWithError(scene.status().to_string().c_str());
    return;
  }
  for (auto _ : state) {
    auto r = hc::scene::simulate(*scene);
    if (!r.ok()) {
      state.SkipWithError(r.status().to_string().c_str());
      return;
    }
    state.counters["force_n"] = r->force_n;
    state.counters["error_pct"] = 100 * (r->force_n / kSneddon - 1);
    state.counters["tets"] = static_cast<double>(r->mesh.num_tets());
    state.counters["mesh_s"] = r->mesh_report.time_s;
    state.counters["total_s"] = r->time_s;
  }
}
BENCHMARK(BM_DefaultHertzScene)->Iterations(1)->Unit(benchmark::kSecond);

}  // namespace

BENCHMARK_MAIN();
