#include "processing/scene/scene.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <string>

#include "common/file_io.h"
#include "common/json.h"
#include "common/json_reader.h"
#include "common/mesh_io.h"
#include "processing/fem/corotational.h"
#include "processing/fem/incremental.h"
#include "processing/fem/material_model.h"
#include "processing/fem/probe.h"
#include "processing/hyperelastic/neo_hookean.h"
#include "processing/hyperelastic/reference_indentation.h"
#include "processing/material/material.h"
#include "processing/meshing/tetrahedralize.h"
#include "processing/scene/contact_meshing.h"
#include "processing/scene/reference.h"

namespace hc::scene {

namespace {

// A file path, relative to the scene's folder unless absolute.
Result<std::filesystem::path> path_value(const JsonNode& j, const std::filesystem::path& base) {
  if (!j.json().is_string() || j.json().get<std::string>().empty())
    return j.error("expected a file path, got " + describe_json(j.json()));
  std::filesystem::path p = j.json().get<std::string>();
  if (p.is_relative()) p = base / p;
  return p;
}

// {"youngs_pa": E, "poisson": ν} and, when `stiffening` is given (neo-Hookean materials), an
// optional "stiffening": β ≥ 0 (default 0).
Status parse_youngs_poisson(const JsonNode& j, double* e, double* nu,
                            double* stiffening = nullptr) {
  if (stiffening != nullptr) {
    HC_RETURN_IF_ERROR(j.only_keys({"youngs_pa", "poisson", "stiffening"}));
    HC_RETURN_IF_ERROR(j.optional("stiffening", *stiffening, Bounds::non_negative()));
  } else {
    HC_RETURN_IF_ERROR(j.only_keys({"youngs_pa", "poisson"}));
  }
  HC_RETURN_IF_ERROR(j.get("youngs_pa", *e));
  HC_RETURN_IF_ERROR(j.get("poisson", *nu));
  return fem::validate_youngs_poisson(*e, *nu).with_context(j.path());
}

Status parse_specimen(const JsonNode& j, const std::filesystem::path& base, SpecimenSpec* s) {
  HC_RETURN_IF_ERROR(j.only_keys({"box_m", "max_tet_volume_m3", "cells", "mesh", "scale_to_m",
                                  "contact_elements_per_radius"}));
  HC_RETURN_IF_ERROR(j.optional("max_tet_volume_m3", s->max_tet_volume_m3, Bounds::positive()));
  // Above 16 the fine region alone would exceed a million tets.
  HC_RETURN_IF_ERROR(j.optional("contact_elements_per_radius", s->contact_elements_per_radius,
                                Bounds::between(1, 16)));
  if (const auto n = j.find("contact_elements_per_radius");
      n && (j.has("cells") || j.has("max_tet_volume_m3")))
    return n->error(
        "refines the contact-adaptive mesh: not with \"cells\" or \"max_tet_volume_m3\"");
  if (j.has("box_m") == j.has("mesh")) {
    return j.error("needs exactly one of \"box_m\" and \"mesh\"");
  }
  if (j.has("box_m")) {
    s->kind = SpecimenSpec::Kind::kBox;
    HC_ASSIGN_OR_RETURN(const JsonNode box, j.member("box_m"));
    HC_ASSIGN_OR_RETURN(s->box_m, box.vector<3>());
    if (!(s->box_m.minCoeff() > 0)) return box.error("sizes must be > 0");
    if (const auto c = j.find("cells")) {
      std::array<int, 3> cells{};
      HC_RETURN_IF_ERROR(c->read(cells, Bounds::between(1, 1000)));
      if (static_cast<long long>(cells[0]) * cells[1] * cells[2] > 2000000) {
        return c->error("more than 2,000,000 cells");
      }
      s->cells = Eigen::Vector3i(cells[0], cells[1], cells[2]);
    } else if (s->max_tet_volume_m3 > 0 && s->box_m.prod() / s->max_tet_volume_m3 > 5e6) {
      HC_ASSIGN_OR_RETURN(const JsonNode v, j.member("max_tet_volume_m3"));
      return v.error("would give more than ~5,000,000 tets");
    }
  } else {
    s->kind = SpecimenSpec::Kind::kMesh;
    HC_ASSIGN_OR_RETURN(const JsonNode mesh, j.member("mesh"));
    HC_ASSIGN_OR_RETURN(s->mesh, path_value(mesh, base));
    if (const auto c = j.find("cells")) return c->error("only for box specimens");
  }
  return j.optional("scale_to_m", s->scale_to_m, Bounds::positive());
}

Status parse_material(const JsonNode& j, const std::filesystem::path& base, MaterialSpec* m) {
  if (j.json().is_array()) {
    m->kind = MaterialKind::kLayered;
    if (j.size() == 0) return j.error("empty layer list");
    for (std::size_t i = 0; i < j.size(); ++i) {
      const JsonNode l = j[i];
      HC_RETURN_IF_ERROR(l.only_keys({"z_m", "linear", "neo_hookean"}));
      LayerSpec layer;
      HC_ASSIGN_OR_RETURN(const JsonNode z, l.member("z_m"));
      HC_ASSIGN_OR_RETURN(const Eigen::Vector2d zr, z.vector<2>());
      layer.z_min_m = zr.x();
      layer.z_max_m = zr.y();
      if (!(layer.z_max_m > layer.z_min_m)) return z.error("needs z_min < z_max");
      if (l.has("linear") == l.has("neo_hookean")) {
        return l.error("needs exactly one of \"linear\" and \"neo_hookean\"");
      }
      layer.neo_hookean = l.has("neo_hookean");
      HC_ASSIGN_OR_RETURN(const JsonNode law,
                          l.member(layer.neo_hookean ? "neo_hookean" : "linear"));
      HC_RETURN_IF_ERROR(parse_youngs_poisson(law, &layer.youngs_pa, &layer.poisson,
                                              layer.neo_hookean ? &layer.stiffening : nullptr));
      if (!m->layers.empty() && m->layers.front().neo_hookean != layer.neo_hookean) {
        return j.error("layers must all be \"linear\" or all \"neo_hookean\"");
      }
      m->layers.push_back(layer);
    }
    return {};
  }
  if (!j.json().is_object()) {
    return j.error("expected an object or a list of layers, got " + describe_json(j.json()));
  }
  HC_RETURN_IF_ERROR(j.only_keys({"linear", "neo_hookean", "file"}));
  if (j.json().size() != 1)
    return j.error("needs exactly one of \"linear\", \"neo_hookean\", \"file\"");
  if (const auto file = j.find("file")) {
    m->kind = MaterialKind::kFile;
    HC_ASSIGN_OR_RETURN(m->file, path_value(*file, base));
    return {};
  }
  m->kind = j.has("linear") ? MaterialKind::kLinear : MaterialKind::kNeoHookean;
  HC_ASSIGN_OR_RETURN(const JsonNode law, j.member(j.has("linear") ? "linear" : "neo_hookean"));
  return parse_youngs_poisson(law, &m->youngs_pa, &m->poisson,
                              m->kind == MaterialKind::kNeoHookean ? &m->stiffening : nullptr);
}

Status parse_probe(const JsonNode& j, const std::filesystem::path& base, ProbeSpec* pr) {
  HC_RETURN_IF_ERROR(
      j.only_keys({"shape", "radius_m", "position_m", "direction", "mesh", "scale_to_m"}));
  std::string shape;
  HC_RETURN_IF_ERROR(j.get("shape", shape, {"sphere", "flat", "mesh"}));
  pr->shape = shape == "sphere" ? ProbeSpec::Shape::kSphere
              : shape == "flat" ? ProbeSpec::Shape::kFlat
                                : ProbeSpec::Shape::kMesh;
  if (pr->shape == ProbeSpec::Shape::kMesh) {
    HC_ASSIGN_OR_RETURN(const JsonNode mesh, j.member("mesh"));
    HC_ASSIGN_OR_RETURN(pr->mesh, path_value(mesh, base));
    HC_RETURN_IF_ERROR(j.optional("scale_to_m", pr->scale_to_m, Bounds::positive()));
  } else {
    HC_RETURN_IF_ERROR(j.get("radius_m", pr->radius_m, Bounds::positive()));
  }
  HC_RETURN_IF_ERROR(j.get("position_m", pr->position_m));
  if (const auto d = j.find("direction")) {
    HC_ASSIGN_OR_RETURN(pr->direction, d->vector<3>());
    if (!(pr->direction.norm() > 1e-12)) return d->error("must not be zero");
  }
  return {};
}

Status parse_load(const JsonNode& j, fem::Load* load) {
  HC_RETURN_IF_ERROR(j.only_keys({"depth_m", "force_n"}));
  if (j.json().size() != 1) return j.error("needs exactly one of \"depth_m\" and \"force_n\"");
  load->control = j.has("depth_m") ? fem::LoadControl::kDepth : fem::LoadControl::kForce;
  return j.get(j.has("depth_m") ? "depth_m" : "force_n", load->value, Bounds::positive());
}

Status parse_fixed(const JsonNode& fixed, Scene* scene) {
  if (fixed.json().is_string()) {
    if (fixed.json().get<std::string>() != "bottom") {
      return fixed.error("expected \"bottom\" or a list of node indices");
    }
    scene->fixed_bottom = true;
  } else if (fixed.json().is_array()) {
    scene->fixed_bottom = false;
    if (fixed.size() == 0) return fixed.error("empty node list (the specimen would float)");
    HC_RETURN_IF_ERROR(fixed.read(scene->fixed_nodes, Bounds::between(0, 1000000000)));
  } else {
    return fixed.error("expected \"bottom\" or a list of node indices, got " +
                       describe_json(fixed.json()));
  }
  return {};
}

Result<Scene> parse_scene_json(const JsonNode& root, const std::filesystem::path& base) {
  HC_RETURN_IF_ERROR(root.only_keys({"specimen", "material", "fixed", "probe", "load", "steps"}));
  Scene scene;
  for (const char* key : {"specimen", "material", "fixed", "probe", "load"}) {
    if (!root.has(key)) return root.error(std::string(key) + ": missing");
  }
  HC_ASSIGN_OR_RETURN(const JsonNode specimen, root.member("specimen"));
  HC_RETURN_IF_ERROR(parse_specimen(specimen, base, &scene.specimen));
  HC_ASSIGN_OR_RETURN(const JsonNode material, root.member("material"));
  HC_RETURN_IF_ERROR(parse_material(material, base, &scene.material));
  HC_ASSIGN_OR_RETURN(const JsonNode fixed, root.member("fixed"));
  HC_RETURN_IF_ERROR(parse_fixed(fixed, &scene));
  HC_ASSIGN_OR_RETURN(const JsonNode probe, root.member("probe"));
  HC_RETURN_IF_ERROR(parse_probe(probe, base, &scene.probe));
  HC_ASSIGN_OR_RETURN(const JsonNode load, root.member("load"));
  HC_RETURN_IF_ERROR(parse_load(load, &scene.load));
  HC_RETURN_IF_ERROR(root.optional("steps", scene.steps, Bounds::between(1, 10000)));
  return scene;
}

}  // namespace

Result<Scene> parse_scene(std::string_view text, std::string_view name,
                          const std::filesystem::path& base_dir) {
  HC_ASSIGN_OR_RETURN(Json root, parse_json(text, name));
  return parse_scene_json(JsonNode(root, name), base_dir);
}

Result<Scene> read_scene(const std::filesystem::path& path) {
  HC_ASSIGN_OR_RETURN(std::string text, read_file(path));
  return parse_scene(text, path.string(), path.parent_path());
}

namespace {

// Per-element linear parameters of a layered list (tet centroid z decides, like hyperelastic).
Result<std::vector<fem::LambdaAlpha>> layered_linear(const std::vector<LayerSpec>& layers,
                                                     const TetMesh& mesh) {
  std::vector<fem::LambdaAlpha> p(static_cast<size_t>(mesh.num_tets()));
  for (Eigen::Index e = 0; e < mesh.num_tets(); ++e) {
    double z = 0;
    for (int a = 0; a < 4; ++a) z += 0.25 * mesh.nodes(mesh.tets(e, a), 2);
    const LayerSpec* hit = nullptr;
    for (const LayerSpec& l : layers) {
      if (z >= l.z_min_m && (z < l.z_max_m || (&l == &layers.back() && z <= l.z_max_m))) hit = &l;
    }
    if (hit == nullptr) {
      return invalid_argument("scene: material: tet " + std::to_string(e) +
                              " (centroid z = " + std::to_string(z) + " m) lies in no layer");
    }
    p[static_cast<size_t>(e)] = fem::lambda_alpha_from_youngs_poisson(hit->youngs_pa, hit->poisson);
  }
  return p;
}

Result<SimulationResult> run_neo_hookean(const Scene& scene, const TetMesh& mesh,
                                         const std::vector<int>& fixed, const fem::Probe& probe) {
  HC_ASSIGN_OR_RETURN(std::vector<hyperelastic::NeoHookeanMaterial> materials,
                      reference_materials(scene.material, mesh));
  HC_ASSIGN_OR_RETURN(hyperelastic::NeoHookeanModel model,
                      hyperelastic::NeoHookeanModel::create(mesh, std::move(materials)));
  hyperelastic::ReferenceIndentationOptions options;
  options.steps = scene.steps;
  HC_ASSIGN_OR_RETURN(
      hyperelastic::IndentationResult ind,
      hyperelastic::reference_indentation(model, fixed, probe, scene.load, options));
  if (!ind.summary.usable) return failed_precondition("neo-Hookean model: " + ind.summary.message);
  SimulationResult r;
  r.model = "neo_hookean";
  r.force_n = ind.summary.force_n;
  r.depth_m = ind.summary.depth_m;
  r.max_displacement_m = ind.summary.max_displacement_m;
  for (const auto& st : ind.summary.steps)
    r.steps.push_back({st.depth_m, st.force_n, st.newton_iterations});
  r.positions = std::move(ind.positions_m);
  return r;
}

}  // namespace

Result<SimulationResult> simulate(const Scene& scene, ProgressReporter* progress,
                                  const MaterialLoader& loader) {
  const auto t0 = std::chrono::steady_clock::now();
  ProgressTask task(progress, "simulate", 3);
  MeshReport mesh_report;
  HC_ASSIGN_OR_RETURN(TetMesh mesh, build_specimen(scene, &mesh_report));
  task.advance();
  HC_ASSIGN_OR_RETURN(std::vector<int> fixed, fixed_nodes(scene, mesh));
  HC_ASSIGN_OR_RETURN(std::unique_ptr<fem::Probe> probe, build_probe(scene.probe));
  Result<SimulationResult> result = internal_error("unset");
  const bool neo =
      scene.material.kind == MaterialKind::kNeoHookean ||
      (scene.material.kind == MaterialKind::kLayered && scene.material.layers.front().neo_hookean);
  if (neo) {
    result = run_neo_hookean(scene, mesh, fixed, *probe);
  } else {
    HC_ASSIGN_OR_RETURN(fem::CorotationalFem model, fem::CorotationalFem::create(mesh, fixed));
    std::unique_ptr<fem::MaterialModel> material;
    std::string name = "corotational_linear";
    if (scene.material.kind == MaterialKind::kLinear) {
      material = std::make_unique<fem::ConstantMaterial>(
          fem::lambda_alpha_from_youngs_poisson(scene.material.youngs_pa, scene.material.poisson));
    } else if (scene.material.kind == MaterialKind::kLayered) {
      HC_ASSIGN_OR_RETURN(std::vector<fem::LambdaAlpha> p,
                          layered_linear(scene.material.layers, mesh));
      material = std::make_unique<fem::ConstantMaterial>(std::move(p));
    } else if (loader) {
      HC_ASSIGN_OR_RETURN(material, loader(scene.material.file, mesh));
      name = "corotational_data_driven";
    } else {
      HC_ASSIGN_OR_RETURN(material, material::load_material(scene.material.file));
      name = "corotational_data_driven";
    }
    task.advance();
    fem::IncrementalOptions options;
    options.steps = scene.steps;
    options.progress = progress;
    fem::IncrementalSummary summary;
    HC_RETURN_IF_ERROR(
        fem::run_incremental(&model, *material, *probe, scene.load, options, &summary));
    SimulationResult r;
    r.model = name;
    r.force_n = summary.steps.back().force_n;
    r.depth_m = summary.steps.back().depth_m;
    r.max_displacement_m = summary.max_displacement_m;
    r.steps = summary.steps;
    r.positions = model.positions();
    result = std::move(r);
  }
  if (!result.ok()) return result.status();
  double poisson = scene.material.poisson;
  for (const LayerSpec& l : scene.material.layers) poisson = std::max(poisson, l.poisson);
  if (scene.material.kind != MaterialKind::kFile && poisson >= kLockingPoisson) {
    result->warnings.push_back(fmt::format(
        "Poisson's ratio {:.3g} is near incompressible: linear tetrahedra lock and the force "
        "comes out too high (a sphere at 0.49 on the default mesh: +16 % against the closed "
        "form); read it as an upper bound",
        poisson));
  }
  task.advance();
  result->mesh = std::move(mesh);
  result->mesh_report = mesh_report;
  result->time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return result;
}

}  // namespace hc::scene
