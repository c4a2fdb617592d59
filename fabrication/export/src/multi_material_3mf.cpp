#include "fabrication/export/multi_material_3mf.h"

#include <fmt/format.h>

#include <cmath>
#include <memory>
#include <string_view>

#include "Model/COM/NMR_DLLInterfaces.h"
#include "common/file_io.h"

namespace hc::printfile {
namespace {

constexpr double kMillimetresPerMetre = 1000.0;
constexpr std::string_view kSlic3rConfigPath = "/Metadata/Slic3r_PE_model.config";
constexpr std::string_view kBambuConfigPath = "/Metadata/model_settings.config";
// Relationship types of the two attachments (slicers find the files by path; the types only keep
// the package's relationships well-formed).
constexpr std::string_view kSlic3rRelationship =
    "http://schemas.slic3r.org/3mf/2017/06/model-config";
constexpr std::string_view kBambuRelationship =
    "http://schemas.bambulab.com/package/2021/model-settings";

Status check_name(std::string_view name, std::string_view what) {
  if (name.empty()) return invalid_argument(fmt::format("3MF: {} has an empty name", what));
  for (const char c : name)
    if (static_cast<unsigned char>(c) < 0x20)
      return invalid_argument(fmt::format("3MF: {} name contains a control character", what));
  return {};
}

std::string xml_attr(std::string_view s) {
  std::string out;
  for (const char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&apos;"; break;
      default: out.push_back(c);
    }
  }
  return out;
}

// Triangle ranges of an object's volumes in its concatenated mesh.
std::vector<std::pair<Eigen::Index, Eigen::Index>> volume_ranges(const PrintObject& o) {
  std::vector<std::pair<Eigen::Index, Eigen::Index>> out;
  Eigen::Index at = 0;
  for (const PrintVolume& v : o.volumes) {
    out.emplace_back(at, at + v.mesh.num_triangles() - 1);
    at += v.mesh.num_triangles();
  }
  return out;
}

// lib3mf 1.8's C interface: every call returns LIB3MF_OK (0) or an error code; objects are
// reference counted and released with lib3mf_release.
struct Release {
  void operator()(NMR::PLib3MFBase* p) const {
    if (p != nullptr) NMR::lib3mf_release(p);
  }
};
using Handle = std::unique_ptr<NMR::PLib3MFBase, Release>;

Status lib3mf_status(long long r, NMR::PLib3MFBase* instance, std::string_view what) {
  if (r == 0) return {};
  DWORD code = static_cast<DWORD>(r);
  LPCSTR message = nullptr;
  if (instance != nullptr) NMR::lib3mf_getlasterror(instance, &code, &message);
  return io_error(fmt::format("3MF (lib3mf): {} failed (error 0x{:x}{}{})", what, code,
                              message != nullptr ? ": " : "", message != nullptr ? message : ""));
}

#define HC_LIB3MF(call, instance, what) HC_RETURN_IF_ERROR(lib3mf_status((call), (instance), (what)))

Status add_attachment(NMR::PLib3MFModel* model, std::string_view path, std::string_view type,
                      const std::string& text) {
  NMR::PLib3MFModelAttachment* raw = nullptr;
  std::string p(path), t(type);
  HC_LIB3MF(NMR::lib3mf_model_addattachmentutf8(model, p.data(), t.data(), &raw), model,
            fmt::format("adding {}", path));
  const Handle attachment(raw);
  std::string bytes = text;
  HC_LIB3MF(NMR::lib3mf_attachment_readfrombuffer(raw, reinterpret_cast<BYTE*>(bytes.data()),
                                                  bytes.size()),
            raw, fmt::format("filling {}", path));
  return {};
}

Status build_model(NMR::PLib3MFModel* model, const MultiMaterialModel& mm,
                   std::vector<DWORD>* object_ids) {
  HC_LIB3MF(NMR::lib3mf_model_setunit(model, NMR::MODELUNIT_MILLIMETER), model, "setting the unit");
  HC_LIB3MF(NMR::lib3mf_model_addmetadatautf8(model, "Application", "Hardcopy"), model,
            "adding metadata");
  // The attachments' extension needs a content type in the package.
  HC_LIB3MF(NMR::lib3mf_model_addcustomcontenttypeutf8(model, "config", "application/xml"), model,
            "adding the .config content type");
  NMR::PLib3MFModelBaseMaterial* group_raw = nullptr;
  HC_LIB3MF(NMR::lib3mf_model_addbasematerialgroup(model, &group_raw), model,
            "adding basematerials");
  const Handle group(group_raw);
  DWORD group_id = 0;
  HC_LIB3MF(NMR::lib3mf_basematerial_getresourceid(group_raw, &group_id), group_raw, "group id");
  for (const PrintMaterial& m : mm.materials) {
    DWORD index = 0;
    HC_LIB3MF(NMR::lib3mf_basematerial_addmaterialutf8(group_raw, m.name.c_str(), m.rgb[0], m.rgb[1],
                                                        m.rgb[2], &index),
              group_raw, fmt::format("adding material '{}'", m.name));
    // Opaque: lib3mf 1.8 would otherwise leave the display colour's alpha at its default.
    HC_LIB3MF(NMR::lib3mf_basematerial_setdisplaycolorrgba(group_raw, index, m.rgb[0], m.rgb[1],
                                                            m.rgb[2], 255),
              group_raw, "setting a display colour");
  }
  for (const PrintObject& o : mm.objects) {
    std::vector<NMR::MODELMESHVERTEX> vertices;
    std::vector<NMR::MODELMESHTRIANGLE> triangles;
    std::vector<NMR::ModelResourceID> groups;
    std::vector<DWORD> indices;
    for (const PrintVolume& v : o.volumes) {
      const auto base = static_cast<DWORD>(vertices.size());
      for (Eigen::Index i = 0; i < v.mesh.num_vertices(); ++i) {
        NMR::MODELMESHVERTEX p;
        for (int c = 0; c < 3; ++c)
          p.m_fPosition[c] = static_cast<float>(kMillimetresPerMetre * v.mesh.vertices(i, c));
        vertices.push_back(p);
      }
      for (Eigen::Index t = 0; t < v.mesh.num_triangles(); ++t) {
        NMR::MODELMESHTRIANGLE tri;
        for (int c = 0; c < 3; ++c) tri.m_nIndices[c] = base + static_cast<DWORD>(v.mesh.triangles(t, c));
        triangles.push_back(tri);
        groups.push_back(group_id);
        indices.push_back(static_cast<DWORD>(v.material));
      }
    }
    NMR::PLib3MFModelMeshObject* mesh_raw = nullptr;
    HC_LIB3MF(NMR::lib3mf_model_addmeshobject(model, &mesh_raw), model, "adding a mesh object");
    const Handle mesh(mesh_raw);
    HC_LIB3MF(NMR::lib3mf_object_setnameutf8(mesh_raw, o.name.c_str()), mesh_raw, "naming an object");
    HC_LIB3MF(NMR::lib3mf_meshobject_setgeometry(mesh_raw, vertices.data(),
                                                  static_cast<DWORD>(vertices.size()),
                                                  triangles.data(),
                                                  static_cast<DWORD>(triangles.size())),
              mesh_raw, fmt::format("setting the geometry of '{}'", o.name));
    NMR::PLib3MFPropertyHandler* props_raw = nullptr;
    HC_LIB3MF(NMR::lib3mf_meshobject_createpropertyhandler(mesh_raw, &props_raw), mesh_raw,
              "creating a property handler");
    const Handle props(props_raw);
    HC_LIB3MF(NMR::lib3mf_propertyhandler_setbasematerialarray(props_raw, groups.data(), indices.data()),
              props_raw, "assigning materials to triangles");
    NMR::PLib3MFDefaultPropertyHandler* def_raw = nullptr;
    HC_LIB3MF(NMR::lib3mf_object_createdefaultpropertyhandler(mesh_raw, &def_raw), mesh_raw,
              "creating a default property handler");
    const Handle def(def_raw);
    HC_LIB3MF(NMR::lib3mf_defaultpropertyhandler_setbasematerial(
                  def_raw, group_id, static_cast<DWORD>(o.volumes.front().material)),
              def_raw, "setting the object's material");
    DWORD id = 0;
    HC_LIB3MF(NMR::lib3mf_resource_getresourceid(mesh_raw, &id), mesh_raw, "object id");
    object_ids->push_back(id);
    NMR::PLib3MFModelBuildItem* item_raw = nullptr;
    HC_LIB3MF(NMR::lib3mf_model_addbuilditem(model, mesh_raw, nullptr, &item_raw), model,
              "adding a build item");
    const Handle item(item_raw);
  }
  return {};
}

std::string config_document(const MultiMaterialModel& mm, const std::vector<DWORD>& ids,
                            bool bambu) {
  std::string out = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<config>\n";
  for (std::size_t o = 0; o < mm.objects.size(); ++o) {
    const PrintObject& obj = mm.objects[o];
    const std::string type = bambu ? "" : " type=\"object\"";
    out += fmt::format(" <object id=\"{}\"{}>\n", ids[o], bambu ? "" : " instances_count=\"1\"");
    out += fmt::format("  <metadata{} key=\"name\" value=\"{}\"/>\n", type, xml_attr(obj.name));
    const auto ranges = volume_ranges(obj);
    for (std::size_t v = 0; v < obj.volumes.size(); ++v) {
      const PrintVolume& vol = obj.volumes[v];
      const std::string vtype = bambu ? "" : " type=\"volume\"";
      if (bambu)
        out += fmt::format("  <part id=\"{}\" subtype=\"normal_part\" firstid=\"{}\" lastid=\"{}\">\n",
                           v + 1, ranges[v].first, ranges[v].second);
      else
        out += fmt::format("  <volume firstid=\"{}\" lastid=\"{}\">\n", ranges[v].first,
                           ranges[v].second);
      out += fmt::format("   <metadata{} key=\"name\" value=\"{}\"/>\n", vtype, xml_attr(vol.name));
      if (!bambu)
        out += "   <metadata type=\"volume\" key=\"volume_type\" value=\"ModelPart\"/>\n";
      out += fmt::format("   <metadata{} key=\"extruder\" value=\"{}\"/>\n", vtype, vol.material + 1);
      out += bambu ? "  </part>\n" : "  </volume>\n";
    }
    out += " </object>\n";
  }
  out += "</config>\n";
  return out;
}

std::vector<DWORD> sequential_ids(const MultiMaterialModel& mm) {
  // lib3mf numbers resources in creation order: the basematerials group is 1, objects 2, 3, ...
  std::vector<DWORD> ids;
  for (std::size_t o = 0; o < mm.objects.size(); ++o) ids.push_back(static_cast<DWORD>(o + 2));
  return ids;
}

}  // namespace

Status validate(const MultiMaterialModel& model) {
  if (model.materials.empty()) return invalid_argument("3MF: no materials");
  if (model.objects.empty()) return invalid_argument("3MF: no objects");
  for (std::size_t m = 0; m < model.materials.size(); ++m)
    HC_RETURN_IF_ERROR(check_name(model.materials[m].name, fmt::format("material {}", m)));
  for (std::size_t o = 0; o < model.objects.size(); ++o) {
    const PrintObject& obj = model.objects[o];
    const std::string what = fmt::format("object {} ('{}')", o, obj.name);
    HC_RETURN_IF_ERROR(check_name(obj.name, fmt::format("object {}", o)));
    if (obj.volumes.empty()) return invalid_argument(fmt::format("3MF: {} has no volumes", what));
    for (std::size_t v = 0; v < obj.volumes.size(); ++v) {
      const PrintVolume& vol = obj.volumes[v];
      const std::string vw = fmt::format("{} volume {} ('{}')", what, v, vol.name);
      HC_RETURN_IF_ERROR(check_name(vol.name, vw));
      if (vol.mesh.num_triangles() == 0) return invalid_argument(fmt::format("3MF: {} has no triangles", vw));
      if (!vol.mesh.vertices.allFinite())
        return invalid_argument(fmt::format("3MF: {} has non-finite vertices", vw));
      if (vol.mesh.triangles.minCoeff() < 0 || vol.mesh.triangles.maxCoeff() >= vol.mesh.num_vertices())
        return invalid_argument(fmt::format("3MF: {} has vertex indices out of range", vw));
      if (vol.material < 0 || vol.material >= static_cast<int>(model.materials.size()))
        return invalid_argument(fmt::format("3MF: {} uses material {} of {}", vw, vol.material,
                                            model.materials.size()));
    }
  }
  return {};
}

std::string slic3r_model_config(const MultiMaterialModel& model) {
  return config_document(model, sequential_ids(model), /*bambu=*/false);
}
std::string bambu_model_settings(const MultiMaterialModel& model) {
  return config_document(model, sequential_ids(model), /*bambu=*/true);
}

Status write_multi_material_3mf(const std::filesystem::path& path, const MultiMaterialModel& mm) {
  HC_RETURN_IF_ERROR(validate(mm));
  NMR::PLib3MFModel* model_raw = nullptr;
  HC_LIB3MF(NMR::lib3mf_createmodel(&model_raw), nullptr, "creating a model");
  const Handle model(model_raw);
  std::vector<DWORD> ids;
  HC_RETURN_IF_ERROR(build_model(model_raw, mm, &ids));
  if (ids != sequential_ids(mm))
    return internal_error("3MF: lib3mf numbered the objects unexpectedly");
  HC_RETURN_IF_ERROR(add_attachment(model_raw, kSlic3rConfigPath, kSlic3rRelationship,
                                    config_document(mm, ids, false)));
  HC_RETURN_IF_ERROR(add_attachment(model_raw, kBambuConfigPath, kBambuRelationship,
                                    config_document(mm, ids, true)));
  NMR::PLib3MFModelWriter* writer_raw = nullptr;
  HC_LIB3MF(NMR::lib3mf_model_querywriter(model_raw, "3mf", &writer_raw), model_raw,
            "creating the writer");
  const Handle writer(writer_raw);
  return write_file_atomic(path, [&](const std::filesystem::path& tmp) -> Status {
    return lib3mf_status(NMR::lib3mf_writer_writetofileutf8(writer_raw, tmp.string().c_str()),
                         writer_raw, fmt::format("writing {}", path.string()));
  });
}

TriangleMesh box_triangles(const Eigen::AlignedBox3d& box) {
  TriangleMesh m;
  m.vertices.resize(8, 3);
  for (int i = 0; i < 8; ++i)
    m.vertices.row(i) << ((i & 1) ? box.max().x() : box.min().x()),
        ((i & 2) ? box.max().y() : box.min().y()), ((i & 4) ? box.max().z() : box.min().z());
  m.triangles.resize(12, 3);
  // Outward normals: -x, +x, -y, +y, -z, +z faces, two triangles each.
  m.triangles << 0, 4, 6, 0, 6, 2,  //
      1, 3, 7, 1, 7, 5,             //
      0, 1, 5, 0, 5, 4,             //
      2, 6, 7, 2, 7, 3,             //
      0, 2, 3, 0, 3, 1,             //
      4, 5, 7, 4, 7, 6;
  return m;
}

}  // namespace hc::printfile
