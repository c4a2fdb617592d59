// Synthetic force–displacement samples (thesis Sec. 4.5's virtual block; `hardcopy synth`): probe
// indentations spread over the specimen's top face, simulated by an injected reference model
// (normally the neo-Hookean model of processing/hyperelastic, so that the fitter is never tested
// only against its own model), turned into examples (contact forces as the known nodal forces,
// node positions as the measurements), with Gaussian noise on the measured displacements.
//
// Reproducibility: the probe placements and force levels depend only on `seed`; the noise is drawn
// from a separate stream (also from `seed`), so the same seed with --noise 0 and --noise 0.3 gives
// the same examples, once clean and once noisy (the noise study compares against the clean set).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <vector>

#include "common/progress.h"
#include "common/status.h"
#include "common/tet_mesh.h"
#include "processing/material/samples.h"

namespace hc::material {

// What the reference model returns for one indentation.
struct ReferenceIndentation {
  MatrixX3d positions_m;       // #N by 3 equilibrium positions
  MatrixX3d contact_forces_n;  // #N by 3 forces the probe exerts on the nodes
};

// Simulates the probe `probe` (shape, radius, start pose and unit direction) pushed until the total
// contact force along its direction is `force_n`.
using ReferenceSimulator =
    std::function<Result<ReferenceIndentation>(const ProbePose& probe, double force_n)>;

// Bounds of SynthOptions::validate(): far past any study (the thesis uses 9-12 examples and noise
// up to 30 %), short of what only fails after minutes or gives non-finite positions.
inline constexpr int kMaxSynthExamples = 10'000;
inline constexpr double kMaxSynthNoise = 10.0;

struct SynthOptions {
  int examples = 12;
  // Gaussian noise: per coordinate σ = noise × the example's largest displacement (Sec. 4.5).
  double noise = 0;
  std::uint64_t seed = 1;
  // Probe template: shape, radius and direction; positions are spread over the top face, with the
  // probe's reference point one radius above it (along −direction), i.e. just touching.
  ProbePose probe;
  double max_force_n = 1.0;  // force levels uniform in [min_force_fraction, 1] × max
  double min_force_fraction = 0.2;
  // Instead of random levels: example k pushes with force_levels[k mod size] × max_force_n (each in
  // (0, 1]), e.g. three levels as in thesis Table 5.8.1. Empty: random levels.
  std::vector<double> force_levels;
  double margin_fraction = 0.15;  // keep probe centres this fraction of the size off the edges
  bool surface_only = false;      // true: only boundary nodes are visible (like markers)
  std::vector<int> fixed_nodes;   // sorted, unique
  // Examples simulated in parallel (0: TBB's default); the simulator must then be thread-safe
  // (the reference simulators are: each call builds its own solver state).
  int threads = 0;
  ProgressReporter* progress = nullptr;

  Status validate() const;
};

// Nodes on the boundary surface of the tet mesh (on a face used by exactly one tet), sorted.
std::vector<int> boundary_nodes(const TetMesh& mesh);

// Builds the samples. Fails when a simulation fails (message names the example) or options are
// invalid. The contact forces below 1e-12 of the largest are dropped.
Result<Samples> synthesize_samples(const TetMesh& mesh, const ReferenceSimulator& simulate,
                                   const SynthOptions& options);

// Adds noise to a copy of `clean` as synthesize_samples would (same stream), e.g. for tests.
Samples add_displacement_noise(const Samples& clean, double noise, std::uint64_t seed);

}  // namespace hc::material
