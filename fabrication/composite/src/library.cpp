#include "fabrication/composite/library.h"

#include <fmt/format.h>

#include <cmath>
#include <set>

#include "common/file_io.h"
#include "json_reader.h"

namespace hc::composite {
namespace {

using detail::item_path;
using detail::JsonReader;

Result<std::array<std::uint8_t, 3>> parse_colour(const JsonReader& rd, const Json& j,
                                                 std::string_view path) {
  std::string s;
  HC_RETURN_IF_ERROR(rd.string(j, path, &s));
  const auto hex = [](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
  };
  std::array<std::uint8_t, 3> out{};
  bool ok = s.size() == 7 && s[0] == '#';
  for (int i = 0; ok && i < 3; ++i) {
    const int hi = hex(s[static_cast<std::size_t>(1 + 2 * i)]);
    const int lo = hex(s[static_cast<std::size_t>(2 + 2 * i)]);
    ok = hi >= 0 && lo >= 0;
    out[static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(16 * std::max(hi, 0) + std::max(lo, 0));
  }
  if (!ok) return rd.error(path, fmt::format("expected an opaque colour \"#RRGGBB\", got \"{}\"", s));
  return out;
}

Status check_name(const JsonReader& rd, const std::string& name, std::string_view path) {
  if (name.empty()) return rd.error(path, "must not be empty");
  for (const char c : name)
    if (static_cast<unsigned char>(c) < 0x20)
      return rd.error(path, "must not contain control characters");
  return {};
}

}  // namespace

Result<BaseMaterialFile> parse_base_material(std::string_view text, std::string_view name) {
  HC_ASSIGN_OR_RETURN(const Json j, parse_json(text, name));
  const JsonReader rd(name);
  HC_RETURN_IF_ERROR(rd.object(j, ""));
  HC_RETURN_IF_ERROR(rd.only_keys(j, "", {"format", "version", "name", "printer_material", "model",
                                          "units", "centres", "values", "limits", "fit"}));
  HC_RETURN_IF_ERROR(rd.header(j, kBaseMaterialFormat, kBaseMaterialVersion));
  std::string material_name, printer_material;
  HC_ASSIGN_OR_RETURN(const Json* jn, rd.member(j, "", "name"));
  HC_RETURN_IF_ERROR(rd.string(*jn, "name", &material_name));
  HC_RETURN_IF_ERROR(check_name(rd, material_name, "name"));
  if (const Json* pm = rd.optional(j, "printer_material"))
    HC_RETURN_IF_ERROR(rd.string(*pm, "printer_material", &printer_material));
  if (const Json* u = rd.optional(j, "units")) {
    HC_RETURN_IF_ERROR(rd.object(*u, "units"));
    HC_RETURN_IF_ERROR(rd.only_keys(*u, "units", {"stress"}));
    HC_ASSIGN_OR_RETURN(const Json* us, rd.member(*u, "units", "stress"));
    std::string stress;
    HC_RETURN_IF_ERROR(rd.string(*us, "units.stress", &stress));
    if (stress != "Pa")
      return rd.error("units.stress",
                      fmt::format("expected \"Pa\" (values are SI), got \"{}\"", stress));
  }
  HC_ASSIGN_OR_RETURN(const Json* jm, rd.member(j, "", "model"));
  std::string model_name;
  HC_RETURN_IF_ERROR(rd.string(*jm, "model", &model_name));
  Result<BaseModel> model = base_model_from_string(model_name);
  if (!model.ok()) return rd.error("model", model.status().message());
  Eigen::MatrixXd centres, values;
  HC_ASSIGN_OR_RETURN(const Json* jc, rd.member(j, "", "centres"));
  HC_RETURN_IF_ERROR(rd.matrix(*jc, "centres", feature_count(*model), 1, &centres));
  HC_ASSIGN_OR_RETURN(const Json* jv, rd.member(j, "", "values"));
  HC_RETURN_IF_ERROR(rd.matrix(*jv, "values", parameter_count(*model), 1, &values));
  if (values.rows() != centres.rows())
    return rd.error("values", fmt::format("{} parameter vectors for {} centres", values.rows(),
                                          centres.rows()));
  FeasibilityLimits limits;
  HC_ASSIGN_OR_RETURN(const Json* jl, rd.member(j, "", "limits"));
  HC_RETURN_IF_ERROR(rd.object(*jl, "limits"));
  HC_RETURN_IF_ERROR(rd.only_keys(*jl, "limits", {"min_modulus_pa", "min_poisson", "max_poisson"}));
  HC_ASSIGN_OR_RETURN(const Json* lm, rd.member(*jl, "limits", "min_modulus_pa"));
  HC_RETURN_IF_ERROR(rd.number(*lm, "limits.min_modulus_pa", &limits.min_modulus_pa));
  if (const Json* v = rd.optional(*jl, "min_poisson"))
    HC_RETURN_IF_ERROR(rd.number(*v, "limits.min_poisson", &limits.min_poisson));
  if (const Json* v = rd.optional(*jl, "max_poisson"))
    HC_RETURN_IF_ERROR(rd.number(*v, "limits.max_poisson", &limits.max_poisson));
  if (Status s = limits.validate(); !s.ok()) return rd.error("limits", s.message());
  Result<BaseMaterial> m = BaseMaterial::create(*model, centres, values, limits);
  if (!m.ok()) return rd.error("centres", m.status().message());
  Json fit;
  if (const Json* f = rd.optional(j, "fit")) {
    HC_RETURN_IF_ERROR(rd.object(*f, "fit"));
    fit = *f;
  }
  return BaseMaterialFile{std::move(material_name), std::move(printer_material),
                          std::move(m).value(), std::move(fit)};
}

Result<BaseMaterialFile> read_base_material(const std::filesystem::path& path) {
  HC_ASSIGN_OR_RETURN(const std::string text, read_file(path));
  return parse_base_material(text, path.string());
}

Json base_material_to_json(const BaseMaterialFile& file) {
  const BaseMaterial& m = file.material;
  Json j = {{"format", kBaseMaterialFormat},
            {"version", kBaseMaterialVersion},
            {"name", file.name},
            {"model", to_string(m.model())},
            {"units", {{"stress", "Pa"}}},
            {"centres", eigen_to_json(m.centres())},
            {"values", eigen_to_json(m.values())},
            {"limits",
             {{"min_modulus_pa", m.limits().min_modulus_pa},
              {"min_poisson", m.limits().min_poisson},
              {"max_poisson", m.limits().max_poisson}}}};
  if (!file.printer_material.empty()) j["printer_material"] = file.printer_material;
  if (file.fit.is_object()) j["fit"] = file.fit;
  return j;
}

Status save_base_material(const std::filesystem::path& path, const BaseMaterialFile& file) {
  return write_file_atomic(path, dump_json(base_material_to_json(file)));
}

std::vector<BaseMaterial> Library::models() const {
  std::vector<BaseMaterial> out;
  for (const LibraryEntry& e : materials) out.push_back(e.base.material);
  return out;
}

std::vector<std::string> Library::names() const {
  std::vector<std::string> out;
  for (const LibraryEntry& e : materials) out.push_back(e.name);
  return out;
}

std::optional<int> Library::find(std::string_view name) const {
  for (std::size_t i = 0; i < materials.size(); ++i)
    if (materials[i].name == name) return static_cast<int>(i);
  return std::nullopt;
}

std::array<std::uint8_t, 3> default_colour(int i, int n) {
  // Evenly spaced hues at full saturation, value 0.85 (HSV -> RGB).
  const double h = 6.0 * static_cast<double>(i) / std::max(n, 1);
  const double v = 0.85, c = v, x = c * (1 - std::abs(std::fmod(h, 2.0) - 1));
  double r = 0, g = 0, b = 0;
  switch (static_cast<int>(h) % 6) {
    case 0: r = c; g = x; break;
    case 1: r = x; g = c; break;
    case 2: g = c; b = x; break;
    case 3: g = x; b = c; break;
    case 4: r = x; b = c; break;
    default: r = c; b = x; break;
  }
  const auto byte = [](double u) { return static_cast<std::uint8_t>(std::lround(255 * u)); };
  return {byte(r), byte(g), byte(b)};
}

Result<Library> parse_library(std::string_view text, std::string_view name,
                              const std::filesystem::path& base_dir) {
  HC_ASSIGN_OR_RETURN(const Json j, parse_json(text, name));
  const JsonReader rd(name);
  HC_RETURN_IF_ERROR(rd.object(j, ""));
  HC_RETURN_IF_ERROR(rd.only_keys(j, "", {"materials"}));
  HC_ASSIGN_OR_RETURN(const Json* jm, rd.member(j, "", "materials"));
  HC_RETURN_IF_ERROR(rd.array(*jm, "materials"));
  if (jm->empty()) return rd.error("materials", "the library lists no base materials");
  Library lib;
  std::set<std::string> seen;
  for (std::size_t i = 0; i < jm->size(); ++i) {
    const Json& e = (*jm)[i];
    const std::string path = item_path("materials", i);
    HC_RETURN_IF_ERROR(rd.object(e, path));
    HC_RETURN_IF_ERROR(rd.only_keys(e, path, {"name", "file", "printer_material", "colour"}));
    std::string entry_name, printer_material, file;
    HC_ASSIGN_OR_RETURN(const Json* n, rd.member(e, path, "name"));
    HC_RETURN_IF_ERROR(rd.string(*n, path + ".name", &entry_name));
    HC_RETURN_IF_ERROR(check_name(rd, entry_name, path + ".name"));
    if (!seen.insert(entry_name).second)
      return rd.error(path + ".name", fmt::format("'{}' is listed twice", entry_name));
    HC_ASSIGN_OR_RETURN(const Json* f, rd.member(e, path, "file"));
    HC_RETURN_IF_ERROR(rd.string(*f, path + ".file", &file));
    if (file.empty()) return rd.error(path + ".file", "must not be empty");
    const std::filesystem::path resolved =
        std::filesystem::path(file).is_absolute() ? std::filesystem::path(file) : base_dir / file;
    if (const Json* pm = rd.optional(e, "printer_material"))
      HC_RETURN_IF_ERROR(rd.string(*pm, path + ".printer_material", &printer_material));
    std::array<std::uint8_t, 3> colour =
        default_colour(static_cast<int>(i), static_cast<int>(jm->size()));
    if (const Json* c = rd.optional(e, "colour")) {
      HC_ASSIGN_OR_RETURN(colour, parse_colour(rd, *c, path + ".colour"));
    }
    Result<BaseMaterialFile> base = read_base_material(resolved);
    if (!base.ok()) return base.status().with_context(fmt::format("{}: {}", name, path));
    if (printer_material.empty()) printer_material = base->printer_material;
    if (printer_material.empty()) printer_material = entry_name;
    LibraryEntry entry{std::move(entry_name), std::move(printer_material), resolved, colour,
                       std::move(base).value()};
    lib.materials.push_back(std::move(entry));
  }
  return lib;
}

Result<Library> read_library(const std::filesystem::path& path) {
  HC_ASSIGN_OR_RETURN(const std::string text, read_file(path));
  return parse_library(text, path.string(), path.parent_path());
}

}  // namespace hc::composite
