// hardcopy plot | report: the lab's figures (force–displacement curves of sessions and samples,
// measured vs simulated, base materials, target vs design, error maps) as PNG/SVG with their data,
// or gathered into one self-contained HTML page.
#include <fmt/format.h>

#include <filesystem>
#include <memory>
#include <set>

#include "command.h"
#include "common/file_io.h"
#include "common/json.h"
#include "figures/inputs.h"
#include "figures/report.h"

namespace hc::cli {
namespace {

struct FigureArgs {
  figures::FigureInputs inputs;
  std::string target;
  std::string output;
  std::string formats = "png,svg";
  std::string title = "Hardcopy report";
  bool json = false;
};

int inputs_failed(const Context& ctx, std::string_view name, const Status& s) {
  // Inputs are read but not understood -> bad input; anything else keeps its mapping.
  const int code = ctx.fail(name, s);
  return s.code() == StatusCode::kInvalidArgument || s.code() == StatusCode::kNotFound
             ? kExitBadInput
             : code;
}

int run_plot(const GlobalOptions& global, FigureArgs args) {
  Context ctx(global);
  constexpr std::string_view kName = "plot";
  Result<std::vector<plot::ImageFormat>> formats = figures::parse_formats(args.formats);
  if (!formats.ok()) return ctx.fail(kName, formats.status());
  if (!args.target.empty()) args.inputs.target = args.target;
  Result<std::vector<figures::FigureSet>> sets = figures::figures_for_inputs(args.inputs);
  if (!sets.ok()) return inputs_failed(ctx, kName, sets.status());
  // One set goes straight into the folder; several get a sub-folder each (named after the set).
  const std::filesystem::path root(args.output);
  std::set<std::string> used;
  Json out = Json::array();
  for (const figures::FigureSet& set : *sets) {
    std::filesystem::path dir = root;
    if (sets->size() > 1) {
      std::string name = figures::slug(set.title);
      for (int k = 2; !used.insert(name).second; ++k) name = figures::slug(set.title) + "-" + std::to_string(k);
      dir /= name;
    }
    Result<std::vector<std::filesystem::path>> written = figures::write_figure_set(set, dir, *formats);
    if (!written.ok()) return ctx.fail(kName, written.status());
    Json files = Json::array();
    for (const auto& p : *written) files.push_back(p.string());
    out.push_back(Json{{"title", set.title}, {"dir", dir.string()}, {"numbers", set.numbers},
                       {"files", files}});
    if (!args.json)
      fmt::print("{}: {} figures in {}\n", set.title, set.figures.size(), dir.string());
  }
  if (args.json) {
    if (Status s = print_json(Json{{"sets", out}}); !s.ok()) return ctx.fail(kName, s);
  }
  return kExitYes;
}

int run_report(const GlobalOptions& global, FigureArgs args) {
  Context ctx(global);
  constexpr std::string_view kName = "report";
  if (!args.target.empty()) args.inputs.target = args.target;
  Result<std::vector<figures::FigureSet>> sets = figures::figures_for_inputs(args.inputs);
  if (!sets.ok()) return inputs_failed(ctx, kName, sets.status());
  figures::ReportOptions o;
  o.title = args.title;
  o.generator = "hardcopy " HARDCOPY_VERSION;
  Result<std::string> html = figures::report_html(*sets, o);
  if (!html.ok()) return ctx.fail(kName, html.status());
  if (Status s = write_file_atomic(args.output, *html); !s.ok()) return ctx.fail(kName, s);
  std::size_t n = 0;
  for (const auto& s : *sets) n += s.figures.size();
  if (args.json) {
    Json numbers = Json::array();
    for (const auto& s : *sets) numbers.push_back(Json{{"title", s.title}, {"numbers", s.numbers}});
    if (Status s = print_json(Json{{"report", args.output}, {"figures", n}, {"sets", numbers}});
        !s.ok())
      return ctx.fail(kName, s);
  } else {
    fmt::print("wrote {} ({} figures, {} bytes)\n", args.output, n, html->size());
  }
  return kExitYes;
}

void add_inputs(CLI::App* c, FigureArgs& a) {
  c->add_option("INPUT", a.inputs.files,
                "Session .mcap files and/or samples .json files (hardcopy.samples)")
      ->required();
  c->add_option("--label", a.inputs.labels,
                "Legend name of each samples input, in order (default: file names)");
  c->add_option("--material", a.inputs.materials,
                "Material JSON to simulate the samples with: measured vs simulated curves and the "
                "error map (repeatable)");
  c->add_option("--material-label", a.inputs.material_labels,
                "Legend name of each --material, in order");
  c->add_option("--target", a.target,
                "Target samples JSON: every samples input is compared with it (target vs design)");
  c->add_option("--steps", a.inputs.simulation_steps, "Load increments of each simulation")
      ->check(kPositive)
      ->capture_default_str();
  c->add_flag("--json", a.json, "Print one JSON object");
}

}  // namespace

void add_plot_commands(CLI::App& app, const GlobalOptions& global, int* exit_code) {
  auto pa = std::make_shared<FigureArgs>();
  CLI::App* p = app.add_subcommand(
      "plot",
      "Figures of sessions and samples as PNG/SVG, each with its data (NAME.csv as plotted, "
      "NAME.json with the source numbers in SI): force-displacement curves per probe location; "
      "with --material, measured vs simulated and the error map on the surface (also VTU); with "
      "two or more samples files, the materials' curves together; with --target, target vs "
      "design. Several figure sets go to one sub-folder each.\nExit 0 on success, 2 on bad "
      "input.");
  add_inputs(p, *pa);
  p->add_option("-o,--output", pa->output, "Folder to write into (created)")->required();
  p->add_option("--format", pa->formats, "Image formats: png, svg or png,svg")
      ->capture_default_str();
  p->callback([&global, pa, exit_code] { *exit_code = run_plot(global, *pa); });

  auto ra = std::make_shared<FigureArgs>();
  CLI::App* r = app.add_subcommand(
      "report",
      "One self-contained HTML page (figures embedded as data: URIs, no external files) with "
      "the figures and headline numbers of the inputs (as for hardcopy plot).\nExit 0 on "
      "success, 2 on bad input.");
  add_inputs(r, *ra);
  r->add_option("-o,--output", ra->output, "HTML file to write")->required();
  r->add_option("--title", ra->title, "The page's title")->capture_default_str();
  r->callback([&global, ra, exit_code] { *exit_code = run_report(global, *ra); });
}

HC_REGISTER_COMMANDS_ORDERED(80, add_plot_commands);

}  // namespace hc::cli
