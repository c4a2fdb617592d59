#include "processing/material/samples.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "common/file_io.h"
#include "common/json_reader.h"
#include "common/tet_mesh_io.h"

namespace hc::material {
namespace {

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

Result<TetMesh> read_inline_mesh(const JsonNode& j) {
  HC_ASSIGN_OR_RETURN(const JsonNode nodes, j.member("nodes"));
  HC_ASSIGN_OR_RETURN(const JsonNode tets, j.member("tets"));
  HC_RETURN_IF_ERROR(nodes.expect_array(4));
  HC_RETURN_IF_ERROR(tets.expect_array(1));
  TetMesh mesh;
  mesh.nodes.resize(static_cast<Eigen::Index>(nodes.size()), 3);
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    HC_ASSIGN_OR_RETURN(const Eigen::Vector3d p, nodes[i].vector<3>());
    mesh.nodes.row(static_cast<Eigen::Index>(i)) = p.transpose();
  }
  mesh.tets.resize(static_cast<Eigen::Index>(tets.size()), 4);
  for (std::size_t t = 0; t < tets.size(); ++t) {
    const JsonNode tet = tets[t];
    HC_RETURN_IF_ERROR(tet.expect_array_of(4, "node indices"));
    for (std::size_t k = 0; k < 4; ++k) {
      HC_ASSIGN_OR_RETURN(const std::size_t n,
                          tet[k].index(static_cast<std::size_t>(mesh.num_nodes())));
      mesh.tets(static_cast<Eigen::Index>(t), static_cast<Eigen::Index>(k)) = static_cast<int>(n);
    }
  }
  return mesh;
}

Status read_probe(const JsonNode& j, ProbePose* probe) {
  HC_RETURN_IF_ERROR(j.only_keys({"shape", "radius_m", "position_m", "direction", "mesh"}));
  HC_ASSIGN_OR_RETURN(const JsonNode shape, j.member("shape"));
  HC_ASSIGN_OR_RETURN(probe->shape, shape.string());
  if (std::find(std::begin(kProbeShapes), std::end(kProbeShapes), probe->shape) ==
      std::end(kProbeShapes))
    return shape.error(fmt::format("unknown probe shape '{}' (expected sphere, flat, mesh or none)",
                                   probe->shape));
  if (const auto v = j.find("radius_m")) {
    HC_ASSIGN_OR_RETURN(probe->radius_m, v->number());
  }
  if (const auto v = j.find("position_m")) {
    HC_ASSIGN_OR_RETURN(probe->position_m, v->vector<3>());
  }
  if (const auto v = j.find("direction")) {
    HC_ASSIGN_OR_RETURN(probe->direction, v->vector<3>());
  }
  if (const auto v = j.find("mesh")) {
    HC_ASSIGN_OR_RETURN(probe->mesh, v->string());
  }
  return {};
}

// A node index of a mesh with `num_nodes` nodes.
Result<int> node_index(const JsonNode& j, Eigen::Index num_nodes) {
  HC_ASSIGN_OR_RETURN(const std::size_t n, j.index(static_cast<std::size_t>(num_nodes)));
  return static_cast<int>(n);
}

Result<Example> read_example(const JsonNode& j, Eigen::Index num_nodes) {
  Example ex;
  HC_RETURN_IF_ERROR(
      j.only_keys({"name", "probe", "forces", "positions_m", "visible", "fixed_nodes"}));
  if (const auto v = j.find("name")) {
    HC_ASSIGN_OR_RETURN(ex.name, v->string());
  }
  if (const auto v = j.find("probe")) HC_RETURN_IF_ERROR(read_probe(*v, &ex.probe));

  HC_ASSIGN_OR_RETURN(const JsonNode forces, j.member("forces"));
  HC_RETURN_IF_ERROR(forces.expect_array());
  for (std::size_t i = 0; i < forces.size(); ++i) {
    const JsonNode f = forces[i];
    HC_RETURN_IF_ERROR(f.only_keys({"node", "force_n"}));
    NodalForce nf;
    HC_ASSIGN_OR_RETURN(const JsonNode node, f.member("node"));
    HC_ASSIGN_OR_RETURN(nf.node, node_index(node, num_nodes));
    HC_ASSIGN_OR_RETURN(const JsonNode fn, f.member("force_n"));
    HC_ASSIGN_OR_RETURN(nf.force_n, fn.vector<3>());
    ex.forces.push_back(nf);
  }

  HC_ASSIGN_OR_RETURN(const JsonNode positions, j.member("positions_m"));
  HC_RETURN_IF_ERROR(positions.expect_array());
  if (static_cast<Eigen::Index>(positions.size()) != num_nodes)
    return positions.error(fmt::format("expected {} positions (one per mesh node), got {}",
                                       num_nodes, positions.size()));
  ex.positions_m.resize(num_nodes, 3);
  for (std::size_t i = 0; i < positions.size(); ++i) {
    HC_ASSIGN_OR_RETURN(const Eigen::Vector3d p, positions[i].vector<3>());
    ex.positions_m.row(static_cast<Eigen::Index>(i)) = p.transpose();
  }

  ex.visible.assign(static_cast<std::size_t>(num_nodes), 1);
  if (const auto vis = j.find("visible")) {
    HC_RETURN_IF_ERROR(vis->expect_array());
    if (static_cast<Eigen::Index>(vis->size()) != num_nodes)
      return vis->error(
          fmt::format("expected {} flags (one per mesh node), got {}", num_nodes, vis->size()));
    for (std::size_t i = 0; i < vis->size(); ++i) {
      const JsonNode v = (*vis)[i];
      if (v.json().is_boolean()) {
        ex.visible[i] = v.json().get<bool>() ? 1 : 0;
      } else {
        HC_ASSIGN_OR_RETURN(ex.visible[i], v.integer<std::uint8_t>(Bounds::between(0, 1)));
      }
    }
  }

  HC_ASSIGN_OR_RETURN(const JsonNode fixed, j.member("fixed_nodes"));
  HC_RETURN_IF_ERROR(fixed.expect_array());
  for (std::size_t i = 0; i < fixed.size(); ++i) {
    HC_ASSIGN_OR_RETURN(const int n, node_index(fixed[i], num_nodes));
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
  const JsonNode root(doc, name);
  HC_RETURN_IF_ERROR(root.only_keys({"format", "version", "units", "mesh", "examples"}));
  HC_ASSIGN_OR_RETURN(const JsonNode format, root.member("format"));
  HC_ASSIGN_OR_RETURN(const std::string format_name, format.string());
  if (format_name != kSamplesFormat)
    return format.error(fmt::format("expected '{}', got '{}'", kSamplesFormat, format_name));
  HC_ASSIGN_OR_RETURN(const JsonNode version, root.member("version"));
  HC_ASSIGN_OR_RETURN(const std::int64_t v, version.integer<std::int64_t>());
  if (v != kSamplesVersion)
    return version.error(
        fmt::format("unknown version {} (this build reads version {})", v, kSamplesVersion));
  if (const auto units = root.find("units")) {
    HC_RETURN_IF_ERROR(units->only_keys({"length", "force"}));
    if (const auto l = units->find("length")) {
      HC_ASSIGN_OR_RETURN(const std::string u, l->string());
      if (u != "m") return l->error(fmt::format("expected 'm', got '{}'", u));
    }
    if (const auto f = units->find("force")) {
      HC_ASSIGN_OR_RETURN(const std::string u, f->string());
      if (u != "N") return f->error(fmt::format("expected 'N', got '{}'", u));
    }
  }

  Samples samples;
  HC_ASSIGN_OR_RETURN(const JsonNode mesh, root.member("mesh"));
  HC_RETURN_IF_ERROR(mesh.expect_object());
  if (mesh.has("node_file") || mesh.has("ele_file")) {
    HC_RETURN_IF_ERROR(mesh.only_keys({"node_file", "ele_file"}));
    HC_RETURN_IF_ERROR(mesh.get("node_file", samples.node_file));
    HC_RETURN_IF_ERROR(mesh.get("ele_file", samples.ele_file));
    const std::filesystem::path node_path = base_dir / samples.node_file;
    const std::filesystem::path ele_path = base_dir / samples.ele_file;
    HC_ASSIGN_OR_RETURN(std::string node_bytes, read_file(node_path));
    HC_ASSIGN_OR_RETURN(std::string ele_bytes, read_file(ele_path));
    Result<TetMesh> m = parse_tetgen(node_bytes, ele_bytes, node_path.string(), ele_path.string());
    if (!m.ok()) return m.status().with_context(std::string(name));
    samples.mesh = std::move(m).value();
  } else {
    HC_RETURN_IF_ERROR(mesh.only_keys({"nodes", "tets"}));
    HC_ASSIGN_OR_RETURN(samples.mesh, read_inline_mesh(mesh));
  }
  if (Status s = validate_mesh(samples.mesh, "mesh"); !s.ok())
    return s.with_context(std::string(name));

  HC_ASSIGN_OR_RETURN(const JsonNode examples, root.member("examples"));
  HC_RETURN_IF_ERROR(examples.expect_array(1));
  for (std::size_t i = 0; i < examples.size(); ++i) {
    HC_ASSIGN_OR_RETURN(Example ex, read_example(examples[i], samples.mesh.num_nodes()));
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
