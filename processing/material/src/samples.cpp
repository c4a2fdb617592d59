#include "processing/material/samples.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "common/file_io.h"
#include "common/tet_mesh_io.h"
#include "json_fields.h"

namespace hc::material {
namespace {

using detail::FieldReader;
using detail::index;
using detail::join;

constexpr std::string_view kProbeShapes[] = {"sphere", "flat", "mesh", "none"};

// Tets with |volume| below this fraction of the bounding-box volume are refused as degenerate.
constexpr double kDegenerateVolumeFraction = 1e-12;

Status validate_mesh(const TetMesh& mesh, std::string_view where) {
  const auto err = [&](std::string what) {
    return invalid_argument(fmt::format("{}: {}", where, what));
  };
  if (mesh.num_nodes() < 4)
    return err(fmt::format("needs at least 4 nodes, has {}", mesh.num_nodes()));
  if (mesh.num_tets() < 1) return err("has no tets");
  if (!mesh.nodes.allFinite()) return err("node coordinates must be finite");
  const Eigen::Vector3d extent = mesh.nodes.colwise().maxCoeff() - mesh.nodes.colwise().minCoeff();
  const double box_volume = extent.prod();
  for (Eigen::Index t = 0; t < mesh.num_tets(); ++t) {
    for (int k = 0; k < 4; ++k) {
      const int n = mesh.tets(t, k);
      if (n < 0 || n >= mesh.num_nodes())
        return err(fmt::format("tets[{}]: node {} is out of range (mesh has {} nodes)", t, n,
                               mesh.num_nodes()));
    }
    const Eigen::Vector3d a = mesh.nodes.row(mesh.tets(t, 0));
    const Eigen::Vector3d b = mesh.nodes.row(mesh.tets(t, 1));
    const Eigen::Vector3d c = mesh.nodes.row(mesh.tets(t, 2));
    const Eigen::Vector3d d = mesh.nodes.row(mesh.tets(t, 3));
    const double v = (b - a).dot((c - a).cross(d - a)) / 6.0;
    if (!(std::abs(v) > kDegenerateVolumeFraction * box_volume))
      return err(fmt::format("tets[{}] is degenerate (volume {:.3g} m^3)", t, v));
    if (v < 0) return err(fmt::format("tets[{}] is inverted (negative volume {:.3g} m^3)", t, v));
  }
  return {};
}

Result<TetMesh> read_inline_mesh(const FieldReader& r, const Json& j) {
  HC_ASSIGN_OR_RETURN(const Json* nodes, r.member(j, "mesh", "nodes"));
  HC_ASSIGN_OR_RETURN(const Json* tets, r.member(j, "mesh", "tets"));
  HC_RETURN_IF_ERROR(r.array(*nodes, "mesh.nodes", 4));
  HC_RETURN_IF_ERROR(r.array(*tets, "mesh.tets", 1));
  TetMesh mesh;
  mesh.nodes.resize(static_cast<Eigen::Index>(nodes->size()), 3);
  for (std::size_t i = 0; i < nodes->size(); ++i) {
    Eigen::Vector3d p;
    HC_RETURN_IF_ERROR(r.vector<3>((*nodes)[i], index("mesh.nodes", i), &p));
    mesh.nodes.row(static_cast<Eigen::Index>(i)) = p.transpose();
  }
  mesh.tets.resize(static_cast<Eigen::Index>(tets->size()), 4);
  for (std::size_t t = 0; t < tets->size(); ++t) {
    const Json& tet = (*tets)[t];
    const std::string path = index("mesh.tets", t);
    if (!tet.is_array() || tet.size() != 4)
      return r.error(path, "expected an array of 4 node indices");
    for (std::size_t k = 0; k < 4; ++k) {
      int n = 0;
      HC_RETURN_IF_ERROR(r.index_in(tet[k], index(path, k), mesh.num_nodes(), &n));
      mesh.tets(static_cast<Eigen::Index>(t), static_cast<Eigen::Index>(k)) = n;
    }
  }
  return mesh;
}

Status read_probe(const FieldReader& r, const Json& j, const std::string& path, ProbePose* probe) {
  HC_RETURN_IF_ERROR(r.object(j, path));
  HC_RETURN_IF_ERROR(
      r.only_keys(j, path, {"shape", "radius_m", "position_m", "direction", "mesh"}));
  HC_ASSIGN_OR_RETURN(const Json* shape, r.member(j, path, "shape"));
  HC_RETURN_IF_ERROR(r.string(*shape, join(path, "shape"), &probe->shape));
  if (std::find(std::begin(kProbeShapes), std::end(kProbeShapes), probe->shape) ==
      std::end(kProbeShapes))
    return r.error(join(path, "shape"),
                   fmt::format("unknown probe shape '{}' (expected sphere, flat, mesh or none)",
                               probe->shape));
  if (const Json* v = r.optional(j, "radius_m"))
    HC_RETURN_IF_ERROR(r.number(*v, join(path, "radius_m"), &probe->radius_m));
  if (const Json* v = r.optional(j, "position_m"))
    HC_RETURN_IF_ERROR(r.vector<3>(*v, join(path, "position_m"), &probe->position_m));
  if (const Json* v = r.optional(j, "direction"))
    HC_RETURN_IF_ERROR(r.vector<3>(*v, join(path, "direction"), &probe->direction));
  if (const Json* v = r.optional(j, "mesh"))
    HC_RETURN_IF_ERROR(r.string(*v, join(path, "mesh"), &probe->mesh));
  return {};
}

Result<Example> read_example(const FieldReader& r, const Json& j, const std::string& path,
                             Eigen::Index num_nodes) {
  Example ex;
  HC_RETURN_IF_ERROR(r.object(j, path));
  HC_RETURN_IF_ERROR(
      r.only_keys(j, path, {"name", "probe", "forces", "positions_m", "visible", "fixed_nodes"}));
  if (const Json* v = r.optional(j, "name"))
    HC_RETURN_IF_ERROR(r.string(*v, join(path, "name"), &ex.name));
  if (const Json* v = r.optional(j, "probe"))
    HC_RETURN_IF_ERROR(read_probe(r, *v, join(path, "probe"), &ex.probe));

  HC_ASSIGN_OR_RETURN(const Json* forces, r.member(j, path, "forces"));
  const std::string fpath = join(path, "forces");
  HC_RETURN_IF_ERROR(r.array(*forces, fpath));
  for (std::size_t i = 0; i < forces->size(); ++i) {
    const Json& f = (*forces)[i];
    const std::string p = index(fpath, i);
    HC_RETURN_IF_ERROR(r.object(f, p));
    HC_RETURN_IF_ERROR(r.only_keys(f, p, {"node", "force_n"}));
    NodalForce nf;
    HC_ASSIGN_OR_RETURN(const Json* node, r.member(f, p, "node"));
    HC_RETURN_IF_ERROR(r.index_in(*node, join(p, "node"), num_nodes, &nf.node));
    HC_ASSIGN_OR_RETURN(const Json* fn, r.member(f, p, "force_n"));
    HC_RETURN_IF_ERROR(r.vector<3>(*fn, join(p, "force_n"), &nf.force_n));
    ex.forces.push_back(nf);
  }

  HC_ASSIGN_OR_RETURN(const Json* positions, r.member(j, path, "positions_m"));
  const std::string ppath = join(path, "positions_m");
  HC_RETURN_IF_ERROR(r.array(*positions, ppath));
  if (static_cast<Eigen::Index>(positions->size()) != num_nodes)
    return r.error(ppath, fmt::format("expected {} positions (one per mesh node), got {}",
                                      num_nodes, positions->size()));
  ex.positions_m.resize(num_nodes, 3);
  for (std::size_t i = 0; i < positions->size(); ++i) {
    Eigen::Vector3d p;
    HC_RETURN_IF_ERROR(r.vector<3>((*positions)[i], index(ppath, i), &p));
    ex.positions_m.row(static_cast<Eigen::Index>(i)) = p.transpose();
  }

  ex.visible.assign(static_cast<std::size_t>(num_nodes), 1);
  if (const Json* vis = r.optional(j, "visible")) {
    const std::string vpath = join(path, "visible");
    HC_RETURN_IF_ERROR(r.array(*vis, vpath));
    if (static_cast<Eigen::Index>(vis->size()) != num_nodes)
      return r.error(vpath, fmt::format("expected {} flags (one per mesh node), got {}", num_nodes,
                                        vis->size()));
    for (std::size_t i = 0; i < vis->size(); ++i) {
      const Json& v = (*vis)[i];
      if (v.is_boolean()) {
        ex.visible[i] = v.get<bool>() ? 1 : 0;
      } else {
        long long b = 0;
        HC_RETURN_IF_ERROR(r.integer(v, index(vpath, i), 0, 1, &b));
        ex.visible[i] = static_cast<std::uint8_t>(b);
      }
    }
  }

  HC_ASSIGN_OR_RETURN(const Json* fixed, r.member(j, path, "fixed_nodes"));
  const std::string xpath = join(path, "fixed_nodes");
  HC_RETURN_IF_ERROR(r.array(*fixed, xpath));
  for (std::size_t i = 0; i < fixed->size(); ++i) {
    int n = 0;
    HC_RETURN_IF_ERROR(r.index_in((*fixed)[i], index(xpath, i), num_nodes, &n));
    ex.fixed_nodes.push_back(n);
  }
  std::sort(ex.fixed_nodes.begin(), ex.fixed_nodes.end());
  ex.fixed_nodes.erase(std::unique(ex.fixed_nodes.begin(), ex.fixed_nodes.end()),
                       ex.fixed_nodes.end());
  return ex;
}

}  // namespace

Eigen::VectorXd Example::force_vector(Eigen::Index num_nodes) const {
  Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * num_nodes);
  for (const NodalForce& nf : forces) f.segment<3>(3 * nf.node) += nf.force_n;
  return f;
}

double Samples::max_displacement_m(std::size_t i) const {
  const Example& ex = examples.at(i);
  std::vector<char> fixed(static_cast<std::size_t>(mesh.num_nodes()), 0);
  for (int n : ex.fixed_nodes) fixed[static_cast<std::size_t>(n)] = 1;
  double m = 0;
  for (Eigen::Index n = 0; n < mesh.num_nodes(); ++n) {
    const auto k = static_cast<std::size_t>(n);
    if (!ex.visible[k] || fixed[k]) continue;
    m = std::max(m, (ex.positions_m.row(n) - mesh.nodes.row(n)).norm());
  }
  return m;
}

double Samples::max_displacement_m() const {
  double m = 0;
  for (std::size_t i = 0; i < examples.size(); ++i) m = std::max(m, max_displacement_m(i));
  return m;
}

Status validate_samples(const Samples& samples) {
  HC_RETURN_IF_ERROR(validate_mesh(samples.mesh, "mesh"));
  if (samples.examples.empty()) return invalid_argument("examples: at least one example is needed");
  const Eigen::Index n = samples.mesh.num_nodes();
  for (std::size_t e = 0; e < samples.examples.size(); ++e) {
    const Example& ex = samples.examples[e];
    const std::string path = fmt::format("examples[{}]", e);
    const auto err = [&](std::string what) {
      return invalid_argument(fmt::format("{}.{}", path, what));
    };
    if (ex.positions_m.rows() != n)
      return err(fmt::format("positions_m: expected {} rows, got {}", n, ex.positions_m.rows()));
    if (!ex.positions_m.allFinite()) return err("positions_m: coordinates must be finite");
    if (ex.visible.size() != static_cast<std::size_t>(n))
      return err(fmt::format("visible: expected {} flags, got {}", n, ex.visible.size()));
    std::set<int> force_nodes;
    for (std::size_t i = 0; i < ex.forces.size(); ++i) {
      const NodalForce& f = ex.forces[i];
      if (f.node < 0 || f.node >= n)
        return err(
            fmt::format("forces[{}].node: {} is out of range (mesh has {} nodes)", i, f.node, n));
      if (!f.force_n.allFinite()) return err(fmt::format("forces[{}].force_n: must be finite", i));
      if (!force_nodes.insert(f.node).second)
        return err(fmt::format("forces[{}].node: node {} has a force already", i, f.node));
    }
    for (std::size_t i = 0; i < ex.fixed_nodes.size(); ++i) {
      const int f = ex.fixed_nodes[i];
      if (f < 0 || f >= n)
        return err(fmt::format("fixed_nodes[{}]: {} is out of range (mesh has {} nodes)", i, f, n));
      if (i > 0 && f <= ex.fixed_nodes[i - 1])
        return err(fmt::format("fixed_nodes[{}]: must be sorted and unique", i));
    }
    const ProbePose& p = ex.probe;
    if (std::find(std::begin(kProbeShapes), std::end(kProbeShapes), p.shape) ==
        std::end(kProbeShapes))
      return err(fmt::format("probe.shape: unknown probe shape '{}'", p.shape));
    if (!std::isfinite(p.radius_m) || p.radius_m < 0)
      return err("probe.radius_m: must be a finite number >= 0");
    if ((p.shape == "sphere" || p.shape == "flat") && !(p.radius_m > 0))
      return err(fmt::format("probe.radius_m: a {} probe needs a radius > 0", p.shape));
    if (p.shape == "mesh" && p.mesh.empty()) return err("probe.mesh: a mesh probe needs a file");
    if (!p.position_m.allFinite()) return err("probe.position_m: must be finite");
    if (!p.direction.allFinite() || std::abs(p.direction.norm() - 1.0) > 1e-6)
      return err("probe.direction: must be a unit vector");
  }
  return {};
}

Result<Samples> parse_samples(std::string_view text, std::string_view name,
                              const std::filesystem::path& base_dir) {
  HC_ASSIGN_OR_RETURN(Json doc, parse_json(text, name));
  const FieldReader r(name);
  HC_RETURN_IF_ERROR(r.object(doc, ""));
  HC_RETURN_IF_ERROR(r.only_keys(doc, "", {"format", "version", "units", "mesh", "examples"}));
  HC_ASSIGN_OR_RETURN(const Json* format, r.member(doc, "", "format"));
  std::string format_name;
  HC_RETURN_IF_ERROR(r.string(*format, "format", &format_name));
  if (format_name != kSamplesFormat)
    return r.error("format", fmt::format("expected '{}', got '{}'", kSamplesFormat, format_name));
  HC_ASSIGN_OR_RETURN(const Json* version, r.member(doc, "", "version"));
  long long v = 0;
  if (!version->is_number_integer()) return r.error("version", "expected an integer");
  HC_RETURN_IF_ERROR(r.integer(*version, "version", std::numeric_limits<long long>::min(),
                               std::numeric_limits<long long>::max(), &v));
  if (v != kSamplesVersion)
    return r.error("version", fmt::format("unknown version {} (this build reads version {})", v,
                                          kSamplesVersion));
  if (const Json* units = r.optional(doc, "units")) {
    HC_RETURN_IF_ERROR(r.object(*units, "units"));
    HC_RETURN_IF_ERROR(r.only_keys(*units, "units", {"length", "force"}));
    std::string s;
    if (const Json* l = r.optional(*units, "length")) {
      HC_RETURN_IF_ERROR(r.string(*l, "units.length", &s));
      if (s != "m") return r.error("units.length", fmt::format("expected 'm', got '{}'", s));
    }
    if (const Json* f = r.optional(*units, "force")) {
      HC_RETURN_IF_ERROR(r.string(*f, "units.force", &s));
      if (s != "N") return r.error("units.force", fmt::format("expected 'N', got '{}'", s));
    }
  }

  Samples samples;
  HC_ASSIGN_OR_RETURN(const Json* mesh, r.member(doc, "", "mesh"));
  HC_RETURN_IF_ERROR(r.object(*mesh, "mesh"));
  if (mesh->contains("node_file") || mesh->contains("ele_file")) {
    HC_RETURN_IF_ERROR(r.only_keys(*mesh, "mesh", {"node_file", "ele_file"}));
    HC_ASSIGN_OR_RETURN(const Json* nf, r.member(*mesh, "mesh", "node_file"));
    HC_ASSIGN_OR_RETURN(const Json* ef, r.member(*mesh, "mesh", "ele_file"));
    HC_RETURN_IF_ERROR(r.string(*nf, "mesh.node_file", &samples.node_file));
    HC_RETURN_IF_ERROR(r.string(*ef, "mesh.ele_file", &samples.ele_file));
    const std::filesystem::path node_path = base_dir / samples.node_file;
    const std::filesystem::path ele_path = base_dir / samples.ele_file;
    HC_ASSIGN_OR_RETURN(std::string node_bytes, read_file(node_path));
    HC_ASSIGN_OR_RETURN(std::string ele_bytes, read_file(ele_path));
    Result<TetMesh> m = parse_tetgen(node_bytes, ele_bytes, node_path.string(), ele_path.string());
    if (!m.ok()) return m.status().with_context(std::string(name));
    samples.mesh = std::move(m).value();
  } else {
    HC_RETURN_IF_ERROR(r.only_keys(*mesh, "mesh", {"nodes", "tets"}));
    HC_ASSIGN_OR_RETURN(samples.mesh, read_inline_mesh(r, *mesh));
  }
  if (Status s = validate_mesh(samples.mesh, "mesh"); !s.ok())
    return s.with_context(std::string(name));

  HC_ASSIGN_OR_RETURN(const Json* examples, r.member(doc, "", "examples"));
  HC_RETURN_IF_ERROR(r.array(*examples, "examples", 1));
  for (std::size_t i = 0; i < examples->size(); ++i) {
    HC_ASSIGN_OR_RETURN(Example ex, read_example(r, (*examples)[i], index("examples", i),
                                                 samples.mesh.num_nodes()));
    samples.examples.push_back(std::move(ex));
  }
  if (Status s = validate_samples(samples); !s.ok()) return s.with_context(std::string(name));
  return samples;
}

Result<Samples> load_samples(const std::filesystem::path& path) {
  HC_ASSIGN_OR_RETURN(std::string text, read_file(path));
  return parse_samples(text, path.string(), path.parent_path());
}

Json samples_to_json(const Samples& samples) {
  Json doc;
  doc["format"] = kSamplesFormat;
  doc["version"] = kSamplesVersion;
  doc["units"] = {{"length", "m"}, {"force", "N"}};
  if (!samples.node_file.empty() && !samples.ele_file.empty()) {
    doc["mesh"] = {{"node_file", samples.node_file}, {"ele_file", samples.ele_file}};
  } else {
    Json tets = Json::array();
    for (Eigen::Index t = 0; t < samples.mesh.num_tets(); ++t)
      tets.push_back({samples.mesh.tets(t, 0), samples.mesh.tets(t, 1), samples.mesh.tets(t, 2),
                      samples.mesh.tets(t, 3)});
    doc["mesh"] = {{"nodes", eigen_to_json(samples.mesh.nodes)}, {"tets", std::move(tets)}};
  }
  Json examples = Json::array();
  for (const Example& ex : samples.examples) {
    Json e;
    if (!ex.name.empty()) e["name"] = ex.name;
    Json probe = {{"shape", ex.probe.shape},
                  {"radius_m", ex.probe.radius_m},
                  {"position_m", eigen_to_json(ex.probe.position_m)},
                  {"direction", eigen_to_json(ex.probe.direction)}};
    if (!ex.probe.mesh.empty()) probe["mesh"] = ex.probe.mesh;
    e["probe"] = std::move(probe);
    Json forces = Json::array();
    for (const NodalForce& f : ex.forces)
      forces.push_back({{"node", f.node}, {"force_n", eigen_to_json(f.force_n)}});
    e["forces"] = std::move(forces);
    e["positions_m"] = eigen_to_json(ex.positions_m);
    Json vis = Json::array();
    for (std::uint8_t v : ex.visible) vis.push_back(static_cast<int>(v));
    e["visible"] = std::move(vis);
    e["fixed_nodes"] = ex.fixed_nodes;
    examples.push_back(std::move(e));
  }
  doc["examples"] = std::move(examples);
  return doc;
}

Status save_samples(const std::filesystem::path& path, const Samples& samples) {
  HC_RETURN_IF_ERROR(validate_samples(samples));
  return write_file_atomic(path, dump_json(samples_to_json(samples)));
}

}  // namespace hc::material
