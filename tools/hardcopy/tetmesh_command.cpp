// hardcopy tetmesh: closed surface mesh or TetGen .poly → tetrahedra (.node/.ele/.vtu).
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <string>

#include "command.h"
#include "common/file_io.h"
#include "common/json.h"
#include "common/mesh_io.h"
#include "common/tet_mesh_io.h"
#include "fabrication/printability/mesh_check.h"
#include "processing/meshing/tetrahedralize.h"

namespace hc::cli {
namespace {

struct TetmeshArgs {
  std::string input;
  std::string output;
  double quality = 2.0;
  double max_volume_m3 = 0;
  double scale_to_m = 1.0;
  long max_tets = 5'000'000;
  // Structured box specimen instead of IN: size (m), hexahedral cells per axis, min corner (m).
  std::vector<double> box_m;
  std::vector<int> cells;
  std::vector<double> origin_m;
  bool json = false;
};

// OUT may be given as BASE or BASE.node / .ele / .vtu: all three files share BASE.
std::filesystem::path output_base(const std::string& out) {
  std::filesystem::path p(out);
  const std::string ext = p.extension().string();
  if (ext == ".node" || ext == ".ele" || ext == ".vtu") p.replace_extension();
  return p;
}

// --box: a structured specimen (each hexahedral cell split into 6 tets), e.g. a tracking template
// whose top nodes lie on the painted 3 mm marker grid. Fills the summary as TetGen would.
Result<TetMesh> box_input(const TetmeshArgs& args, meshing::TetrahedralizeSummary* summary) {
  if (args.box_m.size() != 3 || args.cells.size() != 3 ||
      (!args.origin_m.empty() && args.origin_m.size() != 3))
    return invalid_argument("--box, --cells and --origin take three values each");
  for (int i = 0; i < 3; ++i)
    if (!(std::isfinite(args.box_m[i]) && args.box_m[i] > 0) || args.cells[i] < 1 ||
        args.cells[i] > 1000)
      return invalid_argument("--box sizes must be positive and --cells between 1 and 1000");
  HC_ASSIGN_OR_RETURN(
      TetMesh mesh,
      meshing::structured_box(Eigen::Vector3d(args.box_m[0], args.box_m[1], args.box_m[2]),
                              Eigen::Vector3i(args.cells[0], args.cells[1], args.cells[2])));
  if (!args.origin_m.empty()) {
    const Eigen::RowVector3d o(args.origin_m[0], args.origin_m[1], args.origin_m[2]);
    if (!o.allFinite()) return invalid_argument("--origin must be finite");
    mesh.nodes.rowwise() += o;
  }
  summary->volume = args.box_m[0] * args.box_m[1] * args.box_m[2];
  summary->min_tet_volume = summary->max_tet_volume =
      summary->volume / (6.0 * args.cells[0] * args.cells[1] * args.cells[2]);
  summary->boundary_faces = 4 * (Eigen::Index{args.cells[0]} * args.cells[1] +
                                 Eigen::Index{args.cells[1]} * args.cells[2] +
                                 Eigen::Index{args.cells[0]} * args.cells[2]);
  summary->switches = "";  // not TetGen
  return mesh;
}

// Points TetGen may add for --max-tets tets. Its meshes have 3.4-3.5 tets per node (measured on
// pinion.off: 15,407 / 4,424 at the default quality, 276,453 / 56,733 at -q1.1), so a budget of
// max_tets / 5 points keeps the element count under the limit whatever -q and -a ask.
constexpr double kTetsPerNode = 5.0;
long steiner_budget(long max_tets) {
  return std::max<long>(1, static_cast<long>(static_cast<double>(max_tets) / kTetsPerNode));
}

// TetGen's -a mesh of a volume V has about kTetsPerVolumeBound * V / a tets once the volume bound
// dominates (measured on pinion.off: 4.1 at a = 1e-4, V / a = 8.2e3; 20.7 at a = 1e-3 where the
// surface refinement dominates); refuse up front what would exceed --max-tets instead of meshing
// for minutes to find out.
constexpr double kTetsPerVolumeBound = 6.0;
Status check_tet_estimate(const TetmeshArgs& args, double volume_m3) {
  if (!(args.max_volume_m3 > 0) || !(volume_m3 > 0)) return {};
  const double estimate = kTetsPerVolumeBound * volume_m3 / args.max_volume_m3;
  if (estimate <= static_cast<double>(args.max_tets)) return {};
  return invalid_argument(fmt::format(
      "--max-volume {:g} m^3 would make about {:.3g} tets of this {:.4g} m^3 volume, more than "
      "--max-tets {}; use --max-volume {:.3g} or more (or raise --max-tets)",
      args.max_volume_m3, estimate, volume_m3, args.max_tets,
      kTetsPerVolumeBound * volume_m3 / static_cast<double>(args.max_tets)));
}

Result<TetMesh> mesh_input(const TetmeshArgs& args, meshing::TetrahedralizeSummary* summary) {
  if (!args.box_m.empty()) {
    if (!args.input.empty()) return invalid_argument("give either IN or --box, not both");
    return box_input(args, summary);
  }
  if (args.input.empty()) return invalid_argument("give a surface mesh IN or --box");
  if (!args.cells.empty() || !args.origin_m.empty())
    return invalid_argument("--cells and --origin go with --box");
  meshing::TetrahedralizeOptions options;
  options.max_radius_edge_ratio = args.quality;
  options.max_volume = args.max_volume_m3;
  options.max_steiner_points = steiner_budget(args.max_tets);
  HC_RETURN_IF_ERROR(options.validate());
  if (std::filesystem::path(args.input).extension() == ".poly") {
    HC_ASSIGN_OR_RETURN(meshing::Plc plc, meshing::read_poly(args.input));
    plc.points *= args.scale_to_m;
    if (plc.points.rows() > 0) {  // the bounding box bounds the volume
      const Eigen::RowVector3d extent =
          plc.points.colwise().maxCoeff() - plc.points.colwise().minCoeff();
      HC_RETURN_IF_ERROR(check_tet_estimate(args, extent.prod()));
    }
    for (auto& f : plc.facets)
      for (auto& h : f.holes) h *= args.scale_to_m;
    for (auto& h : plc.holes) h *= args.scale_to_m;
    for (auto& r : plc.regions) {
      r.seed *= args.scale_to_m;
      r.max_volume *= args.scale_to_m * args.scale_to_m * args.scale_to_m;
    }
    Result<TetMesh> m = meshing::tetrahedralize(plc, options, summary, !plc.regions.empty());
    if (!m.ok()) return m.status().with_context(args.input);
    return m;
  }
  HC_ASSIGN_OR_RETURN(TriangleMesh surface, read_mesh(args.input));
  // The enclosed volume, for the tet-count estimate (meshing::tetrahedralize refuses a
  // self-intersecting surface itself).
  fabrication::MeshCheckOptions check;
  check.check_self_intersections = false;
  HC_ASSIGN_OR_RETURN(const fabrication::MeshCheckReport report,
                      fabrication::check_mesh(surface, check));
  surface.vertices *= args.scale_to_m;
  HC_RETURN_IF_ERROR(check_tet_estimate(
      args, std::abs(report.volume) * args.scale_to_m * args.scale_to_m * args.scale_to_m));
  Result<TetMesh> m = meshing::tetrahedralize(surface, options, summary);
  if (!m.ok()) return m.status().with_context(args.input);
  return m;
}

int run_tetmesh(const GlobalOptions& global, const TetmeshArgs& args) {
  Context ctx(global);
  if (!(std::isfinite(args.scale_to_m) && args.scale_to_m > 0))
    return ctx.fail("tetmesh",
                    invalid_argument(fmt::format("--scale-to-m {} must be positive and finite",
                                                 args.scale_to_m)));
  const auto start = std::chrono::steady_clock::now();
  meshing::TetrahedralizeSummary summary;
  Result<TetMesh> mesh = mesh_input(args, &summary);
  if (!mesh.ok()) return ctx.fail("tetmesh", mesh.status());
  const long budget = steiner_budget(args.max_tets);
  if (!summary.switches.empty() && summary.nodes - summary.input_vertices >= budget)
    return ctx.fail("tetmesh",
                    invalid_argument(fmt::format(
                        "TetGen used all {} points that --max-tets {} allows without meeting "
                        "--quality {} / --max-volume {}: loosen them or raise --max-tets",
                        budget, args.max_tets, args.quality, args.max_volume_m3)));
  const std::filesystem::path base = output_base(args.output);
  // The three files appear together or not at all (a failed or killed run leaves no .node/.ele
  // without their .vtu; leftovers of a killed run are removed by the next).
  AtomicFileGroup out(base, {".node", ".ele", ".vtu"});
  if (Status s = write_tetgen(out.staged_base(), *mesh); !s.ok()) return ctx.fail("tetmesh", s);
  if (Status s = write_vtu(out.staged(2), *mesh); !s.ok()) return ctx.fail("tetmesh", s);
  if (Status s = out.commit(); !s.ok()) return ctx.fail("tetmesh", s);
  const std::filesystem::path vtu(base.string() + ".vtu");
  const double time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (args.json) {
    Json j{{"input", args.input.empty() ? std::string("box") : args.input},
           {"node", base.string() + ".node"},
           {"ele", base.string() + ".ele"},
           {"vtu", vtu.string()},
           {"nodes", mesh->num_nodes()},
           {"tets", mesh->num_tets()},
           {"boundary_faces", summary.boundary_faces},
           {"volume_m3", summary.volume},
           {"min_tet_volume_m3", summary.min_tet_volume},
           {"max_tet_volume_m3", summary.max_tet_volume},
           {"tetgen_switches", summary.switches},
           {"time_s", time_s}};
    if (Status s = print_json(j); !s.ok()) return ctx.fail("tetmesh", s);
  } else {
    fmt::print(
        "{} -> {}.{{node,ele,vtu}}: {} nodes, {} tets, volume {:.6g} m^3 ({})\n",
        args.input.empty() ? std::string("structured box") : args.input, base.string(),
        mesh->num_nodes(), mesh->num_tets(), summary.volume,
        summary.switches.empty() ? std::string("6 tets per cell") : "TetGen -" + summary.switches);
  }
  return kExitYes;
}

}  // namespace

void add_tetmesh_commands(CLI::App& app, const GlobalOptions& global, int* exit_code) {
  auto args = std::make_shared<TetmeshArgs>();
  CLI::App* c = app.add_subcommand(
      "tetmesh",
      "Tetrahedralize a closed surface mesh (.obj .stl .ply .off) or a TetGen .poly with TetGen; "
      "writes OUT.node, OUT.ele (TetGen) and OUT.vtu (ParaView).\nExit 0 on success, 2 on "
      "unreadable input, a surface TetGen rejects or bad options.");
  c->add_option("IN", args->input, "Closed surface mesh or .poly file (or use --box)");
  c->add_option("-o,--output", args->output, "Output base name (OUT.node, OUT.ele, OUT.vtu)")
      ->required();
  c->add_option("--quality", args->quality,
                "Maximum radius-edge ratio of the tets (TetGen -q; >= 1.1, 0 = no refinement)")
      ->capture_default_str();
  c->add_option("--max-volume", args->max_volume_m3,
                "Maximum tet volume in m^3, after scaling (TetGen -a; 0 = none)")
      ->check(kNonNegative)
      ->capture_default_str();
  c->add_option("--max-tets", args->max_tets,
                "Refuse (exit 2) a mesh of more tets: checked up front from the volume and "
                "--max-volume, and TetGen may add at most max-tets/5 points")
      ->check(CLI::Range(1L, 500'000'000L))
      ->capture_default_str();
  c->add_option("--scale-to-m", args->scale_to_m,
                "Multiply input coordinates by this to get metres (0.001 for a mesh in mm)")
      ->capture_default_str();
  c->add_option("--box", args->box_m,
                "Instead of IN: a structured box specimen of this size X Y Z (m)")
      ->expected(3);
  c->add_option("--cells", args->cells, "With --box: hexahedral cells per axis NX NY NZ")
      ->expected(3);
  c->add_option("--origin", args->origin_m, "With --box: its minimum corner X Y Z (m)")
      ->expected(3);
  c->add_flag("--json", args->json, "Print one JSON object");
  c->callback([&global, args, exit_code] { *exit_code = run_tetmesh(global, *args); });
}

HC_REGISTER_COMMANDS_ORDERED(30, add_tetmesh_commands);

}  // namespace hc::cli
