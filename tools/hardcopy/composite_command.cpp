// hardcopy fit base | design composite: base materials and goal-driven composite design (thesis
// Ch. 5), written as a design file and a multi-material 3MF.
#include <fmt/format.h>

#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include "command.h"
#include "common/json.h"
#include "fabrication/composite/base_fit.h"
#include "fabrication/composite/design.h"
#include "fabrication/composite/design_file.h"
#include "fabrication/composite/library.h"
#include "fabrication/export/multi_material_3mf.h"
#include "processing/material/samples.h"

namespace hc::cli {
namespace {

using composite::ForceLevelError;

// The composite fills the target specimen's bounding box: the specimen must be that box.
constexpr double kBoxVolumeTolerance = 0.01;

Json levels_json(const std::vector<ForceLevelError>& levels) {
  Json out = Json::array();
  for (const ForceLevelError& l : levels)
    out.push_back({{"force_n", l.force_n},
                   {"examples", l.examples},
                   {"avg_m", l.avg_m},
                   {"std_m", l.std_m},
                   {"max_m", l.max_m}});
  return out;
}

// A tracked press has one example per step (30-200): keeps n (> 0) spread evenly over them, the
// first and the last included (each example costs a full simulation per fit iteration or design).
void keep_examples(int n_max, material::Samples* s) {
  auto& ex = s->examples;
  const auto n = static_cast<std::size_t>(n_max);
  if (n == 0 || ex.size() <= n) return;
  std::vector<material::Example> kept;
  for (std::size_t k = 0; k < n; ++k)
    kept.push_back(std::move(ex[n == 1 ? ex.size() - 1 : k * (ex.size() - 1) / (n - 1)]));
  ex = std::move(kept);
}

struct FitBaseArgs {
  std::vector<std::string> samples;
  std::string model = "isotropic";
  int centres = 0;
  int passes = composite::BaseFitOptions{}.passes;
  int max_examples = 0;
  std::string name;
  std::string printer_material;
  std::string tangential = "auto";
  std::string output;
  bool json = false;
};

int run_fit_base(const GlobalOptions& global, const FitBaseArgs& args) {
  Context ctx(global);
  constexpr std::string_view kName = "fit base";
  std::vector<material::Samples> samples;
  for (const std::string& path : args.samples) {
    Result<material::Samples> s = material::load_samples(path);
    if (!s.ok()) return ctx.fail(kName, s.status());
    keep_examples(args.max_examples, &*s);
    samples.push_back(std::move(s).value());
  }
  std::vector<const material::Samples*> ptrs;
  for (const material::Samples& s : samples) ptrs.push_back(&s);
  composite::BaseFitOptions options;
  options.model = args.model == "transverse" ? composite::BaseModel::kTransverse
                                             : composite::BaseModel::kIsotropic;
  options.centres = args.centres;
  options.passes = args.passes;
  options.tangential = args.tangential == "on"    ? composite::TangentialForces::kOn
                       : args.tangential == "off" ? composite::TangentialForces::kOff
                                                  : composite::TangentialForces::kAuto;
  options.progress = ctx.progress();
  composite::BaseFitSummary summary;
  Result<composite::BaseMaterial> m = composite::fit_base_material(ptrs, options, &summary);
  if (!m.ok()) return ctx.fail(kName, m.status());
  Json report = {{"samples", args.samples},
                 {"rms_error_m", summary.rms_error_m},
                 {"max_error_m", summary.max_error_m},
                 {"levels", levels_json(summary.levels)},
                 {"centres", summary.centres},
                 {"passes", summary.passes},
                 {"iterations", summary.iterations},
                 {"tangential_examples", summary.tangential_examples},
                 {"homogeneous_rms_error_m", summary.homogeneous_rms_error_m},
                 {"time_s", summary.time_s}};
  const composite::BaseMaterialFile file{args.name, args.printer_material, std::move(m).value(),
                                         report};
  if (Status s = composite::save_base_material(args.output, file); !s.ok())
    return ctx.fail(kName, s);
  if (args.json) {
    report["output"] = args.output;
    report["name"] = args.name;
    report["model"] = args.model;
    if (Status s = print_json(report); !s.ok()) return ctx.fail(kName, s);
  } else {
    fmt::print("wrote {} ({} model, {} centres, {} examples)\n", args.output, args.model,
               summary.centres, summary.levels.size());
    fmt::print("{:>10} {:>12} {:>12} {:>12}\n", "force_n", "avg_mm", "std_mm", "max_mm");
    for (const ForceLevelError& l : summary.levels)
      fmt::print("{:10.3g} {:12.4f} {:12.4f} {:12.4f}\n", l.force_n, 1e3 * l.avg_m, 1e3 * l.std_m,
                 1e3 * l.max_m);
    fmt::print("rms_error_m {:.4g}\nmax_error_m {:.4g}\ntime_s {:.2f}\n", summary.rms_error_m,
               summary.max_error_m, summary.time_s);
  }
  return kExitYes;
}

struct DesignArgs {
  std::string target;
  std::string library;
  int layers = 0;
  std::vector<int> cells;
  std::vector<double> thickness_m;
  bool vary_thickness = false;
  int sublayers = 0;
  std::string search = "bnb";
  int clusters = composite::SearchOptions{}.clusters;
  int max_examples = 0;
  std::string output;
  std::string print_3mf;
  bool json = false;
};

Result<composite::CellGrid> design_grid(const DesignArgs& args, const TetMesh& mesh) {
  const Eigen::AlignedBox3d box = composite::mesh_box(mesh);
  double volume = 0;
  for (Eigen::Index t = 0; t < mesh.num_tets(); ++t) {
    Eigen::Matrix3d d;
    for (int a = 1; a < 4; ++a)
      d.col(a - 1) = (mesh.nodes.row(mesh.tets(t, a)) - mesh.nodes.row(mesh.tets(t, 0))).transpose();
    volume += std::abs(d.determinant()) / 6;
  }
  if (std::abs(volume - box.volume()) > kBoxVolumeTolerance * box.volume())
    return invalid_argument(fmt::format(
        "{}: the target's specimen ({:.6g} m^3) is not its bounding box ({:.6g} m^3); a composite "
        "of cells fills a box",
        args.target, volume, box.volume()));
  if (!args.cells.empty() && args.layers > 0)
    return invalid_argument("give either --layers or --cells, not both");
  if (!args.cells.empty()) {
    if (args.cells.size() != 3) return invalid_argument("--cells needs three counts NX NY NZ");
    if (!args.thickness_m.empty())
      return invalid_argument("--thickness-m applies to --layers, not to --cells");
    return composite::CellGrid::voxels(box, {args.cells[0], args.cells[1], args.cells[2]});
  }
  if (!args.thickness_m.empty()) {
    if (args.layers > 0 && static_cast<std::size_t>(args.layers) != args.thickness_m.size())
      return invalid_argument(fmt::format("--layers {} but {} thicknesses in --thickness-m",
                                          args.layers, args.thickness_m.size()));
    return composite::CellGrid::layers(box, args.thickness_m);
  }
  if (args.layers < 1) return invalid_argument("give --layers N or --cells NX NY NZ");
  if (args.vary_thickness) {
    // Thickness as a design variable: the search places layer boundaries on a finer stack.
    const int s = args.sublayers > 0 ? args.sublayers : 2 * args.layers;
    if (s < args.layers)
      return invalid_argument(fmt::format("--sublayers {} < --layers {}", s, args.layers));
    return composite::CellGrid::equal_layers(box, s);
  }
  return composite::CellGrid::equal_layers(box, args.layers);
}

int run_design(const GlobalOptions& global, const DesignArgs& args) {
  Context ctx(global);
  constexpr std::string_view kName = "design composite";
  Result<material::Samples> target = material::load_samples(args.target);
  if (!target.ok()) return ctx.fail(kName, target.status());
  keep_examples(args.max_examples, &*target);
  Result<composite::Library> library = composite::read_library(args.library);
  if (!library.ok()) return ctx.fail(kName, library.status());
  Result<composite::CellGrid> grid = design_grid(args, target->mesh);
  if (!grid.ok()) return ctx.fail(kName, grid.status());
  composite::SearchOptions search;
  search.mode = args.search == "exact" ? composite::SearchMode::kExact
                                       : composite::SearchMode::kBranchAndBound;
  search.clusters = args.clusters;
  search.progress = ctx.progress();
  if (search.mode == composite::SearchMode::kExact) {
    // Refuse before the (costly) screen setup.
    const double m = static_cast<double>(library->materials.size());
    double count = std::pow(m, grid->num_cells());
    if (args.vary_thickness) {  // C(S - 1, L - 1) thickness splits x M^L materials
      const int s = grid->num_cells(), l = args.layers;
      count = std::pow(m, l);
      for (int k = 1; k < l; ++k) count *= static_cast<double>(s - k) / k;
    }
    if (count > search.max_designs)
      return ctx.fail(kName, invalid_argument(fmt::format(
                                 "--search exact: {} materials in {} cells are {:.4g} designs, "
                                 "more than the {:.4g} it enumerates (use --search bnb)",
                                 library->materials.size(),
                                 args.vary_thickness ? args.layers : grid->num_cells(), count,
                                 search.max_designs)));
  }
  composite::ScreenOptions screen;
  screen.progress = ctx.progress();
  Result<composite::CompositeDesigner> designer =
      composite::CompositeDesigner::create(*target, *grid, library->models(), screen);
  if (!designer.ok()) return ctx.fail(kName, designer.status());
  Result<composite::DesignResult> r = args.vary_thickness
                                         ? designer->search_layers(args.layers, search)
                                         : designer->search(search);
  if (!r.ok()) return ctx.fail(kName, r.status());
  composite::CellGrid out_grid = *grid;
  if (args.vary_thickness) {
    // Runs of one material over the sublayers become the layers.
    std::vector<double> thickness;
    std::vector<int> materials;
    for (int c = 0; c < grid->num_cells(); ++c) {
      const double t = grid->z_m()[static_cast<std::size_t>(c) + 1] - grid->z_m()[static_cast<std::size_t>(c)];
      if (c > 0 && r->design[static_cast<std::size_t>(c)] == materials.back()) {
        thickness.back() += t;
      } else {
        thickness.push_back(t);
        materials.push_back(r->design[static_cast<std::size_t>(c)]);
      }
    }
    Result<composite::CellGrid> layered = composite::CellGrid::layers(grid->box(), thickness);
    if (!layered.ok()) return ctx.fail(kName, layered.status());
    out_grid = std::move(layered).value();
    r->design = materials;
  }
  Json names = Json::array();
  for (int m : r->design) names.push_back(library->materials[static_cast<std::size_t>(m)].name);
  Json report = {{"target", args.target},
                 {"library", args.library},
                 {"search", args.search},
                 {"design", names},
                 {"rms_error_m", r->rms_error_m},
                 {"screen_error_m", r->screen_error_m},
                 {"designs_simulated", r->designs_simulated},
                 {"designs_screened", r->designs_screened},
                 {"certified", r->certified},
                 {"certificate", r->certificate},
                 {"gap_m", finite_or_null(r->gap_m)},
                 {"screen_bound_m", r->screen_bound_m},
                 {"max_screen_discrepancy_m", r->max_screen_discrepancy_m},
                 {"setup_time_s", designer->setup_time_s()},
                 {"search_time_s", r->search_time_s},
                 {"simulate_time_s", r->simulate_time_s},
                 {"time_s", r->time_s + designer->setup_time_s()}};
  Json thickness = Json::array();
  for (std::size_t k = 0; k + 1 < out_grid.z_m().size(); ++k)
    thickness.push_back(out_grid.z_m()[k + 1] - out_grid.z_m()[k]);
  if (out_grid.is_layers()) report["thickness_m"] = thickness;
  const composite::DesignFile file =
      composite::make_design_file(out_grid, *library, r->design, report);
  if (!args.print_3mf.empty()) {
    if (Status s = printfile::write_multi_material_3mf(args.print_3mf,
                                                       composite::design_print_model(file));
        !s.ok())
      return ctx.fail(kName, s);
  }
  if (Status s = composite::save_design(args.output, file); !s.ok()) return ctx.fail(kName, s);
  if (args.json) {
    report["output"] = args.output;
    if (!args.print_3mf.empty()) report["3mf"] = args.print_3mf;
    if (Status s = print_json(report); !s.ok()) return ctx.fail(kName, s);
  } else {
    std::string joined;
    for (const Json& n : names) joined += (joined.empty() ? "" : ", ") + n.get<std::string>();
    fmt::print("wrote {}\ndesign (bottom first): {}\nrms_error_m {:.4g}\ndesigns_simulated {}\n"
               "certified {} ({})\ntime_s {:.2f}\n",
               args.output, joined, r->rms_error_m,
               r->designs_simulated, r->certified, r->certificate,
               r->time_s + designer->setup_time_s());
  }
  return search.mode == composite::SearchMode::kExact && !r->certified ? kExitNo : kExitYes;
}

}  // namespace

void add_composite_commands(CLI::App& app, const GlobalOptions& global, int* exit_code) {
  CLI::App* fit = app.get_subcommand("fit");
  auto fa = std::make_shared<FitBaseArgs>();
  CLI::App* b = fit->add_subcommand(
      "base",
      "Fit a base material (thesis Sec. 5.4): one homogeneous non-linear material to all examples "
      "of one or more samples files at once, isotropic ((lambda, mu) of the strain invariants) or "
      "transversely isotropic (Eq. 5.6's five constants of the strain, axis z). Prints the errors "
      "per force level as in Table 5.8.1.\nExit 0 on success, 2 on bad input.");
  b->add_option("--samples", fa->samples, "Samples JSON (repeat for several specimens)")
      ->required();
  b->add_option("--model", fa->model, "isotropic or transverse")
      ->check(CLI::IsMember({"isotropic", "transverse"}))
      ->capture_default_str();
  b->add_option("--centres", fa->centres, "RBF centres P (0: 6 isotropic, 12 transverse)")
      ->check(kNonNegative);
  b->add_option("--passes", fa->passes, "Strain-coverage passes")->check(kPositive)->capture_default_str();
  b->add_option("--max-examples", fa->max_examples,
                "Per samples file, at most N examples, spread evenly over its steps (0: all)")
      ->check(kNonNegative);
  b->add_option("--name", fa->name, "The base material's name")->required();
  b->add_option("--printer-material", fa->printer_material,
                "The printer material (or mix) it is printed with");
  b->add_option("--tangential", fa->tangential,
                "Recover missing tangential probe forces: auto (when an example's forces are all "
                "parallel), on, off")
      ->check(CLI::IsMember({"auto", "on", "off"}))
      ->capture_default_str();
  b->add_option("-o,--output", fa->output, "Base-material JSON to write")->required();
  b->add_flag("--json", fa->json, "Print one JSON object");
  b->callback([&global, fa, exit_code] { *exit_code = run_fit_base(global, *fa); });

  CLI::App* design = app.add_subcommand("design", "Goal-driven design (thesis Ch. 5)");
  design->require_subcommand(1);
  auto da = std::make_shared<DesignArgs>();
  CLI::App* c = design->add_subcommand(
      "composite",
      "Find the assignment of base materials to cells (layers or voxels of the target specimen's "
      "box) whose simulation best matches the target's force-displacement examples: the thesis's "
      "branch-and-bound with clustering (bnb) or every design screened and the best ones "
      "simulated in full until the answer is certified (exact).\nExit 0 on success, 1 when "
      "--search exact ends without a certificate, 2 on bad input.");
  c->add_option("--target", da->target, "Samples JSON: the target's examples and specimen")
      ->required();
  c->add_option("--library", da->library, "Base-material library JSON")->required();
  c->add_option("--layers", da->layers, "Layers along z (equal unless --thickness-m)")
      ->check(kPositive);
  c->add_option("--cells", da->cells, "Voxels NX NY NZ")->expected(3);
  c->add_option("--thickness-m", da->thickness_m, "Layer thicknesses in metres, bottom first")
      ->check(kPositive);
  c->add_flag("--vary-thickness", da->vary_thickness,
              "With --layers N: layer thicknesses are design variables too (boundaries on a stack "
              "of --sublayers, default 2N)");
  c->add_option("--sublayers", da->sublayers, "With --vary-thickness: the stack's sublayers")
      ->check(kPositive);
  c->add_option("--search", da->search, "bnb or exact")
      ->check(CLI::IsMember({"bnb", "exact"}))
      ->capture_default_str();
  c->add_option("--clusters", da->clusters, "K of the K-means per tree level")
      ->check(kPositive)
      ->capture_default_str();
  c->add_option("--max-examples", da->max_examples,
                "At most N of the target's examples, spread evenly over its steps (0: all)")
      ->check(kNonNegative);
  c->add_option("-o,--output", da->output, "Design JSON to write")->required();
  c->add_option("--3mf", da->print_3mf, "Multi-material 3MF to write (millimetres)");
  c->add_flag("--json", da->json, "Print one JSON object");
  c->callback([&global, da, exit_code] { *exit_code = run_design(global, *da); });
}

HC_REGISTER_COMMANDS_ORDERED(45, add_composite_commands);

}  // namespace hc::cli
