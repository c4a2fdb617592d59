// hardcopy simulate SCENE.json: specimen + material + probe + load -> incremental simulation (the
// material may be a composite design file of `hardcopy design composite`).
// hardcopy validate fem: the FEM verification table (patch, cantilever, flat punch, sphere).
#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "command.h"
#include "common/file_io.h"
#include "common/json.h"
#include "common/tet_mesh_io.h"
#include "fabrication/composite/design_file.h"
#include "processing/fem/verification.h"
#include "processing/scene/scene.h"

namespace hc::cli {
namespace {

struct SimulateArgs {
  std::string scene;
  std::string vtu;
  bool json = false;
};

// A probe load past this is not a probe load (the rig's sensor reads 125 N; a press through any
// specimen stays far below): 1e300 N used to run until "unreachable probe".
constexpr double kMaxProbeForceN = 1e6;

// Whether `p` lies on the triangle (a, b, c), within `tol` (a length).
bool on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                 const Eigen::Vector3d& c, double tol) {
  const Eigen::Vector3d n = (b - a).cross(c - a);
  const double area2 = n.norm();
  if (!(area2 > 0) || std::abs(n.dot(p - a)) > tol * area2) return false;
  // Barycentric coordinates from the sub-triangle areas (signed along n).
  const double u = n.dot((b - p).cross(c - p)) / (area2 * area2);
  const double v = n.dot((c - p).cross(a - p)) / (area2 * area2);
  const double rel = tol / std::sqrt(area2);
  return u >= -rel && v >= -rel && 1 - u - v >= -rel;
}

// A tet that holds `p` in its interior or on a face shared with another tet, or -1: a probe whose
// reference point is there starts inside the specimen. On the boundary surface is touching, not
// inside (a flat probe at contact).
Eigen::Index tet_containing(const TetMesh& mesh, const Eigen::Vector3d& p) {
  static constexpr int kFaces[4][3] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};
  const double tol =
      1e-9 * (mesh.nodes.colwise().maxCoeff() - mesh.nodes.colwise().minCoeff()).norm();
  Eigen::Index hit = -1;
  for (Eigen::Index t = 0; t < mesh.num_tets() && hit < 0; ++t) {
    const Eigen::Vector3d a = mesh.nodes.row(mesh.tets(t, 0)).transpose();
    Eigen::Matrix3d m;
    for (int k = 0; k < 3; ++k) m.col(k) = mesh.nodes.row(mesh.tets(t, k + 1)).transpose() - a;
    if (!(std::abs(m.determinant()) > 0)) continue;
    const Eigen::Vector3d l = m.inverse() * (p - a);
    constexpr double kEps = 1e-9;
    if (l.minCoeff() >= -kEps && l.sum() <= 1 + kEps) hit = t;
  }
  if (hit < 0) return -1;
  std::map<std::array<int, 3>, int> faces;  // boundary faces: used by one tet
  for (Eigen::Index t = 0; t < mesh.num_tets(); ++t)
    for (const auto& f : kFaces) {
      std::array<int, 3> key = {mesh.tets(t, f[0]), mesh.tets(t, f[1]), mesh.tets(t, f[2])};
      std::sort(key.begin(), key.end());
      ++faces[key];
    }
  for (const auto& [f, uses] : faces) {
    if (uses != 1) continue;
    if (on_triangle(p, mesh.nodes.row(f[0]).transpose(), mesh.nodes.row(f[1]).transpose(),
                    mesh.nodes.row(f[2]).transpose(), tol))
      return -1;
  }
  return hit;
}

// Non-finite numbers in a result mean the solve broke down (no equilibrium), never an answer.
Status check_finite(const scene::SimulationResult& r) {
  bool finite = std::isfinite(r.force_n) && std::isfinite(r.depth_m) &&
                std::isfinite(r.max_displacement_m) && r.positions.allFinite();
  for (const auto& s : r.steps)
    finite = finite && std::isfinite(s.force_n) && std::isfinite(s.depth_m);
  if (finite) return {};
  return failed_precondition(fmt::format(
      "the simulation gave non-finite values (force {} N, depth {} m, max displacement {} m): no "
      "equilibrium was found",
      r.force_n, r.depth_m, r.max_displacement_m));
}

int run_simulate(const GlobalOptions& global, const SimulateArgs& args) {
  Context ctx(global);
  Result<scene::Scene> sc = scene::read_scene(args.scene);
  if (!sc.ok()) return ctx.fail("simulate", sc.status());
  if (sc->load.control == fem::LoadControl::kForce && sc->load.value > kMaxProbeForceN)
    return ctx.fail("simulate", invalid_argument(fmt::format(
                                    "{}: load.force_n {:g} N is not a probe load (at most {:g} N)",
                                    args.scene, sc->load.value, kMaxProbeForceN)));
  // A composite design (fabrication/composite) is a material file too.
  scene::MaterialLoader loader;
  if (sc->material.kind == scene::MaterialKind::kFile) {
    Result<std::string> text = read_file(sc->material.file);
    if (text.ok() && composite::is_design_document(*text)) {
      loader = [](const std::filesystem::path& file,
                  const TetMesh& mesh) -> Result<std::unique_ptr<fem::MaterialModel>> {
        HC_ASSIGN_OR_RETURN(const composite::DesignFile d, composite::read_design(file));
        return composite::design_material(d, mesh);
      };
    }
  }
  Result<scene::SimulationResult> r = scene::simulate(*sc, ctx.progress(), loader);
  if (!r.ok()) return ctx.fail("simulate", r.status().with_context(args.scene));
  if (sc->probe.shape != scene::ProbeSpec::Shape::kMesh) {
    const Eigen::Index t = tet_containing(r->mesh, sc->probe.position_m);
    if (t >= 0)
      return ctx.fail(
          "simulate",
          invalid_argument(fmt::format(
              "{}: probe.position_m ({:g}, {:g}, {:g}) is inside the specimen (tet {}): the probe "
              "starts outside, touching or above the surface",
              args.scene, sc->probe.position_m.x(), sc->probe.position_m.y(),
              sc->probe.position_m.z(), t)));
  }
  if (Status s = check_finite(*r); !s.ok()) return ctx.fail("simulate", s.with_context(args.scene));
  if (!args.vtu.empty()) {
    VtuData data;
    data.positions = r->positions;
    const MatrixX3d u = r->positions - r->mesh.nodes;
    data.point_data.push_back(
        {"displacement_m", 3, std::vector<double>(u.data(), u.data() + u.size())});
    if (Status s = write_vtu(args.vtu, r->mesh, data); !s.ok()) return ctx.fail("simulate", s);
  }
  for (const std::string& w : r->warnings) fmt::print(stderr, "simulate: warning: {}\n", w);
  if (args.json) {
    Json steps = Json::array();
    for (const auto& s : r->steps)
      steps.push_back(
          {{"depth_m", s.depth_m}, {"force_n", s.force_n}, {"iterations", s.iterations}});
    const scene::MeshReport& m = r->mesh_report;
    Json mesh{{"method", m.method},         {"nodes", m.nodes},           {"tets", m.tets},
              {"min_edge_m", m.min_edge_m}, {"max_edge_m", m.max_edge_m}, {"time_s", m.time_s}};
    if (m.method == "contact_adaptive") {
      mesh["focus_m"] = {m.focus_m.x(), m.focus_m.y(), m.focus_m.z()};
      mesh["patch_radius_m"] = m.patch_radius_m;
      mesh["fine_size_m"] = m.fine_size_m;
      mesh["coarse_size_m"] = m.coarse_size_m;
      mesh["growth"] = m.growth;
      mesh["elements_per_radius"] = m.elements_per_radius;
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
           {"warnings", r->warnings},
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
      "when no equilibrium is found (also a probe that never reaches the specimen), 2 on bad input "
      "(missing keys, NaN, out-of-range values, inverted or degenerate elements, a probe that "
      "starts inside the specimen).");
  s->add_option("SCENE", sargs->scene, "Scene JSON file")->required();
  s->add_flag("--json", sargs->json,
              "Print one JSON object: force_n, depth_m, max_displacement_m, steps (force and "
              "iterations per load step), nodes, tets, mesh (how the specimen was meshed), "
              "warnings, time_s");
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
