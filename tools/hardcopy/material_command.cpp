// hardcopy fit heterogeneous | evaluate: the data-driven material of thesis Ch. 4.
#include <fmt/format.h>

#include <chrono>
#include <string>

#include "command.h"
#include "common/json.h"
#include "processing/material/fit.h"
#include "processing/material/material.h"
#include "processing/material/samples.h"

namespace hc::cli {
namespace {

using material::Material;
using material::Samples;

struct FitArgs {
  std::string samples;
  std::string output;
  bool json = false;
  double regularization = material::ParameterFitOptions{}.regularization;
  double tolerance = material::HeterogeneousFitOptions::RbfOptions{}.tolerance;
  int max_basis = material::HeterogeneousFitOptions::RbfOptions{}.max_basis;
  int max_iterations = material::ParameterFitOptions{}.max_iterations;
  std::string backend = "own";
  int threads = 0;
};

int run_fit(const GlobalOptions& global, const FitArgs& args) {
  Context ctx(global);
  constexpr std::string_view kName = "fit heterogeneous";
  Result<Samples> samples = material::load_samples(args.samples);
  if (!samples.ok()) return ctx.fail(kName, samples.status());
  material::HeterogeneousFitOptions options;
  options.parameters.regularization = args.regularization;
  options.parameters.max_iterations = args.max_iterations;
  options.parameters.backend =
      args.backend == "ceres" ? material::FitBackend::kCeres : material::FitBackend::kOwnLm;
  options.rbf.tolerance = args.tolerance;
  options.rbf.max_basis = args.max_basis;
  options.threads = args.threads;
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
  options.progress = ctx.progress();
  Result<material::EvaluateSummary> ev = material::evaluate_material(**model, *samples, options);
  if (!ev.ok()) {
    const int code = ctx.fail(kName, ev.status());
    return ev.status().code() == StatusCode::kInvalidArgument ? kExitBadInput : code;
  }
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
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  h->add_option("--tolerance", fa->tolerance,
                "Greedy basis selection stops when every example's parameters are reproduced "
                "within this relative error")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  h->add_option("--max-basis", fa->max_basis, "Largest RBF basis per tet")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  h->add_option("--max-iterations", fa->max_iterations, "LM iterations per example")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  h->add_option("--backend", fa->backend, "Optimiser: own LM or Ceres")
      ->check(CLI::IsMember({"own", "ceres"}))
      ->capture_default_str();
  h->add_option("--threads", fa->threads, "Examples fitted in parallel (0: all cores)")
      ->check(CLI::NonNegativeNumber);
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
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  e->callback([&global, ea, exit_code] { *exit_code = run_evaluate(global, *ea); });
}

HC_REGISTER_COMMANDS_ORDERED(40, add_material_commands);

}  // namespace hc::cli
