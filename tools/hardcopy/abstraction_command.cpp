// hardcopy abstract | engrave | offset | boolean | calibration-part (thesis Ch. 7). Inputs ending
// in .svg are 2-D outlines and give 2-D outputs; anything else is a surface mesh.
#include <fmt/format.h>

#include <chrono>
#include <filesystem>
#include <string>

#include "command.h"
#include "common/json.h"
#include "common/mesh_io.h"
#include "fabrication/abstraction/abstraction.h"
#include "fabrication/abstraction/calibration_part.h"
#include "fabrication/abstraction/fidelity.h"
#include "fabrication/abstraction/svg.h"
#include "fabrication/printability/mesh_check.h"
#include "fabrication/printability/mesh_repair.h"

namespace hc::cli {
namespace {

using namespace hc::abstraction;  // NOLINT(google-build-using-namespace): one library per file

bool is_svg(const std::string& path) { return std::filesystem::path(path).extension() == ".svg"; }

struct ScaleArgs {
  double height_mm = 0.0;  // scale so the model is this tall (z; y for SVG)
  double scale = 0.0;      // or multiply coordinates by this (mm per model unit)
};

Result<double> scale_factor(const ScaleArgs& s, double height) {
  if (s.height_mm > 0 && s.scale > 0)
    return invalid_argument("--height-mm and --scale exclude each other");
  if (s.height_mm > 0) {
    if (!(height > 0)) return invalid_argument("--height-mm: the model has no height");
    return s.height_mm / height;
  }
  return s.scale > 0 ? s.scale : 1.0;
}

// A closed, printable mesh (repaired if needed) in millimetres.
Result<TriangleMesh> load_mesh(const std::string& path, const ScaleArgs& s) {
  HC_ASSIGN_OR_RETURN(TriangleMesh mesh, read_mesh(path));
  fabrication::MeshRepairOptions ro;
  fabrication::MeshRepairSummary rs;
  HC_RETURN_IF_ERROR(fabrication::repair_mesh(ro, &mesh, &rs).with_context(path));
  if (!rs.printable) {
    std::string why;
    for (const auto& p : rs.after.problems) why += (why.empty() ? "" : "; ") + p;
    return invalid_argument(fmt::format(
        "{}: not a closed, self-intersection-free solid even after repair ({}); run `hardcopy "
        "mesh repair --resolve-self-intersections` or fix the model",
        path, why));
  }
  const auto box = rs.after.bounding_box;
  HC_ASSIGN_OR_RETURN(double f, scale_factor(s, box.sizes().z()));
  mesh.vertices *= f;
  return mesh;
}

Result<Polygon2> load_svg(const std::string& path, const ScaleArgs& s) {
  HC_ASSIGN_OR_RETURN(Polygon2 p, read_svg(path));
  HC_ASSIGN_OR_RETURN(double f, scale_factor(s, p.bounding_box().sizes().y()));
  for (auto& l : p.loops)
    for (auto& q : l) q *= f;
  return p;
}

// 3-D sampling scale: from the feature size when there is one, else from the bounding box.
ShapeOptions shape_options(bool three_d, double feature_mm) {
  ShapeOptions o;
  if (three_d) {
    o.sampling.r_min_fraction = 2e-3;
    o.sampling.r_uniform_fraction = 1e-2;
  }
  if (feature_mm > 0) {
    o.sampling.r_min = feature_mm / 10;
    o.sampling.r_uniform = feature_mm / 4;
  }
  return o;
}

Json summary_json(const OperationSummary& s) {
  return {{"samples", s.samples},
          {"balls", s.balls},
          {"intrusions_closed", s.intrusions_closed},
          {"intrusions_kept", s.intrusions_kept},
          {"time_s", s.time_s},
          {"r_min_mm", s.sampling.r_min}};
}

Json intrusions_json(const std::vector<Intrusion>& v) {
  Json a = Json::array();
  for (const auto& i : v) {
    a.push_back({{"centre_mm", {i.centre.x(), i.centre.y(), i.centre.z()}},
                 {"width_mm", i.width},
                 {"depth_mm", i.depth},
                 {"ratio", i.ratio},
                 {"closed", i.closed},
                 {"medial_part", i.medial_part}});
  }
  return a;
}

// Writes the output, measures it against the input and prints; returns the exit code.
template <class Shape, int D>
int finish(const Context& ctx, std::string_view cmd, const std::string& out, const Shape& input,
           const Shape& result, const OperationSummary& sum,
           const std::vector<Intrusion>& intrusions, const Balls<D>& closed, bool json) {
  Json j = summary_json(sum);
  bool printable = true;
  HausdorffOptions ho;
  ho.margin = 2 * sum.sampling.r_min;
  if constexpr (D == 2) {
    if (Status s = write_svg(out, result); !s.ok()) return ctx.fail(cmd, s);
    auto h = hausdorff_2d(input, result, closed, ho);
    if (!h.ok()) return ctx.fail(cmd, h.status());
    j["hausdorff_mm"] = h->symmetric();
    j["loops"] = result.loops.size();
    printable = validate(result, "result").ok();
  } else {
    auto check = fabrication::check_mesh(result);
    if (!check.ok()) return ctx.fail(cmd, check.status());
    printable = check->printable;
    if (Status s = write_mesh(out, result); !s.ok()) return ctx.fail(cmd, s);
    auto h = hausdorff_3d(input, result, closed, ho);
    if (!h.ok()) return ctx.fail(cmd, h.status());
    j["hausdorff_mm"] = h->symmetric();
    j["triangles"] = result.num_triangles();
    j["genus"] = check->genus ? Json(*check->genus) : Json(nullptr);
  }
  j["printable"] = printable;
  j["output"] = out;
  j["intrusions"] = intrusions_json(intrusions);
  if (cmd == "boolean") j["method"] = sum.exact_fallback ? "corefinement" : "medial_balls";
  if (sum.exact_fallback) {
    j["fallback_reason"] = sum.fallback_reason;
    if (!json)
      fmt::print(stderr, "{}: the medial-ball result was not a valid solid ({}); wrote the exact "
                 "corefinement instead\n", cmd, sum.fallback_reason);
  }
  if (json) {
    (void)print_json(j);
  } else {
    fmt::print(
        "{} -> {}: {} samples, {} balls, {} intrusions closed, Hausdorff {:.4g} mm outside "
        "them, {}, {:.2f} s\n",
        cmd, out, sum.samples, sum.balls, sum.intrusions_closed, j["hausdorff_mm"].get<double>(),
        printable ? "printable" : "NOT printable", sum.time_s);
  }
  return printable ? kExitYes : kExitNo;
}

struct AbstractArgs {
  std::string input, output;
  double feature_mm = 0.0, depth_mm = 0.0, tau = 0.5;
  ScaleArgs scale;
  bool emboss = false, json = false;
};

int run_abstract(const GlobalOptions& global, const AbstractArgs& a, bool engrave) {
  Context ctx(global);
  const std::string_view cmd = engrave ? "engrave" : "abstract";
  if (is_svg(a.input) != is_svg(a.output)) {
    return ctx.fail(cmd, invalid_argument("an .svg input needs an .svg output and the reverse"));
  }
  EngraveOptions eo;
  eo.depth = a.depth_mm;
  eo.emboss = a.emboss;
  eo.abstraction.feature_size = a.feature_mm;
  eo.abstraction.depth_ratio = a.tau;
  eo.abstraction.shape = shape_options(!is_svg(a.input), a.feature_mm);
  if (Status s = engrave ? eo.validate() : eo.abstraction.validate(); !s.ok())
    return ctx.fail(cmd, s);
  if (is_svg(a.input)) {
    auto in = load_svg(a.input, a.scale);
    if (!in.ok()) return ctx.fail(cmd, in.status());
    auto r = engrave ? engrave_2d(*in, eo) : abstract_2d(*in, eo.abstraction);
    if (!r.ok()) return ctx.fail(cmd, r.status().with_context(a.input));
    return finish<Polygon2, 2>(ctx, cmd, a.output, *in, r->shape, r->summary, r->intrusions,
                               r->closed, a.json);
  }
  if (auto f = mesh_format_from_path(a.output); !f.ok()) return ctx.fail(cmd, f.status());
  auto in = load_mesh(a.input, a.scale);
  if (!in.ok()) return ctx.fail(cmd, in.status());
  auto r = engrave ? engrave_3d(*in, eo) : abstract_3d(*in, eo.abstraction);
  if (!r.ok()) return ctx.fail(cmd, r.status().with_context(a.input));
  return finish<TriangleMesh, 3>(ctx, cmd, a.output, *in, r->shape, r->summary, r->intrusions,
                                 r->closed, a.json);
}

struct OffsetArgs {
  std::string input, output;
  double distance_mm = 0.0;
  bool json = false;
};

int run_offset(const GlobalOptions& global, const OffsetArgs& a) {
  Context ctx(global);
  if (is_svg(a.input) != is_svg(a.output)) {
    return ctx.fail("offset",
                    invalid_argument("an .svg input needs an .svg output and the reverse"));
  }
  OperationSummary sum;
  if (is_svg(a.input)) {
    auto in = load_svg(a.input, {});
    if (!in.ok()) return ctx.fail("offset", in.status());
    auto r = offset_2d(*in, a.distance_mm, shape_options(false, 0), &sum);
    if (!r.ok()) return ctx.fail("offset", r.status().with_context(a.input));
    // The offset surface is meant to move: Hausdorff = how far it moved (about |D|).
    return finish<Polygon2, 2>(ctx, "offset", a.output, *in, *r, sum, {}, {}, a.json);
  }
  if (auto f = mesh_format_from_path(a.output); !f.ok()) return ctx.fail("offset", f.status());
  auto in = load_mesh(a.input, {});
  if (!in.ok()) return ctx.fail("offset", in.status());
  auto r = offset_3d(*in, a.distance_mm, shape_options(true, 0), &sum);
  if (!r.ok()) return ctx.fail("offset", r.status().with_context(a.input));
  return finish<TriangleMesh, 3>(ctx, "offset", a.output, *in, *r, sum, {}, {}, a.json);
}

struct BooleanArgs {
  std::string op, a, b, output;
  bool json = false;
};

int run_boolean(const GlobalOptions& global, const BooleanArgs& a) {
  Context ctx(global);
  auto op = parse_boolean_op(a.op);
  if (!op.ok()) return ctx.fail("boolean", op.status());
  if (is_svg(a.a) != is_svg(a.output) || is_svg(a.b) != is_svg(a.output)) {
    return ctx.fail("boolean",
                    invalid_argument("mix of .svg and mesh files; all three must be one kind"));
  }
  OperationSummary sum;
  if (is_svg(a.a)) {
    auto pa = load_svg(a.a, {});
    if (!pa.ok()) return ctx.fail("boolean", pa.status());
    auto pb = load_svg(a.b, {});
    if (!pb.ok()) return ctx.fail("boolean", pb.status());
    auto r = boolean_2d(*pa, *pb, *op, shape_options(false, 0), &sum);
    if (!r.ok()) return ctx.fail("boolean", r.status());
    return finish<Polygon2, 2>(ctx, "boolean", a.output, *pa, *r, sum, {}, {}, a.json);
  }
  if (auto f = mesh_format_from_path(a.output); !f.ok()) return ctx.fail("boolean", f.status());
  auto ma = load_mesh(a.a, {});
  if (!ma.ok()) return ctx.fail("boolean", ma.status());
  auto mb = load_mesh(a.b, {});
  if (!mb.ok()) return ctx.fail("boolean", mb.status());
  auto r = boolean_3d(*ma, *mb, *op, shape_options(true, 0), &sum);
  if (!r.ok()) return ctx.fail("boolean", r.status());
  return finish<TriangleMesh, 3>(ctx, "boolean", a.output, *ma, *r, sum, {}, {}, a.json);
}

struct CalibrationArgs {
  std::string depths, diameters, output;
  bool json = false;
};

int run_calibration(const GlobalOptions& global, const CalibrationArgs& a) {
  Context ctx(global);
  const auto t0 = std::chrono::steady_clock::now();
  CalibrationPartOptions o;
  auto depths = parse_range(a.depths, "--depths-mm");
  if (!depths.ok()) return ctx.fail("calibration-part", depths.status());
  auto diameters = parse_range(a.diameters, "--diameters-mm");
  if (!diameters.ok()) return ctx.fail("calibration-part", diameters.status());
  o.depths = *depths;
  o.diameters = *diameters;
  if (auto f = mesh_format_from_path(a.output); !f.ok())
    return ctx.fail("calibration-part", f.status());
  auto part = calibration_part(o);
  if (!part.ok()) return ctx.fail("calibration-part", part.status());
  auto check = fabrication::check_mesh(part->mesh);
  if (!check.ok()) return ctx.fail("calibration-part", check.status());
  if (Status s = write_mesh(a.output, part->mesh); !s.ok()) return ctx.fail("calibration-part", s);
  const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (a.json) {
    (void)print_json({{"output", a.output},
                      {"size_mm", part->size},
                      {"legend", part->legend},
                      {"triangles", part->mesh.num_triangles()},
                      {"printable", check->printable},
                      {"time_s", t}});
  } else {
    fmt::print("{}: {:.1f} mm cube, {} triangles, {}\n", a.output, part->size,
               part->mesh.num_triangles(), check->printable ? "printable" : "NOT printable");
    for (const auto& l : part->legend) fmt::print("  {}\n", l);
  }
  return check->printable ? kExitYes : kExitNo;
}

void add_scale(CLI::App* c, ScaleArgs* s) {
  c->add_option("--height-mm", s->height_mm, "Scale the model to this height (z; y for SVG), mm")
      ->check(kPositive);
  c->add_option("--scale", s->scale, "Or multiply its coordinates by this (mm per model unit)")
      ->check(kPositive);
}

}  // namespace

void add_abstraction_commands(CLI::App& app, const GlobalOptions& global, int* exit_code) {
  for (const bool engrave : {false, true}) {
    auto args = std::make_shared<AbstractArgs>();
    CLI::App* c = app.add_subcommand(
        engrave ? "engrave" : "abstract",
        engrave
            ? "Close narrow deep intrusions and engrave them by the calibrated depth (thesis 7.5)"
            : "Close intrusions narrower than the feature size and deeper than tau x width (thesis "
              "7.4)");
    c->add_option("IN", args->input, "Mesh (.obj .stl .ply .off) or outline (.svg)")->required();
    c->add_option("-o,--output", args->output, "Output mesh or .svg")->required();
    c->add_option("--feature-mm", args->feature_mm, "Feature size F at print scale, mm")
        ->required()
        ->check(kPositive);
    c->add_option("--tau", args->tau, "Depth/width ratio above which narrow intrusions close (0.5)")
        ->check(kPositive);
    if (engrave) {
      c->add_option("--depth-mm", args->depth_mm,
                    "Engraving depth (the printer's calibrated minimum), mm")
          ->required()
          ->check(kPositive);
      c->add_flag("--emboss", args->emboss, "Raise the closed regions instead of sinking them");
    }
    add_scale(c, &args->scale);
    c->add_flag("--json", args->json, "Print one JSON object");
    c->callback(
        [&global, args, exit_code, engrave] { *exit_code = run_abstract(global, *args, engrave); });
  }
  auto off = std::make_shared<OffsetArgs>();
  CLI::App* o = app.add_subcommand(
      "offset", "Grow (D > 0) or shrink (D < 0) a solid by D on its medial balls (thesis 7.5.1)");
  o->add_option("IN", off->input, "Mesh or .svg")->required();
  o->add_option("-o,--output", off->output, "Output mesh or .svg")->required();
  o->add_option("--distance-mm", off->distance_mm, "Offset distance, mm (negative shrinks)")
      ->required();
  o->add_flag("--json", off->json, "Print one JSON object");
  o->callback([&global, off, exit_code] { *exit_code = run_offset(global, *off); });

  auto bo = std::make_shared<BooleanArgs>();
  CLI::App* b = app.add_subcommand(
      "boolean", "Union, difference or intersection of two solids on medial balls (thesis 7.5.2)");
  b->add_option("OP", bo->op, "union | difference | intersection")->required();
  b->add_option("A", bo->a, "First mesh or .svg")->required();
  b->add_option("B", bo->b, "Second mesh or .svg")->required();
  b->add_option("-o,--output", bo->output, "Output mesh or .svg")->required();
  b->add_flag("--json", bo->json, "Print one JSON object");
  b->callback([&global, bo, exit_code] { *exit_code = run_boolean(global, *bo); });

  auto ca = std::make_shared<CalibrationArgs>();
  CLI::App* k =
      app.add_subcommand("calibration-part", "The engraving-depth calibration part (thesis 7.3)");
  k->add_option("--depths-mm", ca->depths, "Depths: A:B:STEP or a,b,c (mm)")->required();
  k->add_option("--diameters-mm", ca->diameters, "Diameters: A:B:STEP or a,b,c (mm)")->required();
  k->add_option("-o,--output", ca->output, "Output mesh (.stl .obj .ply .off .3mf)")->required();
  k->add_flag("--json", ca->json, "Print one JSON object");
  k->callback([&global, ca, exit_code] { *exit_code = run_calibration(global, *ca); });
}

HC_REGISTER_COMMANDS(add_abstraction_commands);

}  // namespace hc::cli
