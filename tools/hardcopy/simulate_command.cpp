// hardcopy simulate SCENE.json: specimen + material + probe + load -> incremental simulation.
// hardcopy validate fem: the FEM verification table (patch, cantilever, flat punch, sphere).
#include <fmt/format.h>

#include <filesystem>
#include <string>
#include <vector>

#include "command.h"
#include "common/json.h"
#include "common/tet_mesh_io.h"
#include "processing/fem/verification.h"
#include "processing/scene/scene.h"

namespace hc::cli {
namespace {

struct SimulateArgs {
  std::string scene;
  std::string vtu;
  bool json = false;
};

int run_simulate(const GlobalOptions& global, const SimulateArgs& args) {
  Context ctx(global);
  Result<scene::Scene> sc = scene::read_scene(args.scene);
  if (!sc.ok()) return ctx.fail("simulate", sc.status());
  Result<scene::SimulationResult> r = scene::simulate(*sc, ctx.progress());
  if (!r.ok()) return ctx.fail("simulate", r.status().with_context(args.scene));
  if (!args.vtu.empty()) {
    VtuData data;
    data.positions = r->positions;
    const MatrixX3d u = r->positions - r->mesh.nodes;
    data.point_data.push_back(
        {"displacement_m", 3, std::vector<double>(u.data(), u.data() + u.size())});
    if (Status s = write_vtu(args.vtu, r->mesh, data); !s.ok()) return ctx.fail("simulate", s);
  }
  if (args.json) {
    Json steps = Json::array();
    for (const auto& s : r->steps)
      steps.push_back({{"depth_m", s.depth_m}, {"force_n", s.force_n}});
    const scene::MeshReport& m = r->mesh_report;
    Json mesh{{"method", m.method},           {"nodes", m.nodes},
              {"tets", m.tets},               {"min_edge_m", m.min_edge_m},
              {"max_edge_m", m.max_edge_m},   {"time_s", m.time_s}};
    if (m.method == "contact_adaptive") {
      mesh["focus_m"] = {m.focus_m.x(), m.focus_m.y(), m.focus_m.z()};
      mesh["patch_radius_m"] = m.patch_radius_m;
      mesh["fine_size_m"] = m.fine_size_m;
      mesh["coarse_size_m"] = m.coarse_size_m;
      mesh["growth"] = m.growth;
    }
    Json j{{"scene", args.scene},
           {"model", r->model},
           {"force_n", r->force_n},
           {"depth_m", r->depth_m},
           {"max_displacement_m", r->max_displacement_m},
           {"steps", steps},
           {"nodes", r->mesh.num_nodes()},
           {"tets", r->mesh.num_tets()},
           {"mesh", mesh},
           {"time_s", r->time_s}};
    if (!args.vtu.empty()) j["vtu"] = args.vtu;
    if (Status s = print_json(j); !s.ok()) return ctx.fail("simulate", s);
  } else {
    fmt::print("{}: {} model, {} nodes, {} tets ({} mesh, edges {:.3g} to {:.3g} m)\n", args.scene,
               r->model, r->mesh.num_nodes(), r->mesh.num_tets(), r->mesh_report.method,
               r->mesh_report.min_edge_m, r->mesh_report.max_edge_m);
    for (size_t k = 0; k < r->steps.size(); ++k) {
      fmt::print("  step {:3d}: depth {:.6g} m, force {:.6g} N\n", k + 1, r->steps[k].depth_m,
                 r->steps[k].force_n);
    }
    fmt::print("force {:.6g} N at depth {:.6g} m, max displacement {:.6g} m ({:.2f} s)\n",
               r->force_n, r->depth_m, r->max_displacement_m, r->time_s);
  }
  return kExitYes;
}

struct ValidateArgs {
  int level = 4;
  bool json = false;
};

int run_validate_fem(const GlobalOptions& global, const ValidateArgs& args) {
  Context ctx(global);
  if (args.level < 1 || args.level > 6) {
    return ctx.fail("validate fem", invalid_argument("--level must be in [1, 6]"));
  }
  std::vector<Status> errors;
  const std::vector<fem::VerificationCase> table = fem::run_verification(args.level, &errors);
  bool all = errors.empty();
  for (const auto& c : table) all = all && c.pass;
  if (args.json) {
    Json cases = Json::array();
    for (const auto& c : table) {
      cases.push_back({{"name", c.name},
                       {"quantity", c.quantity},
                       {"computed", finite_or_null(c.computed)},
                       {"expected", finite_or_null(c.expected)},
                       {"error_rel", finite_or_null(c.error_rel)},
                       {"tolerance", c.tolerance},
                       {"pass", c.pass},
                       {"source", c.source},
                       {"tets", c.tets},
                       {"time_s", c.time_s}});
    }
    Json errs = Json::array();
    for (const auto& e : errors) errs.push_back(e.to_string());
    Json j{{"level", args.level}, {"pass", all}, {"cases", cases}, {"errors", errs}};
    if (Status s = print_json(j); !s.ok()) return ctx.fail("validate fem", s);
  } else {
    fmt::print("{:<20} {:>14} {:>14} {:>10} {:>8} {:>8} {:>8}  {}\n", "case", "computed",
               "expected", "error", "tol", "tets", "time_s", "result");
    for (const auto& c : table) {
      fmt::print("{:<20} {:>14.6g} {:>14.6g} {:>10.3e} {:>8.2g} {:>8} {:>8.2f}  {}\n", c.name,
                 c.computed, c.expected, c.error_rel, c.tolerance, c.tets, c.time_s,
                 c.pass ? "pass" : "FAIL");
    }
    for (const auto& e : errors) fmt::print("error: {}\n", e.to_string());
  }
  return all ? kExitYes : kExitNo;
}

}  // namespace

void add_simulate_commands(CLI::App& app, const GlobalOptions& global, int* exit_code) {
  auto sargs = std::make_shared<SimulateArgs>();
  CLI::App* s = app.add_subcommand(
      "simulate",
      "Simulate a probe indentation described by SCENE.json (specimen, material, fixed, probe, "
      "load, "
      "steps) with the co-rotational FEM or the neo-Hookean reference model.\nExit 0 on success, 1 "
      "when no equilibrium is found, 2 on bad input (missing keys, NaN, inverted or degenerate "
      "elements, unreachable probe).");
  s->add_option("SCENE", sargs->scene, "Scene JSON file")->required();
  s->add_flag("--json", sargs->json,
              "Print one JSON object: force_n, depth_m, max_displacement_m, steps, nodes, tets, "
              "mesh (how the specimen was meshed), time_s");
  s->add_option("--vtu", sargs->vtu, "Write the deformed mesh with displacements (.vtu)");
  s->callback([&global, sargs, exit_code] { *exit_code = run_simulate(global, *sargs); });

  auto vargs = std::make_shared<ValidateArgs>();
  CLI::App* v = app.add_subcommand("validate", "Built-in verification tables");
  v->require_subcommand(1);
  CLI::App* f = v->add_subcommand(
      "fem",
      "Run the FEM verification table (constant-strain patch test, cantilever vs Timoshenko, flat "
      "punch vs Boussinesq, sphere vs Sneddon/Hertz) and print each case with its error.\nExit 0 "
      "when every case is within tolerance, 1 otherwise.");
  f->add_option("--level", vargs->level, "Mesh refinement level (1 coarse .. 6 fine)")
      ->capture_default_str();
  f->add_flag("--json", vargs->json, "Print one JSON object");
  f->callback([&global, vargs, exit_code] { *exit_code = run_validate_fem(global, *vargs); });
}

HC_REGISTER_COMMANDS_ORDERED(40, add_simulate_commands);

}  // namespace hc::cli
