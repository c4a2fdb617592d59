#include "fabrication/composite/design_file.h"

#include <fmt/format.h>

#include <map>
#include <set>

#include "common/file_io.h"
#include "json_reader.h"

namespace hc::composite {
namespace {

using detail::item_path;
using detail::JsonReader;

// The design's box must be the specimen's to this fraction of the box's diagonal.
constexpr double kSpecimenTolerance = 1e-6;

std::string colour_string(const std::array<std::uint8_t, 3>& c) {
  return fmt::format("#{:02X}{:02X}{:02X}", c[0], c[1], c[2]);
}

// Owns the base materials that a CompositeMaterial points into.
class DesignMaterialModel final : public fem::MaterialModel {
 public:
  DesignMaterialModel(std::vector<BaseMaterial> library, const std::vector<int>& per_element)
      : library_(std::move(library)), composite_(pointers(library_, per_element)) {}
  fem::LambdaAlpha params(Eigen::Index e, const Vector6d& s) const override {
    return composite_.params(e, s);
  }
  Matrix6d elasticity(Eigen::Index e, const Vector6d& s) const override {
    return composite_.elasticity(e, s);
  }
  bool anisotropic() const override { return composite_.anisotropic(); }
  Eigen::Index num_elements() const override { return composite_.num_elements(); }

 private:
  static std::vector<const BaseMaterial*> pointers(const std::vector<BaseMaterial>& lib,
                                                   const std::vector<int>& per_element) {
    std::vector<const BaseMaterial*> out;
    for (int m : per_element) out.push_back(&lib[static_cast<std::size_t>(m)]);
    return out;
  }
  std::vector<BaseMaterial> library_;
  CompositeMaterial composite_;
};

Result<std::vector<double>> read_axis(const JsonReader& rd, const Json& cells, const char* key) {
  const std::string path = std::string("cells.") + key;
  HC_ASSIGN_OR_RETURN(const Json* a, rd.member(cells, "cells", key));
  HC_RETURN_IF_ERROR(rd.array(*a, path, 2));
  std::vector<double> out(a->size());
  for (std::size_t i = 0; i < a->size(); ++i)
    HC_RETURN_IF_ERROR(rd.number((*a)[i], item_path(path, i), &out[i]));
  return out;
}

}  // namespace

DesignFile make_design_file(const CellGrid& grid, const Library& library,
                            const std::vector<int>& cells, Json report) {
  DesignFile d;
  d.grid = grid;
  d.report = std::move(report);
  std::map<int, int> remap;
  for (int m : cells) {
    if (remap.count(m)) continue;
    remap[m] = static_cast<int>(d.materials.size());
    const LibraryEntry& e = library.materials[static_cast<std::size_t>(m)];
    d.materials.push_back({e.name, e.printer_material, e.colour, e.base});
  }
  for (int m : cells) d.cells.push_back(remap[m]);
  return d;
}

Json design_to_json(const DesignFile& d) {
  Json materials = Json::array();
  for (const DesignMaterial& m : d.materials)
    materials.push_back({{"name", m.name},
                         {"printer_material", m.printer_material},
                         {"colour", colour_string(m.colour)},
                         {"base", base_material_to_json(m.base)}});
  Json names = Json::array();
  for (int c : d.cells) names.push_back(d.materials[static_cast<std::size_t>(c)].name);
  const Eigen::AlignedBox3d box = d.grid.box();
  Json j = {{"format", kDesignFormat},
            {"version", kDesignVersion},
            {"specimen", {{"box_m", Json::array({eigen_to_json(box.min()), eigen_to_json(box.max())})}}},
            {"cells", {{"x_m", d.grid.x_m()}, {"y_m", d.grid.y_m()}, {"z_m", d.grid.z_m()}}},
            {"materials", std::move(materials)},
            {"design", std::move(names)}};
  if (d.report.is_object()) j["report"] = d.report;
  return j;
}

Status save_design(const std::filesystem::path& path, const DesignFile& design) {
  return write_file_atomic(path, dump_json(design_to_json(design)));
}

bool is_design_document(std::string_view text) {
  Result<Json> j = parse_json(text, "");
  if (!j.ok() || !j->is_object()) return false;
  const auto it = j->find("format");
  return it != j->end() && it->is_string() && it->get<std::string>() == kDesignFormat;
}

Result<DesignFile> parse_design(std::string_view text, std::string_view name) {
  HC_ASSIGN_OR_RETURN(const Json j, parse_json(text, name));
  const JsonReader rd(name);
  HC_RETURN_IF_ERROR(rd.object(j, ""));
  HC_RETURN_IF_ERROR(rd.only_keys(
      j, "", {"format", "version", "specimen", "cells", "materials", "design", "report"}));
  HC_RETURN_IF_ERROR(rd.header(j, kDesignFormat, kDesignVersion));
  DesignFile d;
  HC_ASSIGN_OR_RETURN(const Json* cells, rd.member(j, "", "cells"));
  HC_RETURN_IF_ERROR(rd.object(*cells, "cells"));
  HC_RETURN_IF_ERROR(rd.only_keys(*cells, "cells", {"x_m", "y_m", "z_m"}));
  HC_ASSIGN_OR_RETURN(std::vector<double> xs, read_axis(rd, *cells, "x_m"));
  HC_ASSIGN_OR_RETURN(std::vector<double> ys, read_axis(rd, *cells, "y_m"));
  HC_ASSIGN_OR_RETURN(std::vector<double> zs, read_axis(rd, *cells, "z_m"));
  Result<CellGrid> grid = CellGrid::from_boundaries(std::move(xs), std::move(ys), std::move(zs));
  if (!grid.ok()) return rd.error("cells", grid.status().message());
  d.grid = std::move(grid).value();
  HC_ASSIGN_OR_RETURN(const Json* spec, rd.member(j, "", "specimen"));
  HC_RETURN_IF_ERROR(rd.object(*spec, "specimen"));
  HC_RETURN_IF_ERROR(rd.only_keys(*spec, "specimen", {"box_m"}));
  HC_ASSIGN_OR_RETURN(const Json* bj, rd.member(*spec, "specimen", "box_m"));
  Eigen::MatrixXd box;
  HC_RETURN_IF_ERROR(rd.matrix(*bj, "specimen.box_m", 3, 2, &box));
  if (box.rows() != 2) return rd.error("specimen.box_m", "expected [[x0, y0, z0], [x1, y1, z1]]");
  const Eigen::AlignedBox3d cb = d.grid.box();
  const double tol = kSpecimenTolerance * cb.diagonal().norm();
  if ((box.row(0).transpose() - cb.min()).norm() > tol || (box.row(1).transpose() - cb.max()).norm() > tol)
    return rd.error("specimen.box_m", "does not match the cells' outer boundaries");
  HC_ASSIGN_OR_RETURN(const Json* mats, rd.member(j, "", "materials"));
  HC_RETURN_IF_ERROR(rd.array(*mats, "materials", 1));
  std::map<std::string, int> index;
  for (std::size_t i = 0; i < mats->size(); ++i) {
    const std::string path = item_path("materials", i);
    const Json& e = (*mats)[i];
    HC_RETURN_IF_ERROR(rd.object(e, path));
    HC_RETURN_IF_ERROR(rd.only_keys(e, path, {"name", "printer_material", "colour", "base"}));
    std::string mname, printer, colour;
    HC_ASSIGN_OR_RETURN(const Json* n, rd.member(e, path, "name"));
    HC_RETURN_IF_ERROR(rd.string(*n, path + ".name", &mname));
    if (mname.empty() || index.count(mname))
      return rd.error(path + ".name", fmt::format("'{}' is empty or repeated", mname));
    HC_ASSIGN_OR_RETURN(const Json* p, rd.member(e, path, "printer_material"));
    HC_RETURN_IF_ERROR(rd.string(*p, path + ".printer_material", &printer));
    if (printer.empty()) return rd.error(path + ".printer_material", "must not be empty");
    HC_ASSIGN_OR_RETURN(const Json* c, rd.member(e, path, "colour"));
    HC_RETURN_IF_ERROR(rd.string(*c, path + ".colour", &colour));
    std::array<std::uint8_t, 3> rgb{};
    unsigned r = 0, g = 0, b = 0;
    char tail = 0;
    if (colour.size() != 7 || std::sscanf(colour.c_str(), "#%2x%2x%2x%c", &r, &g, &b, &tail) != 3)
      return rd.error(path + ".colour", fmt::format("expected \"#RRGGBB\", got \"{}\"", colour));
    rgb = {static_cast<std::uint8_t>(r), static_cast<std::uint8_t>(g), static_cast<std::uint8_t>(b)};
    HC_ASSIGN_OR_RETURN(const Json* base, rd.member(e, path, "base"));
    Result<BaseMaterialFile> bm = parse_base_material(base->dump(), fmt::format("{}: {}.base", name, path));
    if (!bm.ok()) return bm.status();
    index[mname] = static_cast<int>(d.materials.size());
    d.materials.push_back({std::move(mname), std::move(printer), rgb, std::move(bm).value()});
  }
  HC_ASSIGN_OR_RETURN(const Json* design, rd.member(j, "", "design"));
  HC_RETURN_IF_ERROR(rd.array(*design, "design"));
  if (static_cast<int>(design->size()) != d.grid.num_cells())
    return rd.error("design", fmt::format("{} materials for {} cells", design->size(),
                                          d.grid.num_cells()));
  for (std::size_t c = 0; c < design->size(); ++c) {
    std::string mname;
    HC_RETURN_IF_ERROR(rd.string((*design)[c], item_path("design", c), &mname));
    const auto it = index.find(mname);
    if (it == index.end())
      return rd.error(item_path("design", c), fmt::format("'{}' is not among the materials", mname));
    d.cells.push_back(it->second);
  }
  if (const Json* r = rd.optional(j, "report")) {
    HC_RETURN_IF_ERROR(rd.object(*r, "report"));
    d.report = *r;
  }
  return d;
}

Result<DesignFile> read_design(const std::filesystem::path& path) {
  HC_ASSIGN_OR_RETURN(const std::string text, read_file(path));
  return parse_design(text, path.string());
}

Result<std::unique_ptr<fem::MaterialModel>> design_material(const DesignFile& design,
                                                            const TetMesh& mesh) {
  const Eigen::AlignedBox3d want = design.grid.box();
  const Eigen::AlignedBox3d have = mesh_box(mesh);
  const double tol = kSpecimenTolerance * want.diagonal().norm();
  if ((want.min() - have.min()).norm() > tol || (want.max() - have.max()).norm() > tol) {
    const Eigen::Vector3d ws = 1e3 * want.sizes(), hs = 1e3 * have.sizes();
    return invalid_argument(fmt::format(
        "the design is for a {:.6g} x {:.6g} x {:.6g} mm specimen at ({:.6g}, {:.6g}, {:.6g}) mm, "
        "this specimen is {:.6g} x {:.6g} x {:.6g} mm at ({:.6g}, {:.6g}, {:.6g}) mm",
        ws.x(), ws.y(), ws.z(), 1e3 * want.min().x(), 1e3 * want.min().y(), 1e3 * want.min().z(),
        hs.x(), hs.y(), hs.z(), 1e3 * have.min().x(), 1e3 * have.min().y(), 1e3 * have.min().z()));
  }
  std::vector<BaseMaterial> library;
  for (const DesignMaterial& m : design.materials) library.push_back(m.base.material);
  std::vector<int> per_element;
  for (int c : element_cells(mesh, design.grid))
    per_element.push_back(design.cells[static_cast<std::size_t>(c)]);
  return std::unique_ptr<fem::MaterialModel>(
      std::make_unique<DesignMaterialModel>(std::move(library), per_element));
}

printfile::MultiMaterialModel design_print_model(const DesignFile& design, std::string object_name) {
  printfile::MultiMaterialModel out;
  std::map<std::string, int> extruder;
  std::vector<int> material_extruder;
  for (const DesignMaterial& m : design.materials) {
    auto it = extruder.find(m.printer_material);
    if (it == extruder.end()) {
      it = extruder.emplace(m.printer_material, static_cast<int>(out.materials.size())).first;
      out.materials.push_back({m.printer_material, m.colour});
    }
    material_extruder.push_back(it->second);
  }
  printfile::PrintObject object;
  object.name = std::move(object_name);
  const Eigen::Vector3i n = design.grid.counts();
  for (int c = 0; c < design.grid.num_cells(); ++c) {
    const DesignMaterial& m = design.materials[static_cast<std::size_t>(design.cells[static_cast<std::size_t>(c)])];
    const std::string cell = design.grid.is_layers()
                                 ? fmt::format("layer {}", c + 1)
                                 : fmt::format("cell {} {} {}", c % n.x() + 1, (c / n.x()) % n.y() + 1,
                                               c / (n.x() * n.y()) + 1);
    object.volumes.push_back({fmt::format("{} ({})", cell, m.name),
                              printfile::box_triangles(design.grid.cell_box(c)),
                              material_extruder[static_cast<std::size_t>(design.cells[static_cast<std::size_t>(c)])]});
  }
  out.objects.push_back(std::move(object));
  return out;
}

}  // namespace hc::composite
