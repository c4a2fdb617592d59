#include "processing/scene/scene.h"

#include <algorithm>
#include <chrono>
#include <limits>
#include <memory>
#include <cmath>
#include <set>
#include <string>

#include "common/file_io.h"
#include "common/json.h"
#include "common/mesh_io.h"
#include "processing/fem/corotational.h"
#include "processing/fem/incremental.h"
#include "processing/fem/material_model.h"
#include "processing/fem/probe.h"
#include "processing/hyperelastic/reference_indentation.h"
#include "processing/hyperelastic/neo_hookean.h"
#include "processing/material/material.h"
#include "processing/meshing/tetrahedralize.h"
#include "processing/scene/contact_meshing.h"
#include "processing/scene/reference.h"

namespace hc::scene {

namespace {

// Reading helpers: every failure names the JSON key path.
Status key_error(const std::string& key, const std::string& what) {
  return invalid_argument("scene: " + key + ": " + what);
}

Status check_keys(const Json& obj, const std::string& path, const std::set<std::string>& allowed) {
  for (auto it = obj.begin(); it != obj.end(); ++it) {
    if (allowed.count(it.key()) == 0) return key_error(path + "." + it.key(), "unknown key");
  }
  return {};
}

Result<const Json*> member(const Json& obj, const std::string& path, const std::string& key) {
  if (!obj.is_object()) return key_error(path, "expected an object");
  auto it = obj.find(key);
  if (it == obj.end()) return key_error(path + "." + key, "missing");
  return &*it;
}

Result<double> number(const Json& j, const std::string& path) {
  if (!j.is_number()) return key_error(path, "expected a number");
  const double v = j.get<double>();
  if (!std::isfinite(v)) return key_error(path, "not a finite number");
  return v;
}

Result<double> positive(const Json& j, const std::string& path) {
  HC_ASSIGN_OR_RETURN(double v, number(j, path));
  if (!(v > 0)) return key_error(path, "must be > 0, got " + std::to_string(v));
  return v;
}

Result<Eigen::Vector3d> vec3(const Json& j, const std::string& path) {
  if (!j.is_array() || j.size() != 3) return key_error(path, "expected an array of 3 numbers");
  Eigen::Vector3d v;
  for (int i = 0; i < 3; ++i) {
    HC_ASSIGN_OR_RETURN(v(i),
                        number(j[static_cast<size_t>(i)], path + "[" + std::to_string(i) + "]"));
  }
  return v;
}

Result<std::filesystem::path> path_value(const Json& j, const std::string& key,
                                         const std::filesystem::path& base) {
  if (!j.is_string() || j.get<std::string>().empty()) return key_error(key, "expected a file path");
  std::filesystem::path p = j.get<std::string>();
  if (p.is_relative()) p = base / p;
  return p;
}

// {"youngs_pa": E, "poisson": ν} and, when `stiffening` is given (neo-Hookean materials), an
// optional "stiffening": β ≥ 0 (default 0).
Status parse_youngs_poisson(const Json& j, const std::string& path, double* e, double* nu,
                            double* stiffening = nullptr) {
  if (!j.is_object()) return key_error(path, "expected an object");
  if (stiffening != nullptr) {
    HC_RETURN_IF_ERROR(check_keys(j, path, {"youngs_pa", "poisson", "stiffening"}));
  } else {
    HC_RETURN_IF_ERROR(check_keys(j, path, {"youngs_pa", "poisson"}));
  }
  HC_ASSIGN_OR_RETURN(const Json* je, member(j, path, "youngs_pa"));
  HC_ASSIGN_OR_RETURN(const Json* jn, member(j, path, "poisson"));
  HC_ASSIGN_OR_RETURN(*e, number(*je, path + ".youngs_pa"));
  HC_ASSIGN_OR_RETURN(*nu, number(*jn, path + ".poisson"));
  if (stiffening != nullptr && j.contains("stiffening")) {
    HC_ASSIGN_OR_RETURN(*stiffening, number(j["stiffening"], path + ".stiffening"));
    if (!(*stiffening >= 0)) return key_error(path + ".stiffening", "must be >= 0");
  }
  return fem::validate_youngs_poisson(*e, *nu).with_context("scene: " + path);
}

Status parse_specimen(const Json& j, const std::filesystem::path& base, SpecimenSpec* s) {
  const std::string p = "specimen";
  if (!j.is_object()) return key_error(p, "expected an object");
  HC_RETURN_IF_ERROR(
      check_keys(j, p, {"box_m", "max_tet_volume_m3", "cells", "mesh", "scale_to_m"}));
  if (j.contains("max_tet_volume_m3")) {
    HC_ASSIGN_OR_RETURN(s->max_tet_volume_m3,
                        positive(j["max_tet_volume_m3"], p + ".max_tet_volume_m3"));
  }
  if (j.contains("box_m") == j.contains("mesh")) {
    return key_error(p, "needs exactly one of \"box_m\" and \"mesh\"");
  }
  if (j.contains("box_m")) {
    s->kind = SpecimenSpec::Kind::kBox;
    HC_ASSIGN_OR_RETURN(s->box_m, vec3(j["box_m"], p + ".box_m"));
    if (!(s->box_m.minCoeff() > 0)) return key_error(p + ".box_m", "sizes must be > 0");
    if (j.contains("cells")) {
      const Json& c = j["cells"];
      if (!c.is_array() || c.size() != 3) return key_error(p + ".cells", "expected 3 integers");
      Eigen::Vector3i cells;
      for (int i = 0; i < 3; ++i) {
        const Json& ci = c[static_cast<size_t>(i)];
        if (!ci.is_number_integer() || ci.get<long long>() < 1 || ci.get<long long>() > 1000) {
          return key_error(p + ".cells", "expected integers in [1, 1000]");
        }
        cells(i) = static_cast<int>(ci.get<long long>());
      }
      if (static_cast<long long>(cells(0)) * cells(1) * cells(2) > 2000000) {
        return key_error(p + ".cells", "more than 2,000,000 cells");
      }
      s->cells = cells;
    } else if (s->max_tet_volume_m3 > 0 && s->box_m.prod() / s->max_tet_volume_m3 > 5e6) {
      return key_error(p + ".max_tet_volume_m3", "would give more than ~5,000,000 tets");
    }
  } else {
    s->kind = SpecimenSpec::Kind::kMesh;
    HC_ASSIGN_OR_RETURN(s->mesh, path_value(j["mesh"], p + ".mesh", base));
    if (j.contains("cells")) return key_error(p + ".cells", "only for box specimens");
  }
  if (j.contains("scale_to_m")) {
    HC_ASSIGN_OR_RETURN(s->scale_to_m, positive(j["scale_to_m"], p + ".scale_to_m"));
  }
  return {};
}

Status parse_material(const Json& j, const std::filesystem::path& base, MaterialSpec* m) {
  const std::string p = "material";
  if (j.is_array()) {
    m->kind = MaterialKind::kLayered;
    if (j.empty()) return key_error(p, "empty layer list");
    for (size_t i = 0; i < j.size(); ++i) {
      const std::string lp = p + "[" + std::to_string(i) + "]";
      const Json& l = j[i];
      if (!l.is_object()) return key_error(lp, "expected an object");
      HC_RETURN_IF_ERROR(check_keys(l, lp, {"z_m", "linear", "neo_hookean"}));
      LayerSpec layer;
      HC_ASSIGN_OR_RETURN(const Json* z, member(l, lp, "z_m"));
      if (!z->is_array() || z->size() != 2)
        return key_error(lp + ".z_m", "expected [z_min, z_max]");
      HC_ASSIGN_OR_RETURN(layer.z_min_m, number((*z)[0], lp + ".z_m[0]"));
      HC_ASSIGN_OR_RETURN(layer.z_max_m, number((*z)[1], lp + ".z_m[1]"));
      if (!(layer.z_max_m > layer.z_min_m)) return key_error(lp + ".z_m", "needs z_min < z_max");
      if (l.contains("linear") == l.contains("neo_hookean")) {
        return key_error(lp, "needs exactly one of \"linear\" and \"neo_hookean\"");
      }
      layer.neo_hookean = l.contains("neo_hookean");
      HC_RETURN_IF_ERROR(parse_youngs_poisson(layer.neo_hookean ? l["neo_hookean"] : l["linear"],
                                              lp + (layer.neo_hookean ? ".neo_hookean" : ".linear"),
                                              &layer.youngs_pa, &layer.poisson,
                                              layer.neo_hookean ? &layer.stiffening : nullptr));
      if (!m->layers.empty() && m->layers.front().neo_hookean != layer.neo_hookean) {
        return key_error(p, "layers must all be \"linear\" or all \"neo_hookean\"");
      }
      m->layers.push_back(layer);
    }
    return {};
  }
  if (!j.is_object()) return key_error(p, "expected an object or a list of layers");
  HC_RETURN_IF_ERROR(check_keys(j, p, {"linear", "neo_hookean", "file"}));
  if (j.size() != 1)
    return key_error(p, "needs exactly one of \"linear\", \"neo_hookean\", \"file\"");
  if (j.contains("file")) {
    m->kind = MaterialKind::kFile;
    HC_ASSIGN_OR_RETURN(m->file, path_value(j["file"], p + ".file", base));
    return {};
  }
  m->kind = j.contains("linear") ? MaterialKind::kLinear : MaterialKind::kNeoHookean;
  const std::string sub = j.contains("linear") ? "linear" : "neo_hookean";
  return parse_youngs_poisson(j[sub], p + "." + sub, &m->youngs_pa, &m->poisson,
                              m->kind == MaterialKind::kNeoHookean ? &m->stiffening : nullptr);
}

Status parse_probe(const Json& j, const std::filesystem::path& base, ProbeSpec* pr) {
  const std::string p = "probe";
  if (!j.is_object()) return key_error(p, "expected an object");
  HC_RETURN_IF_ERROR(
      check_keys(j, p, {"shape", "radius_m", "position_m", "direction", "mesh", "scale_to_m"}));
  HC_ASSIGN_OR_RETURN(const Json* shape, member(j, p, "shape"));
  if (!shape->is_string())
    return key_error(p + ".shape", "expected \"sphere\", \"flat\" or \"mesh\"");
  const std::string s = shape->get<std::string>();
  if (s == "sphere") {
    pr->shape = ProbeSpec::Shape::kSphere;
  } else if (s == "flat") {
    pr->shape = ProbeSpec::Shape::kFlat;
  } else if (s == "mesh") {
    pr->shape = ProbeSpec::Shape::kMesh;
  } else {
    return key_error(p + ".shape", "expected \"sphere\", \"flat\" or \"mesh\", got \"" + s + "\"");
  }
  if (pr->shape == ProbeSpec::Shape::kMesh) {
    HC_ASSIGN_OR_RETURN(const Json* mesh, member(j, p, "mesh"));
    HC_ASSIGN_OR_RETURN(pr->mesh, path_value(*mesh, p + ".mesh", base));
    if (j.contains("scale_to_m")) {
      HC_ASSIGN_OR_RETURN(pr->scale_to_m, positive(j["scale_to_m"], p + ".scale_to_m"));
    }
  } else {
    HC_ASSIGN_OR_RETURN(const Json* r, member(j, p, "radius_m"));
    HC_ASSIGN_OR_RETURN(pr->radius_m, positive(*r, p + ".radius_m"));
  }
  HC_ASSIGN_OR_RETURN(const Json* pos, member(j, p, "position_m"));
  HC_ASSIGN_OR_RETURN(pr->position_m, vec3(*pos, p + ".position_m"));
  if (j.contains("direction")) {
    HC_ASSIGN_OR_RETURN(pr->direction, vec3(j["direction"], p + ".direction"));
    if (!(pr->direction.norm() > 1e-12)) return key_error(p + ".direction", "must not be zero");
  }
  return {};
}

Status parse_load(const Json& j, fem::Load* load) {
  const std::string p = "load";
  if (!j.is_object()) return key_error(p, "expected an object");
  HC_RETURN_IF_ERROR(check_keys(j, p, {"depth_m", "force_n"}));
  if (j.size() != 1) return key_error(p, "needs exactly one of \"depth_m\" and \"force_n\"");
  load->control = j.contains("depth_m") ? fem::LoadControl::kDepth : fem::LoadControl::kForce;
  const std::string key = j.contains("depth_m") ? "depth_m" : "force_n";
  HC_ASSIGN_OR_RETURN(load->value, positive(j[key], p + "." + key));
  return {};
}

Result<Scene> parse_scene_json(const Json& root, const std::filesystem::path& base) {
  if (!root.is_object()) return invalid_argument("scene: expected a JSON object");
  HC_RETURN_IF_ERROR(
      check_keys(root, "scene", {"specimen", "material", "fixed", "probe", "load", "steps"}));
  Scene scene;
  for (const char* key : {"specimen", "material", "fixed", "probe", "load"}) {
    if (!root.contains(key)) return key_error(key, "missing");
  }
  HC_RETURN_IF_ERROR(parse_specimen(root["specimen"], base, &scene.specimen));
  HC_RETURN_IF_ERROR(parse_material(root["material"], base, &scene.material));
  const Json& fixed = root["fixed"];
  if (fixed.is_string()) {
    if (fixed.get<std::string>() != "bottom") {
      return key_error("fixed", "expected \"bottom\" or a list of node indices");
    }
    scene.fixed_bottom = true;
  } else if (fixed.is_array()) {
    scene.fixed_bottom = false;
    if (fixed.empty()) return key_error("fixed", "empty node list (the specimen would float)");
    for (const Json& n : fixed) {
      if (!n.is_number_integer() || n.get<long long>() < 0 || n.get<long long>() > 1000000000LL) {
        return key_error("fixed", "node indices must be non-negative integers");
      }
      scene.fixed_nodes.push_back(static_cast<int>(n.get<long long>()));
    }
  } else {
    return key_error("fixed", "expected \"bottom\" or a list of node indices");
  }
  HC_RETURN_IF_ERROR(parse_probe(root["probe"], base, &scene.probe));
  HC_RETURN_IF_ERROR(parse_load(root["load"], &scene.load));
  if (root.contains("steps")) {
    const Json& s = root["steps"];
    if (!s.is_number_integer() || s.get<long long>() < 1 || s.get<long long>() > 10000) {
      return key_error("steps", "expected an integer in [1, 10000]");
    }
    scene.steps = static_cast<int>(s.get<long long>());
  }
  return scene;
}

}  // namespace

Result<Scene> parse_scene(std::string_view text, std::string_view name,
                          const std::filesystem::path& base_dir) {
  HC_ASSIGN_OR_RETURN(Json root, parse_json(text, name));
  try {
    Result<Scene> r = parse_scene_json(root, base_dir);
    if (!r.ok()) return r.status().with_context(std::string(name));
    return r;
  } catch (
      const std::exception& e) {  // nlohmann type errors: a bug guard, values are checked above
    return invalid_argument(std::string(name) + ": scene: " + e.what());
  }
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
  if (!ind.summary.usable)
    return failed_precondition("neo-Hookean model: " + ind.summary.message);
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

Result<SimulationResult> simulate(const Scene& scene, ProgressReporter* progress) {
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
  task.advance();
  result->mesh = std::move(mesh);
  result->mesh_report = mesh_report;
  result->time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return result;
}

}  // namespace hc::scene
