#include "processing/material/material.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "common/file_io.h"
#include "common/json_reader.h"

namespace hc::material {
namespace {

// Refuse absurd basis sizes before allocating (a fitted basis has at most the number of examples).
constexpr std::size_t kMaxCentres = 100000;

Result<StrainRbf> read_rbf(const JsonNode& j) {
  StrainRbf rbf;
  HC_RETURN_IF_ERROR(
      j.only_keys({"centres", "weights", "constant", "lambda_floor_pa", "max_poisson"}));
  HC_ASSIGN_OR_RETURN(const JsonNode centres, j.member("centres"));
  HC_ASSIGN_OR_RETURN(const JsonNode weights, j.member("weights"));
  HC_RETURN_IF_ERROR(centres.expect_array());
  HC_RETURN_IF_ERROR(weights.expect_array());
  if (centres.size() > kMaxCentres)
    return centres.error(fmt::format("too many centres ({} > {})", centres.size(), kMaxCentres));
  if (weights.size() != centres.size())
    return weights.error(fmt::format("expected {} weights (one per centre), got {}", centres.size(),
                                     weights.size()));
  rbf.centres.resize(centres.size());
  rbf.weights.resize(static_cast<Eigen::Index>(weights.size()), 2);
  for (std::size_t i = 0; i < centres.size(); ++i) {
    HC_ASSIGN_OR_RETURN(rbf.centres[i], centres[i].vector<6>());
    HC_ASSIGN_OR_RETURN(const Eigen::Vector2d w, weights[i].vector<2>());
    rbf.weights.row(static_cast<Eigen::Index>(i)) = w.transpose();
  }
  HC_RETURN_IF_ERROR(j.get("constant", rbf.constant));
  HC_ASSIGN_OR_RETURN(const JsonNode floor, j.member("lambda_floor_pa"));
  HC_ASSIGN_OR_RETURN(rbf.lambda_floor_pa, floor.number());
  if (!(rbf.lambda_floor_pa > 0)) return floor.error("must be > 0");
  if (const auto mp = j.find("max_poisson")) {
    HC_ASSIGN_OR_RETURN(rbf.max_poisson, mp->number());
    if (!(rbf.max_poisson > 0 && rbf.max_poisson < 0.5)) return mp->error("must be in (0, 0.5)");
  }
  return rbf;
}

Json rbf_to_json(const StrainRbf& rbf) {
  Json centres = Json::array();
  for (const Vector6d& c : rbf.centres) centres.push_back(eigen_to_json(c));
  Json weights = Json::array();
  for (Eigen::Index i = 0; i < rbf.weights.rows(); ++i)
    weights.push_back({rbf.weights(i, 0), rbf.weights(i, 1)});
  return {{"centres", std::move(centres)},
          {"weights", std::move(weights)},
          {"constant", eigen_to_json(rbf.constant)},
          {"lambda_floor_pa", rbf.lambda_floor_pa},
          {"max_poisson", rbf.max_poisson}};
}

}  // namespace

LambdaAlpha project_valid(const Eigen::Vector2d& p, double lambda_floor_pa, double max_poisson) {
  LambdaAlpha out;
  out.lambda = std::max(p(0), lambda_floor_pa);
  out.alpha = std::clamp(p(1), 0.0, max_poisson * out.lambda);
  return out;
}

Eigen::Vector2d StrainRbf::evaluate_raw(const Vector6d& strain) const {
  Eigen::Vector2d p = constant;
  for (std::size_t i = 0; i < centres.size(); ++i)
    p += (strain - centres[i]).norm() * weights.row(static_cast<Eigen::Index>(i)).transpose();
  return p;
}

LambdaAlpha StrainRbf::evaluate(const Vector6d& strain) const {
  return project_valid(evaluate_raw(strain), lambda_floor_pa, max_poisson);
}

Status StrainRbf::validate() const {
  if (weights.rows() != size())
    return invalid_argument(
        fmt::format("weights: expected {} rows (one per centre), got {}", size(), weights.rows()));
  for (std::size_t i = 0; i < centres.size(); ++i)
    if (!centres[i].allFinite()) return invalid_argument(fmt::format("centres[{}]: not finite", i));
  if (!weights.allFinite()) return invalid_argument("weights: not finite");
  if (!constant.allFinite()) return invalid_argument("constant: not finite");
  if (!(std::isfinite(lambda_floor_pa) && lambda_floor_pa > 0))
    return invalid_argument("lambda_floor_pa: must be a finite number > 0");
  if (!(max_poisson > 0 && max_poisson < 0.5))
    return invalid_argument("max_poisson: must be in (0, 0.5)");
  return {};
}

Eigen::Index Material::num_elements() const {
  if (kind == MaterialKind::kHeterogeneous) return static_cast<Eigen::Index>(rbfs.size());
  return element_material.empty() ? -1 : static_cast<Eigen::Index>(element_material.size());
}

const StrainRbf& Material::rbf_of(Eigen::Index element) const {
  if (kind == MaterialKind::kHeterogeneous) return rbfs[static_cast<std::size_t>(element)];
  if (element_material.empty()) return rbfs.front();
  return rbfs[static_cast<std::size_t>(element_material[static_cast<std::size_t>(element)])];
}

Status Material::validate() const {
  if (rbfs.empty()) return invalid_argument("material has no RBF");
  const char* what = kind == MaterialKind::kHeterogeneous ? "elements" : "materials";
  for (std::size_t i = 0; i < rbfs.size(); ++i)
    if (Status s = rbfs[i].validate(); !s.ok())
      return s.with_context(fmt::format("{}[{}]", what, i));
  if (kind == MaterialKind::kHeterogeneous) {
    if (!names.empty() || !element_material.empty())
      return invalid_argument("a heterogeneous material has no names or element_material");
  } else {
    if (names.size() != rbfs.size())
      return invalid_argument(
          fmt::format("materials: {} names for {} materials", names.size(), rbfs.size()));
    for (std::size_t i = 0; i < element_material.size(); ++i)
      if (element_material[i] < 0 || static_cast<std::size_t>(element_material[i]) >= rbfs.size())
        return invalid_argument(
            fmt::format("element_material[{}]: {} is out of range ({} materials)", i,
                        element_material[i], rbfs.size()));
  }
  return {};
}

LambdaAlpha RbfMaterial::params(Eigen::Index element, const Vector6d& strain) const {
  return material_.rbf_of(element).evaluate(strain);
}

Result<Material> parse_material(std::string_view text, std::string_view name) {
  HC_ASSIGN_OR_RETURN(Json doc, parse_json(text, name));
  const JsonNode root(doc, name);
  HC_ASSIGN_OR_RETURN(const JsonNode format, root.member("format"));
  HC_ASSIGN_OR_RETURN(std::string s, format.string());
  if (s != kMaterialFormat)
    return format.error(fmt::format("expected '{}', got '{}'", kMaterialFormat, s));
  HC_ASSIGN_OR_RETURN(const JsonNode version, root.member("version"));
  HC_ASSIGN_OR_RETURN(const std::int64_t v, version.integer<std::int64_t>());
  if (v != kMaterialVersion)
    return version.error(
        fmt::format("unknown version {} (this build reads version {})", v, kMaterialVersion));
  HC_ASSIGN_OR_RETURN(const JsonNode kind, root.member("kind"));
  HC_ASSIGN_OR_RETURN(s, kind.string());
  Material m;
  if (s == "heterogeneous") {
    m.kind = MaterialKind::kHeterogeneous;
    HC_RETURN_IF_ERROR(root.only_keys({"format", "version", "kind", "elements"}));
    HC_ASSIGN_OR_RETURN(const JsonNode elements, root.member("elements"));
    HC_RETURN_IF_ERROR(elements.expect_array(1));
    for (std::size_t i = 0; i < elements.size(); ++i) {
      HC_ASSIGN_OR_RETURN(StrainRbf rbf, read_rbf(elements[i]));
      m.rbfs.push_back(std::move(rbf));
    }
  } else if (s == "base") {
    m.kind = MaterialKind::kBase;
    HC_RETURN_IF_ERROR(
        root.only_keys({"format", "version", "kind", "materials", "element_material"}));
    HC_ASSIGN_OR_RETURN(const JsonNode materials, root.member("materials"));
    HC_RETURN_IF_ERROR(materials.expect_array(1));
    for (std::size_t i = 0; i < materials.size(); ++i) {
      const JsonNode mj = materials[i];
      HC_RETURN_IF_ERROR(mj.only_keys({"name", "rbf"}));
      std::string material_name;
      HC_RETURN_IF_ERROR(mj.get("name", material_name));
      HC_ASSIGN_OR_RETURN(const JsonNode rj, mj.member("rbf"));
      HC_ASSIGN_OR_RETURN(StrainRbf rbf, read_rbf(rj));
      m.names.push_back(std::move(material_name));
      m.rbfs.push_back(std::move(rbf));
    }
    if (const auto em = root.find("element_material")) {
      HC_RETURN_IF_ERROR(em->expect_array(1));
      for (std::size_t i = 0; i < em->size(); ++i) {
        HC_ASSIGN_OR_RETURN(const std::size_t k, (*em)[i].index(m.rbfs.size()));
        m.element_material.push_back(static_cast<int>(k));
      }
    }
  } else {
    return kind.error(fmt::format("unknown kind '{}' (expected heterogeneous or base)", s));
  }
  if (Status st = m.validate(); !st.ok()) return st.with_context(std::string(name));
  return m;
}

Result<Material> read_material(const std::filesystem::path& path) {
  HC_ASSIGN_OR_RETURN(std::string text, read_file(path));
  return parse_material(text, path.string());
}

Result<std::unique_ptr<fem::MaterialModel>> load_material(const std::filesystem::path& path) {
  HC_ASSIGN_OR_RETURN(Material m, read_material(path));
  return std::unique_ptr<fem::MaterialModel>(std::make_unique<RbfMaterial>(std::move(m)));
}

Json material_to_json(const Material& material) {
  Json doc = {{"format", kMaterialFormat}, {"version", kMaterialVersion}};
  if (material.kind == MaterialKind::kHeterogeneous) {
    doc["kind"] = "heterogeneous";
    Json elements = Json::array();
    for (const StrainRbf& rbf : material.rbfs) elements.push_back(rbf_to_json(rbf));
    doc["elements"] = std::move(elements);
  } else {
    doc["kind"] = "base";
    Json materials = Json::array();
    for (std::size_t i = 0; i < material.rbfs.size(); ++i)
      materials.push_back({{"name", material.names[i]}, {"rbf", rbf_to_json(material.rbfs[i])}});
    doc["materials"] = std::move(materials);
    if (!material.element_material.empty()) doc["element_material"] = material.element_material;
  }
  return doc;
}

Status save_material(const std::filesystem::path& path, const Material& material) {
  HC_RETURN_IF_ERROR(material.validate());
  return write_file_atomic(path, dump_json(material_to_json(material)));
}

}  // namespace hc::material
