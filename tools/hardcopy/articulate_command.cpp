// hardcopy articulate CHARACTER --height-mm H [--printer P.yaml] [--joints J.yaml]
//                    [--no-animation] -o OUT.3mf [--stl OUT.stl] [--json]
#include <fmt/format.h>

#include <cmath>
#include <numbers>
#include <string>

#include "command.h"
#include "common/json.h"
#include "common/mesh_io.h"
#include "fabrication/articulation/articulate.h"
#include "fabrication/articulation/skinned_io.h"

namespace hc::cli {
namespace {

using namespace hc::articulation;
constexpr double kMm = 1e-3;
constexpr double kDeg = std::numbers::pi / 180;

struct ArticulateArgs {
  std::string input;
  double height_mm = 0.0;
  std::string printer = "polyjet";
  std::string joints;
  bool no_animation = false;
  bool no_verify = false;
  bool force_wrap = false;
  bool strict = false;
  std::string output;
  std::string stl;
  bool json = false;
};

// Model frame (m, +Y up) -> print frame (mm, +Z up).
Eigen::Vector3d to_print(const Eigen::Vector3d& p) {
  return Eigen::Vector3d(p.x(), -p.z(), p.y()) / kMm;
}

TriangleMesh print_mesh(const TriangleMesh& m) {
  TriangleMesh out = m;
  for (Eigen::Index v = 0; v < m.num_vertices(); ++v)
    out.vertices.row(v) = to_print(m.vertices.row(v).transpose()).transpose();
  return out;
}

Json joint_json(const Joint& j) {
  const Eigen::Vector3d axis_print = to_print(j.a) * kMm;
  Json out{{"links", {j.parent_name, j.child_name}},
           {"type", to_string(j.type)},
           {"source", to_string(j.source)},
           {"excluded", j.excluded},
           {"centre_mm", eigen_to_json(to_print(j.centre))},
           {"axis", eigen_to_json(axis_print)},
           {"normal", eigen_to_json(Eigen::Vector3d(to_print(j.n) * kMm))},
           {"r_max_mm", j.r_max / kMm},
           {"r_max_initial_mm", j.r_max_initial / kMm},
           {"min_area_mm2", j.min_area / (kMm * kMm)},
           {"tree_edge", j.tree_edge}};
  if (j.excluded) out["reason"] = j.reason;
  if (j.type == JointType::kHinge) {
    out["swing_deg"] = {j.swing.forward / kDeg, j.swing.backward / kDeg};
    if (j.hinge.feasible)
      out["design_mm"] = {{"R", j.hinge.R / kMm}, {"r", j.hinge.r / kMm}, {"b", j.hinge.b / kMm}};
  } else {
    out["cone_deg"] = {j.cone.phi_f / kDeg, j.cone.phi_a / kDeg};
    if (j.ball.feasible)
      out["design_mm"] = {{"r", j.ball.r / kMm},
                          {"h", j.ball.h / kMm},
                          {"ball_radius", j.ball.ball_radius / kMm},
                          {"opening_radius", j.ball.opening_radius / kMm}};
  }
  if (j.centre_from_rig_m >= 0) out["centre_from_rig_mm"] = j.centre_from_rig_m / kMm;
  if (j.motion) {
    const MotionEstimate& e = *j.motion;
    out["motion"] = {
        {"clips", e.clips},
        {"frames", e.frames},
        {"max_angle_deg", e.max_angle_rad / kDeg},
        {"centre_moved_mm",
         j.motion_centre_shift_m >= 0 ? Json(j.motion_centre_shift_m / kMm) : Json(nullptr)},
        {"centre_rms_mm", e.centre_rms_m / kMm}};
  }
  if (!j.notes.empty()) out["notes"] = j.notes;
  return out;
}

Json result_json(const ArticulateArgs& args, const ArticulateResult& r) {
  Json joints = Json::array();
  for (const Joint& j : r.joints) joints.push_back(joint_json(j));
  Json stages = Json::object();
  for (const StageTime& s : r.stages) stages[s.stage] = s.seconds;
  const VerificationReport& v = r.verification;
  Json replay = Json::array();
  for (const ClipReplay& c : v.clips)
    replay.push_back({{"clip", c.clip},
                      {"frames", c.frames},
                      {"collision_free", c.collision_free},
                      {"share", c.share},
                      {"colliding_pairs", c.colliding_pairs}});
  Json narrowed = Json::array();
  for (const RangeNarrowing& n : v.narrowed) {
    const Joint& j = r.joints[static_cast<std::size_t>(n.joint)];
    narrowed.push_back({{"links", {j.parent_name, j.child_name}},
                        {"factor", n.factor},
                        {"by_sweep", n.by_sweep},
                        {"by_replay", n.by_replay}});
  }
  return Json{{"input", args.input},
              {"output", args.output},
              {"joints", joints},
              {"accepted", r.accepted()},
              {"parts", r.parts.size()},
              {"cavities", r.carving.cavities},
              {"debris",
               {{"pieces", r.carving.debris_pieces},
                {"volume_mm3", r.carving.debris_volume_m3 / (kMm * kMm * kMm)}}},
              {"collisions_resolved", r.collisions.collisions_resolved},
              {"collisions_initial", r.collisions.initial_collisions},
              {"fabrication_mesh",
               {{"method", r.fabrication.method},
                {"why_wrapped", r.fabrication.why_wrapped},
                {"triangles", r.fabrication.triangles},
                {"components", r.fabrication.input_components}}},
              {"verification",
               {{"ok", v.ok},
                {"parts_valid", v.parts_valid},
                {"min_part_distance_mm",
                 v.min_part_distance_m >= 0 ? Json(v.min_part_distance_m / kMm) : Json(nullptr)},
                {"replay_share", v.replay_share},
                {"replay_share_before_narrowing", v.replay_share_before_narrowing},
                {"narrowed", narrowed},
                {"clips", replay},
                {"problems", v.problems}}},
              {"stage_s", stages},
              {"time_s", r.time_s}};
}

void print_text(const ArticulateArgs& args, const ArticulateResult& r) {
  fmt::print("{}: fabrication mesh by {} ({} triangles){}\n", args.input, r.fabrication.method,
             r.fabrication.triangles,
             r.fabrication.why_wrapped.empty() ? "" : " because " + r.fabrication.why_wrapped);
  for (const Joint& j : r.joints) {
    if (j.excluded) {
      fmt::print("  {} -> {}: excluded: {}\n", j.parent_name, j.child_name, j.reason);
      continue;
    }
    fmt::print("  {} -> {}: {} ({}), r_max {:.2f} mm, smallest section {:.1f} mm^2\n",
               j.parent_name, j.child_name, to_string(j.type), to_string(j.source), j.r_max / kMm,
               j.min_area / (kMm * kMm));
    for (const std::string& note : j.notes) fmt::print("    {}\n", note);
  }
  fmt::print("{} joints, {} parts, {} collisions resolved, {:.1f} s\n", r.accepted(),
             r.parts.size(), r.collisions.collisions_resolved, r.time_s);
  if (r.carving.debris_pieces > 0)
    fmt::print("  dropped {} loose crumb(s) the cuts pinched off ({:.3f} mm^3 in all)\n",
               r.carving.debris_pieces, r.carving.debris_volume_m3 / (kMm * kMm * kMm));
  for (const std::string& p : r.verification.problems) fmt::print("  check: {}\n", p);
}

int run_articulate(const GlobalOptions& global, const ArticulateArgs& args) {
  Context ctx(global);
  ArticulateOptions options;
  if (args.printer == "polyjet" || args.printer == "sla" || args.printer == "fdm") {
    Result<PrinterProfile> p = builtin_printer_profile(args.printer);
    if (!p.ok()) return ctx.fail("articulate", p.status());
    options.printer = *p;
  } else {
    Result<PrinterProfile> p = load_printer_profile(args.printer);
    if (!p.ok()) return ctx.fail("articulate", p.status());
    options.printer = *p;
  }
  if (!args.joints.empty()) {
    Result<JointOverrides> j = load_joint_overrides(args.joints);
    if (!j.ok()) return ctx.fail("articulate", j.status());
    options.overrides = *j;
  }
  if (Result<MeshFormat> f = mesh_format_from_path(args.output); !f.ok() || *f != MeshFormat::k3mf)
    return ctx.fail("articulate", invalid_argument("-o: expected a .3mf file, got " + args.output));
  SkinnedReadOptions read;
  read.target_height_m = args.height_mm * kMm;
  read.read_animations = !args.no_animation;
  Result<SkinnedCharacter> character = read_skinned_character(args.input, read);
  if (!character.ok()) return ctx.fail("articulate", character.status());
  options.use_animation = !args.no_animation;
  options.verify = !args.no_verify;
  options.force_wrap = args.force_wrap;
  options.progress = ctx.progress();
  Result<ArticulateResult> r = articulate(*character, options);
  if (!r.ok()) return ctx.fail("articulate", r.status().with_context(args.input));
  const bool posable = r->accepted() > 0;
  if (posable) {
    std::vector<MeshPart> parts;
    std::vector<TriangleMesh> meshes;
    for (const CarvedPart& p : r->parts) {
      parts.push_back({p.name, print_mesh(p.mesh), "", std::nullopt});
      meshes.push_back(parts.back().mesh);
    }
    if (Status s = write_3mf(args.output, parts); !s.ok()) return ctx.fail("articulate", s);
    if (!args.stl.empty())
      if (Status s = write_mesh(args.stl, concatenated(meshes)); !s.ok())
        return ctx.fail("articulate", s);
  }
  if (args.json)
    (void)print_json(result_json(args, *r));
  else
    print_text(args, *r);
  if (!posable) {
    fmt::print(stderr, "hardcopy articulate: no joint survived; nothing written\n");
    return kExitNo;
  }
  if (options.verify && !r->verification.ok) {
    fmt::print(stderr,
               "hardcopy articulate: {} check(s) of the carved parts failed (listed under "
               "\"verification\"); the parts were written{}\n",
               r->verification.problems.size(), args.strict ? " (--strict: exit 1)" : "");
    if (args.strict) return kExitNo;
  }
  return kExitYes;
}

}  // namespace

void add_articulate_commands(CLI::App& app, const GlobalOptions& global, int* exit_code) {
  auto args = std::make_shared<ArticulateArgs>();
  CLI::App* c = app.add_subcommand(
      "articulate",
      "Skinned character (glTF/GLB, FBX, COLLADA, .x) -> posable articulated model printed in one "
      "piece (thesis Ch. 6): joints from the skin and the clips, carved into interlocked parts.\n"
      "Exit 0 when joints were made and the parts written (a failed check of the parts is "
      "reported, and exits 1 with --strict), 1 when no joint survives (nothing written), 2 on "
      "unreadable input.");
  c->add_option("CHARACTER", args->input, "Skinned character file")->required();
  c->add_option("--height-mm", args->height_mm, "Printed height (rest pose, along +Y)")
      ->required()
      ->check(kPositive);
  c->add_option("--printer", args->printer, "Printer profile: polyjet, sla, fdm, or a YAML file")
      ->capture_default_str();
  c->add_option("--joints", args->joints, "Per-joint overrides (YAML: type, frame angle, ranges)");
  c->add_flag("--no-animation", args->no_animation,
              "Ignore the clips (default ball joints unless overridden)");
  c->add_flag("--no-verify", args->no_verify, "Skip the checks of the carved parts");
  c->add_flag("--wrap", args->force_wrap, "Alpha-wrap the character even when a union works");
  c->add_flag("--strict", args->strict, "Exit 1 when a check of the carved parts fails");
  c->add_option("-o,--output", args->output, "Output 3MF (one object per part, mm)")->required();
  c->add_option("--stl", args->stl, "Also write all parts into one STL (mm)");
  c->add_flag("--json", args->json, "Print one JSON object");
  c->callback([&global, args, exit_code] { *exit_code = run_articulate(global, *args); });
}

HC_REGISTER_COMMANDS_ORDERED(60, add_articulate_commands);

}  // namespace hc::cli
