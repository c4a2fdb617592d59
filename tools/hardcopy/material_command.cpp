// hardcopy synth | fit heterogeneous | evaluate: the data-driven material of thesis Ch. 4.
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

#include "command.h"
#include "common/json.h"
#include "processing/hyperelastic/neo_hookean.h"
#include "processing/material/fit.h"
#include "processing/material/material.h"
#include "processing/material/samples.h"
#include "processing/material/synth.h"
#include "processing/scene/reference.h"
#include "processing/scene/scene.h"

namespace hc::cli {
namespace {

using material::Material;
using material::Samples;

struct SynthArgs {
  std::string scene;
  std::string output;
  int examples = 12;
  double noise = 0;
  std::uint64_t seed = 1;
  bool surface_only = false;
  bool json = false;
  int threads = 0;
};

int run_synth(const GlobalOptions& global, const SynthArgs& args) {
  Context ctx(global);
  constexpr std::string_view kName = "synth";
  Result<scene::Scene> sc = scene::read_scene(args.scene);
  if (!sc.ok()) return ctx.fail(kName, sc.status());
  const auto bad = [&](const std::string& what) {
    (void)ctx.fail(kName, invalid_argument(fmt::format("{}: {}", args.scene, what)));
    return kExitBadInput;
  };
  if (sc->load.control != fem::LoadControl::kForce)
    return bad("synth needs \"load\": {\"force_n\": F} (the largest example force)");
  if (sc->probe.shape == scene::ProbeSpec::Shape::kMesh)
    return bad("synth supports sphere and flat probes");
  // The examples are spread over the whole top face, so the specimen is meshed without a contact
  // in view: the scene's mesh keys, or TetGen's quality mesh (contact_surface.h keeps probes
  // smaller than its elements from slipping between nodes).
  Result<TetMesh> mesh = scene::build_specimen(sc->specimen);
  if (!mesh.ok()) return ctx.fail(kName, mesh.status());
  Result<std::vector<hyperelastic::NeoHookeanMaterial>> per_tet =
      scene::reference_materials(sc->material, *mesh);
  if (!per_tet.ok()) return bad(per_tet.status().message());
  Result<std::vector<int>> fixed = scene::fixed_nodes(*sc, *mesh);
  if (!fixed.ok()) return ctx.fail(kName, fixed.status());
  material::SynthOptions options;
  options.examples = args.examples;
  options.noise = args.noise;
  options.seed = args.seed;
  options.probe.shape = sc->probe.shape == scene::ProbeSpec::Shape::kSphere ? "sphere" : "flat";
  options.probe.radius_m = sc->probe.radius_m;
  options.probe.direction = sc->probe.direction.normalized();
  options.max_force_n = sc->load.value;
  options.surface_only = args.surface_only;
  options.fixed_nodes = *fixed;
  options.threads = args.threads;
  options.progress = ctx.progress();
  if (Status s = options.validate(); !s.ok()) return bad(s.message());
  const auto t0 = std::chrono::steady_clock::now();
  Result<Samples> samples = material::synthesize_samples(
      *mesh,
      scene::reference_simulator(*mesh, std::move(per_tet).value(), *fixed, std::max(1, sc->steps)),
      options);
  if (!samples.ok()) {
    const int code = ctx.fail(kName, samples.status());
    return samples.status().code() == StatusCode::kInvalidArgument ? kExitBadInput : code;
  }
  for (std::size_t i = 0; i < samples->examples.size(); ++i)
    if (!samples->examples[i].positions_m.allFinite() ||
        !std::isfinite(samples->max_displacement_m(i)))
      return ctx.fail(kName, failed_precondition(fmt::format(
                                 "example {}: non-finite positions (the reference model found no "
                                 "equilibrium); nothing written",
                                 i)));
  if (Status s = material::save_samples(args.output, *samples); !s.ok()) return ctx.fail(kName, s);
  const double time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (args.json) {
    Json j = {{"scene", args.scene},       {"output", args.output},
              {"examples", args.examples}, {"noise", args.noise},
              {"seed", args.seed},         {"nodes", mesh->num_nodes()},
              {"tets", mesh->num_tets()},  {"max_displacement_m", samples->max_displacement_m()},
              {"time_s", time_s}};
    if (Status s = print_json(j); !s.ok()) return ctx.fail(kName, s);
  } else {
    fmt::print("wrote {} ({} examples, {} tets, max displacement {:.4g} m, {:.1f} s)\n",
               args.output, args.examples, mesh->num_tets(), samples->max_displacement_m(), time_s);
  }
  return kExitYes;
}

struct FitArgs {
  std::string samples;
  std::string output;
  bool json = false;
  double regularization = material::ParameterFitOptions{}.regularization;
  double poisson_prior = material::ParameterFitOptions{}.poisson_prior;
  double tolerance = material::HeterogeneousFitOptions::RbfOptions{}.tolerance;
  int max_basis = material::HeterogeneousFitOptions::RbfOptions{}.max_basis;
  int max_iterations = material::ParameterFitOptions{}.max_iterations;
  std::string backend = "own";
  std::string solver = "auto";
  int threads = 0;
  bool joint = false;
  double joint_regularization = material::JointRefinementOptions{}.regularization_scale;
  std::string joint_adjacency = "face";
  bool joint_linear = false;
};

int run_fit(const GlobalOptions& global, const FitArgs& args) {
  Context ctx(global);
  constexpr std::string_view kName = "fit heterogeneous";
  Result<Samples> samples = material::load_samples(args.samples);
  if (!samples.ok()) return ctx.fail(kName, samples.status());
  material::HeterogeneousFitOptions options;
  options.parameters.regularization = args.regularization;
  options.parameters.poisson_prior = args.poisson_prior;
  options.parameters.max_iterations = args.max_iterations;
  options.parameters.backend =
      args.backend == "ceres" ? material::FitBackend::kCeres : material::FitBackend::kOwnLm;
  options.parameters.solver = args.solver == "dense"         ? material::FitSolver::kDense
                              : args.solver == "matrix-free" ? material::FitSolver::kMatrixFree
                                                             : material::FitSolver::kAuto;
  options.rbf.tolerance = args.tolerance;
  options.rbf.max_basis = args.max_basis;
  options.threads = args.threads;
  options.joint.enabled = args.joint;
  options.joint.regularization_scale = args.joint_regularization;
  options.joint.adjacency = args.joint_adjacency == "vertex" ? material::TetAdjacency::kVertex
                                                             : material::TetAdjacency::kFace;
  options.joint.quadratic_stiffening = !args.joint_linear;
  options.progress = ctx.progress();
  if (Status s = options.validate(); !s.ok()) return ctx.fail(kName, s);
  material::HeterogeneousFitSummary summary;
  Result<Material> m = material::fit_heterogeneous(*samples, options, &summary);
  if (!m.ok()) {
    // Input that the fitter cannot use (no fixed nodes, displacements against the forces, ...)
    // is bad input; anything else is an internal failure, still "no material".
    const bool bad_input = m.status().code() == StatusCode::kInvalidArgument ||
                           m.status().code() == StatusCode::kFailedPrecondition;
    const int code = ctx.fail(kName, m.status());
    return bad_input ? kExitBadInput : code;
  }
  if (Status s = material::save_material(args.output, *m); !s.ok()) return ctx.fail(kName, s);
  int unusable = 0;
  for (const auto& e : summary.examples) unusable += e.usable ? 0 : 1;
  if (args.json) {
    Json j = {{"samples", args.samples},
              {"output", args.output},
              {"examples", samples->examples.size()},
              {"tets", samples->mesh.num_tets()},
              {"rms_error_m", summary.rms_error_m},
              {"max_error_m", summary.max_error_m},
              {"mean_basis_size", summary.mean_basis_size},
              {"time_s", summary.time_s},
              {"parameter_time_s", summary.parameter_time_s},
              {"rbf_time_s", summary.rbf_time_s},
              {"joint", args.joint},
              {"joint_time_s", summary.joint_time_s},
              {"joint_matrix_free", summary.joint.matrix_free},
              {"joint_cg_iterations", summary.joint.cg_iterations},
              {"unusable_examples", unusable}};
    if (Status s = print_json(j); !s.ok()) return ctx.fail(kName, s);
  } else {
    fmt::print(
        "wrote {} ({} tets, {} examples)\nrms_error_m {:.4g}\nmax_error_m {:.4g}\n"
        "mean_basis_size {:.2f}\ntime_s {:.2f}\n",
        args.output, samples->mesh.num_tets(), samples->examples.size(), summary.rms_error_m,
        summary.max_error_m, summary.mean_basis_size, summary.time_s);
  }
  return unusable == 0 ? kExitYes : kExitNo;
}

struct EvaluateArgs {
  std::string material;
  std::string samples;
  bool json = false;
  int steps = material::EvaluateOptions{}.steps;
  int threads = 0;
};

int run_evaluate(const GlobalOptions& global, const EvaluateArgs& args) {
  Context ctx(global);
  constexpr std::string_view kName = "evaluate";
  Result<std::unique_ptr<fem::MaterialModel>> model = material::load_material(args.material);
  if (!model.ok()) return ctx.fail(kName, model.status());
  Result<Samples> samples = material::load_samples(args.samples);
  if (!samples.ok()) return ctx.fail(kName, samples.status());
  material::EvaluateOptions options;
  options.steps = args.steps;
  options.threads = args.threads;
  options.progress = ctx.progress();
  Result<material::EvaluateSummary> ev = material::evaluate_material(**model, *samples, options);
  if (!ev.ok()) {
    const int code = ctx.fail(kName, ev.status());
    return ev.status().code() == StatusCode::kInvalidArgument ? kExitBadInput : code;
  }
  // A non-finite error is a simulation that broke down, not a score (it printed inf and null).
  bool finite = std::isfinite(ev->rms_error_m) && std::isfinite(ev->max_error_m) &&
                std::isfinite(ev->error_rel_max_disp);
  for (std::size_t i = 0; i < ev->example_rms_error_m.size(); ++i) {
    if (std::isfinite(ev->example_rms_error_m[i])) continue;
    return ctx.fail(kName, failed_precondition(
                               fmt::format("example {}: the material gave non-finite positions (no "
                                           "equilibrium under the example's forces)",
                                           i)));
  }
  if (!finite)
    return ctx.fail(kName, failed_precondition(fmt::format(
                               "non-finite error (rms {} m, max {} m, max displacement {} m)",
                               ev->rms_error_m, ev->max_error_m, ev->max_displacement_m)));
  if (args.json) {
    Json per_example = Json::array();
    for (double e : ev->example_rms_error_m) per_example.push_back(e);
    Json j = {{"material", args.material},
              {"samples", args.samples},
              {"rms_error_m", ev->rms_error_m},
              {"max_error_m", ev->max_error_m},
              {"max_displacement_m", ev->max_displacement_m},
              {"error_rel_max_disp", ev->error_rel_max_disp},
              {"example_rms_error_m", std::move(per_example)},
              {"time_s", ev->time_s}};
    if (Status s = print_json(j); !s.ok()) return ctx.fail(kName, s);
  } else {
    fmt::print("rms_error_m {:.4g}\nmax_error_m {:.4g}\nerror_rel_max_disp {:.4g}\ntime_s {:.2f}\n",
               ev->rms_error_m, ev->max_error_m, ev->error_rel_max_disp, ev->time_s);
  }
  return kExitYes;
}

}  // namespace

void add_material_commands(CLI::App& app, const GlobalOptions& global, int* exit_code) {
  auto sa = std::make_shared<SynthArgs>();
  CLI::App* sy = app.add_subcommand(
      "synth",
      "Synthetic force-displacement samples from the neo-Hookean reference model (thesis Sec. "
      "4.5): probe positions and force levels (up to the scene's load.force_n) spread over the "
      "top face, Gaussian noise on the displacements.\nExit 0 on success, 1 when the reference "
      "model finds no equilibrium, 2 on bad input.");
  sy->add_option("SCENE", sa->scene, "Scene JSON (as for hardcopy simulate)")->required();
  sy->add_option("-o,--output", sa->output, "Samples JSON to write")->required();
  sy->add_option("--examples", sa->examples, "Number of examples")
      ->check(kPositive)
      ->capture_default_str();
  sy->add_option("--noise", sa->noise,
                 "Gaussian noise on each measured coordinate, standard deviation relative to the "
                 "example's largest displacement (0.1 = 10 %)")
      ->check(kNonNegative)
      ->capture_default_str();
  sy->add_option("--seed", sa->seed, "Random seed (placement and noise)")->capture_default_str();
  sy->add_flag("--surface-only", sa->surface_only,
               "Mark only boundary nodes visible (like surface markers)");
  sy->add_option("--threads", sa->threads, "Examples simulated in parallel (0: all cores)")
      ->check(kNonNegative);
  sy->add_flag("--json", sa->json, "Print one JSON object");
  sy->callback([&global, sa, exit_code] { *exit_code = run_synth(global, *sa); });

  CLI::App* fit = app.add_subcommand("fit", "Fit materials to force-displacement samples");
  fit->require_subcommand(1);
  auto fa = std::make_shared<FitArgs>();
  CLI::App* h = fit->add_subcommand(
      "heterogeneous",
      "Fit a heterogeneous non-linear material (thesis Sec. 4.3): per example Levenberg-Marquardt "
      "on Eq. 4.10, then per tet an RBF in strain space.\nExit 0 on success, 1 when some example "
      "fit did not converge to a usable result, 2 on bad input.");
  h->add_option("--samples", fa->samples, "Samples JSON (hardcopy.samples)")->required();
  h->add_option("-o,--output", fa->output, "Material JSON to write")->required();
  h->add_flag("--json", fa->json, "Print one JSON object");
  h->add_option("--regularization", fa->regularization,
                "Weight gamma of the Laplacian smoothness term (dimensionless; residuals are "
                "divided by each example's largest displacement)")
      ->check(kNonNegative)
      ->capture_default_str();
  h->add_option("--poisson-prior", fa->poisson_prior,
                "Weight of a weak prior pulling each tet's Poisson's ratio towards 0.3 (noisy "
                "displacements hardly determine it; 0.1 in the noise study; 0: off)")
      ->check(kNonNegative)
      ->capture_default_str();
  h->add_option("--tolerance", fa->tolerance,
                "Greedy basis selection stops when every example's parameters are reproduced "
                "within this relative error")
      ->check(kNonNegative)
      ->capture_default_str();
  h->add_option("--max-basis", fa->max_basis, "Largest RBF basis per tet")
      ->check(kPositive)
      ->capture_default_str();
  h->add_option("--max-iterations", fa->max_iterations, "LM iterations per example")
      ->check(kPositive)
      ->capture_default_str();
  h->add_option("--backend", fa->backend, "Optimiser: own LM or Ceres")
      ->check(CLI::IsMember({"own", "ceres"}))
      ->capture_default_str();
  h->add_option("--solver", fa->solver,
                "Own LM's linear solver: dense (forms the Jacobian), matrix-free (CG with one FEM "
                "solve per Jacobian product, memory linear in the mesh) or auto (the cheaper)")
      ->check(CLI::IsMember({"auto", "dense", "matrix-free"}))
      ->capture_default_str();
  h->add_option("--threads", fa->threads, "Examples fitted in parallel (0: all cores)")
      ->check(kNonNegative);
  h->add_flag("--joint", fa->joint,
              "For noisy data: after the per-example fits, fit one material (per tet base "
              "stiffness, Poisson's ratio, a linear and a quadratic-like strain stiffening) to ALL "
              "examples at once, smoothing the material instead of each example's parameters (an "
              "extension of the thesis's method; the material has 13 RBF centres per tet)");
  h->add_flag("--joint-linear", fa->joint_linear,
              "With --joint: the linear strain stiffening only (one RBF centre per tet)");
  h->add_option("--joint-regularization", fa->joint_regularization,
                "With --joint: its Laplacian weight relative to --regularization")
      ->check(kNonNegative)
      ->capture_default_str();
  h->add_option("--joint-adjacency", fa->joint_adjacency,
                "With --joint: the tets its Laplacian couples (face neighbours; vertex: the "
                "thesis's per-example stencil, wider, which blurs jumps between layers; its "
                "tuned --joint-regularization is 0.03)")
      ->check(CLI::IsMember({"face", "vertex"}))
      ->capture_default_str();
  h->callback([&global, fa, exit_code] { *exit_code = run_fit(global, *fa); });

  auto ea = std::make_shared<EvaluateArgs>();
  CLI::App* e = app.add_subcommand(
      "evaluate",
      "Simulate every example's forces with a material (incremental loading) and compare with "
      "the samples' node positions. Prints rms_error_m, max_error_m and error_rel_max_disp (RMS "
      "error / largest displacement, thesis Sec. 4.5).");
  e->add_option("--material", ea->material, "Material JSON (hardcopy.material)")->required();
  e->add_option("--samples", ea->samples, "Samples JSON (hardcopy.samples)")->required();
  e->add_flag("--json", ea->json, "Print one JSON object");
  e->add_option("--steps", ea->steps, "Load increments")
      ->check(kPositive)
      ->capture_default_str();
  e->add_option("--threads", ea->threads, "Examples simulated in parallel (0: all cores)")
      ->check(kNonNegative);
  e->callback([&global, ea, exit_code] { *exit_code = run_evaluate(global, *ea); });
}

HC_REGISTER_COMMANDS_ORDERED(40, add_material_commands);

}  // namespace hc::cli
