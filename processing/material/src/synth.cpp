#include "processing/material/synth.h"

#include <fmt/format.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <optional>
#include <random>

#include "processing/fem/blas_threads.h"

namespace hc::material {
namespace {
// Distinct stream for the noise so that the example layout does not depend on the noise level.
constexpr std::uint64_t kNoiseStream = 0x9e3779b97f4a7c15ULL;
}  // namespace

Status SynthOptions::validate() const {
  if (examples < 1 || examples > kMaxSynthExamples)
    return invalid_argument(fmt::format(
        "--examples {}: must be in [1, {}] (each example is a full hyperelastic simulation)",
        examples, kMaxSynthExamples));
  if (!(noise >= 0 && noise <= kMaxSynthNoise))
    return invalid_argument(fmt::format(
        "--noise {}: must be in [0, {}] (the standard deviation relative to the example's largest "
        "displacement: 0.1 = 10 %)",
        noise, kMaxSynthNoise));
  if (!(max_force_n > 0) || !std::isfinite(max_force_n))
    return invalid_argument("force: must be a finite number > 0");
  if (!(min_force_fraction > 0 && min_force_fraction <= 1))
    return invalid_argument("min_force_fraction: must be in (0, 1]");
  for (double l : force_levels)
    if (!(l > 0 && l <= 1)) return invalid_argument("force_levels: each must be in (0, 1]");
  if (!(margin_fraction >= 0 && margin_fraction < 0.5))
    return invalid_argument("margin_fraction: must be in [0, 0.5)");
  if (probe.shape != "sphere" && probe.shape != "flat" && probe.shape != "mesh")
    return invalid_argument(fmt::format("probe shape '{}' cannot indent", probe.shape));
  if (fixed_nodes.empty()) return invalid_argument("no fixed nodes");
  if (threads < 0) return invalid_argument("--threads: must be >= 0");
  if (!probe.direction.allFinite() || probe.direction.norm() < 1e-12)
    return invalid_argument("probe direction must be a non-zero vector");
  return {};
}

std::vector<int> boundary_nodes(const TetMesh& mesh) {
  std::map<std::array<int, 3>, int> faces;
  static constexpr int kFaces[4][3] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};
  for (Eigen::Index t = 0; t < mesh.num_tets(); ++t)
    for (const auto& f : kFaces) {
      std::array<int, 3> key = {mesh.tets(t, f[0]), mesh.tets(t, f[1]), mesh.tets(t, f[2])};
      std::sort(key.begin(), key.end());
      ++faces[key];
    }
  std::vector<char> on(static_cast<std::size_t>(mesh.num_nodes()), 0);
  for (const auto& [key, count] : faces)
    if (count == 1)
      for (int n : key) on[static_cast<std::size_t>(n)] = 1;
  std::vector<int> out;
  for (std::size_t n = 0; n < on.size(); ++n)
    if (on[n]) out.push_back(static_cast<int>(n));
  return out;
}

Samples add_displacement_noise(const Samples& clean, double noise, std::uint64_t seed) {
  Samples out = clean;
  if (noise <= 0) return out;
  std::mt19937_64 rng(seed ^ kNoiseStream);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (std::size_t i = 0; i < out.examples.size(); ++i) {
    Example& ex = out.examples[i];
    const double sigma = noise * clean.max_displacement_m(i);
    std::vector<char> fixed(static_cast<std::size_t>(clean.mesh.num_nodes()), 0);
    for (int n : ex.fixed_nodes) fixed[static_cast<std::size_t>(n)] = 1;
    for (Eigen::Index n = 0; n < clean.mesh.num_nodes(); ++n) {
      if (!ex.visible[static_cast<std::size_t>(n)] || fixed[static_cast<std::size_t>(n)]) continue;
      for (int a = 0; a < 3; ++a) ex.positions_m(n, a) += sigma * normal(rng);
    }
  }
  return out;
}

Result<Samples> synthesize_samples(const TetMesh& mesh, const ReferenceSimulator& simulate,
                                   const SynthOptions& options) {
  HC_RETURN_IF_ERROR(options.validate());
  const Eigen::Vector3d lo = mesh.nodes.colwise().minCoeff();
  const Eigen::Vector3d hi = mesh.nodes.colwise().maxCoeff();
  const Eigen::Vector3d size = hi - lo;
  const Eigen::Vector3d dir = options.probe.direction.normalized();
  const std::vector<int> surface = boundary_nodes(mesh);
  std::mt19937_64 rng(options.seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  // Stratified placement: a near-square grid of cells over the top face, one jittered probe per
  // cell (cells reused round-robin when there are more examples than cells). Placements and force
  // levels are drawn first, in order, so that they do not depend on the threads.
  const int cols = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(options.examples))));
  const int rows = (options.examples + cols - 1) / cols;
  const auto count = static_cast<std::size_t>(options.examples);
  std::vector<ProbePose> probes(count);
  std::vector<double> forces(count);
  for (std::size_t k = 0; k < count; ++k) {
    const int cx = static_cast<int>(k) % cols, cy = (static_cast<int>(k) / cols) % rows;
    const double fx = (cx + unit(rng)) / cols, fy = (cy + unit(rng)) / rows;
    const double m = options.margin_fraction;
    ProbePose& probe = probes[k];
    probe = options.probe;
    probe.direction = dir;
    const double x = lo.x() + size.x() * (m + (1 - 2 * m) * fx);
    const double y = lo.y() + size.y() * (m + (1 - 2 * m) * fy);
    // Start just touching the top face's plane (for a downward probe); the reference model moves
    // it on to first contact with the specimen's boundary.
    probe.position_m = Eigen::Vector3d(x, y, hi.z()) - probe.radius_m * dir;
    const double random_level =
        options.min_force_fraction + (1 - options.min_force_fraction) * unit(rng);
    forces[k] = options.max_force_n *
                (options.force_levels.empty()
                     ? random_level
                     : options.force_levels[k % options.force_levels.size()]);
  }
  std::vector<Result<ReferenceIndentation>> sims(count, internal_error("not simulated"));
  ProgressTask task(options.progress, "synthesize examples", count);
  {
    // One reference solve per example on every core: OpenBLAS single-threaded meanwhile.
    std::optional<fem::SingleThreadedBlasScope> blas;
    if (count > 1 && options.threads != 1) blas.emplace();
    std::optional<tbb::global_control> limit;
    if (options.threads > 0)
      limit.emplace(tbb::global_control::max_allowed_parallelism,
                    static_cast<std::size_t>(options.threads));
    tbb::parallel_for(std::size_t{0}, count, [&](std::size_t k) {
      sims[k] = simulate(probes[k], forces[k]);
      task.advance();
    });
  }
  Samples samples;
  samples.mesh = mesh;
  for (std::size_t k = 0; k < count; ++k) {
    Result<ReferenceIndentation>& sim = sims[k];
    if (!sim.ok()) return sim.status().with_context(fmt::format("synth example {}", k));
    if (sim->positions_m.rows() != mesh.num_nodes() ||
        sim->contact_forces_n.rows() != mesh.num_nodes())
      return internal_error(fmt::format("synth example {}: simulator returned wrong sizes", k));
    Example ex;
    ex.name = fmt::format("synth{:03d}", k);
    ex.probe = probes[k];
    ex.fixed_nodes = options.fixed_nodes;
    ex.positions_m = sim->positions_m;
    for (int n : ex.fixed_nodes) ex.positions_m.row(n) = mesh.nodes.row(n);
    const double fmax = sim->contact_forces_n.rowwise().norm().maxCoeff();
    for (Eigen::Index n = 0; n < mesh.num_nodes(); ++n) {
      const Eigen::Vector3d f = sim->contact_forces_n.row(n).transpose();
      if (f.norm() > 1e-12 * fmax && fmax > 0) ex.forces.push_back({static_cast<int>(n), f});
    }
    if (ex.forces.empty())
      return failed_precondition(fmt::format("synth example {}: the probe exerts no force", k));
    ex.visible.assign(static_cast<std::size_t>(mesh.num_nodes()), options.surface_only ? 0 : 1);
    if (options.surface_only)
      for (int n : surface) ex.visible[static_cast<std::size_t>(n)] = 1;
    samples.examples.push_back(std::move(ex));
  }
  Samples noisy = add_displacement_noise(samples, options.noise, options.seed);
  HC_RETURN_IF_ERROR(validate_samples(noisy));
  return noisy;
}

}  // namespace hc::material
