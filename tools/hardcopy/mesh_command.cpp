// hardcopy mesh check | convert | repair
#include <fmt/format.h>

#include <string>

#include "command.h"
#include "common/json.h"
#include "common/mesh_io.h"
#include "common/units.h"
#include "fabrication/printability/mesh_check.h"
#include "fabrication/printability/mesh_repair.h"

namespace hc::cli {
namespace {

struct CheckArgs {
  std::string input;
  bool json = false;
  bool skip_self_intersections = false;
};

int run_check(const GlobalOptions& global, const CheckArgs& args) {
  Context ctx(global);
  Result<TriangleMesh> mesh = read_mesh(args.input);
  if (!mesh.ok()) return ctx.fail("mesh check", mesh.status());
  fabrication::MeshCheckOptions options;
  options.check_self_intersections = !args.skip_self_intersections;
  options.progress = ctx.progress();
  Result<fabrication::MeshCheckReport> report = fabrication::check_mesh(*mesh, options);
  if (!report.ok()) return ctx.fail("mesh check", report.status().with_context(args.input));
  if (args.json) {
    Json j = fabrication::to_json(*report);
    j["file"] = args.input;
    (void)hc::print_json(j);
  } else {
    fmt::print("{}\n{}", args.input, fabrication::to_text(*report));
  }
  return report->printable ? kExitYes : kExitNo;
}

struct ConvertArgs {
  std::string input;
  std::string output;
  bool ascii = false;
  std::string unit = "millimeter";
  bool json = false;
};

Result<units::LengthUnit> parse_unit(const std::string& name) {
  if (auto u = units::length_unit_from_name(name)) return *u;
  return invalid_argument(fmt::format(
      "--unit: unknown length unit '{}' (expected micron, millimeter, centimeter, inch, foot or "
      "meter)",
      name));
}

int run_convert(const GlobalOptions& global, const ConvertArgs& args) {
  Context ctx(global);
  Result<units::LengthUnit> unit = parse_unit(args.unit);
  if (!unit.ok()) return ctx.fail("mesh convert", unit.status());
  // Check the output format before reading a possibly large input.
  if (Result<MeshFormat> f = mesh_format_from_path(args.output); !f.ok())
    return ctx.fail("mesh convert", f.status());
  Result<TriangleMesh> mesh = read_mesh(args.input);
  if (!mesh.ok()) return ctx.fail("mesh convert", mesh.status());
  MeshWriteOptions options;
  options.binary = !args.ascii;
  options.unit = *unit;
  if (Status s = write_mesh(args.output, *mesh, options); !s.ok())
    return ctx.fail("mesh convert", s);
  if (args.json) {
    (void)hc::print_json({{"input", args.input},
                          {"output", args.output},
                          {"vertices", mesh->num_vertices()},
                          {"triangles", mesh->num_triangles()}});
  } else {
    fmt::print("wrote {} ({} vertices, {} triangles)\n", args.output, mesh->num_vertices(),
               mesh->num_triangles());
  }
  return kExitYes;
}

struct RepairArgs {
  std::string input;
  std::string output;
  double weld_tolerance = 0.0;
  bool resolve_self_intersections = false;
  bool json = false;
};

// --weld-tolerance at or above this fraction of the bounding-box diagonal is refused.
constexpr double kMaxWeldFraction = 0.05;

int run_repair(const GlobalOptions& global, const RepairArgs& args) {
  Context ctx(global);
  if (Result<MeshFormat> f = mesh_format_from_path(args.output); !f.ok())
    return ctx.fail("mesh repair", f.status());
  Result<TriangleMesh> mesh = read_mesh(args.input);
  if (!mesh.ok()) return ctx.fail("mesh repair", mesh.status());
  if (mesh->num_vertices() > 0) {
    // Welding merges near-duplicates; a tolerance on the scale of the mesh merges it into a point
    // (1e308 used to write an empty mesh and exit 1).
    const double diagonal =
        (mesh->vertices.colwise().maxCoeff() - mesh->vertices.colwise().minCoeff()).norm();
    if (args.weld_tolerance >= kMaxWeldFraction * diagonal && args.weld_tolerance > 0)
      return ctx.fail("mesh repair",
                      invalid_argument(fmt::format(
                          "--weld-tolerance {:g} is {:.3g} of the mesh's bounding-box diagonal "
                          "({:g}): welding would merge whole features, not duplicate vertices "
                          "(use less than {:g})",
                          args.weld_tolerance, args.weld_tolerance / diagonal, diagonal,
                          kMaxWeldFraction * diagonal)));
  }
  fabrication::MeshRepairOptions options;
  options.weld_tolerance = args.weld_tolerance;
  options.resolve_self_intersections = args.resolve_self_intersections;
  options.progress = ctx.progress();
  fabrication::MeshRepairSummary summary;
  if (Status s = fabrication::repair_mesh(options, &*mesh, &summary); !s.ok())
    return ctx.fail("mesh repair", s.with_context(args.input));
  if (mesh->num_triangles() == 0)
    return ctx.fail("mesh repair",
                    failed_precondition(fmt::format(
                        "{}: the repair left no triangles; nothing written", args.input)));
  // The repaired mesh is written even when it is still not closed: it is better than the input,
  // and the exit code and the report say plainly that it is not printable.
  if (Status s = write_mesh(args.output, *mesh); !s.ok()) return ctx.fail("mesh repair", s);
  if (args.json) {
    Json j = fabrication::to_json(summary);
    j["input"] = args.input;
    j["output"] = args.output;
    (void)hc::print_json(j);
  } else {
    fmt::print("{} -> {}\n{}", args.input, args.output, fabrication::to_text(summary));
    if (!summary.closed)
      fmt::print("NOT repaired: the result is still not closed ({} boundary edges)\n",
                 summary.after.boundary_edges);
    else if (!summary.printable)
      fmt::print("NOT printable after repair: see the problems above\n");
  }
  return summary.printable ? kExitYes : kExitNo;
}

}  // namespace

void add_mesh_commands(CLI::App& app, const GlobalOptions& global, int* exit_code) {
  CLI::App* mesh = app.add_subcommand("mesh", "Check, convert and repair surface meshes");
  mesh->require_subcommand(1);

  auto check = std::make_shared<CheckArgs>();
  CLI::App* c = mesh->add_subcommand(
      "check",
      "Is this mesh printable? Reports topology, orientation, self-intersections, volume and "
      "genus.\nExit 0 printable, 1 readable but not printable, 2 unreadable or bad usage.");
  c->add_option("FILE", check->input, "Mesh file (.obj .stl .ply .ply.gz .off)")->required();
  c->add_flag("--json", check->json, "Print one JSON object");
  c->add_flag("--no-self-intersections", check->skip_self_intersections,
              "Skip the (expensive) self-intersection test; the verdict is then never printable");
  c->callback([&global, check, exit_code] { *exit_code = run_check(global, *check); });

  auto convert = std::make_shared<ConvertArgs>();
  CLI::App* v = mesh->add_subcommand(
      "convert",
      "Convert between mesh formats, chosen by extension (.obj .stl .ply .ply.gz .off; "
      "writes also .3mf)");
  v->add_option("IN", convert->input, "Input mesh")->required();
  v->add_option("OUT", convert->output, "Output mesh")->required();
  v->add_flag("--ascii", convert->ascii, "Write ASCII STL / PLY instead of binary");
  v->add_option("--unit", convert->unit, "Length unit written into 3MF files")
      ->capture_default_str();
  v->add_flag("--json", convert->json, "Print one JSON object");
  v->callback([&global, convert, exit_code] { *exit_code = run_convert(global, *convert); });

  auto repair = std::make_shared<RepairArgs>();
  CLI::App* r = mesh->add_subcommand(
      "repair",
      "Weld duplicate vertices, drop degenerate and duplicate faces, orient consistently and "
      "outward; optionally resolve self-intersections.\nExit 0 when the result is printable, 1 "
      "when it is not (e.g. still open).");
  r->add_option("IN", repair->input, "Input mesh")->required();
  r->add_option("OUT", repair->output, "Repaired mesh")->required();
  r->add_option("--weld-tolerance", repair->weld_tolerance,
                "Merge vertices closer than this, in the mesh's unit (0: identical positions)")
      ->check(kNonNegative)
      ->capture_default_str();
  r->add_flag("--resolve-self-intersections", repair->resolve_self_intersections,
              fmt::format("Then try CGAL's experimental repairs on self-intersecting triangles "
                          "(cap flips, local removal, autorefinement); they may move the surface "
                          "by up to {:g} of the bounding-box diagonal",
                          fabrication::kDefaultSelfIntersectionMaxDeviation));
  r->add_flag("--json", repair->json, "Print one JSON object");
  r->callback([&global, repair, exit_code] { *exit_code = run_repair(global, *repair); });
}

HC_REGISTER_COMMANDS_ORDERED(10, add_mesh_commands);

}  // namespace hc::cli
