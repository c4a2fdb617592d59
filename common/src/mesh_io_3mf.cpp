// 3MF writer: an OPC (zip) package per the 3MF Core Specification 1.x, built with libzip.
#include <zip.h>

#include <map>
#include <utility>

#include "common/file_io.h"
#include "mesh_io_internal.h"

namespace hc::mesh_io {
namespace {

constexpr std::string_view kContentTypes =
    R"(<?xml version="1.0" encoding="UTF-8"?>
<Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types">
 <Default Extension="rels" ContentType="application/vnd.openxmlformats-package.relationships+xml"/>
 <Default Extension="model" ContentType="application/vnd.ms-package.3dmanufacturing-3dmodel+xml"/>
</Types>
)";

constexpr std::string_view kRels =
    R"(<?xml version="1.0" encoding="UTF-8"?>
<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">
 <Relationship Target="/3D/3dmodel.model" Id="rel0" Type="http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"/>
</Relationships>
)";

constexpr std::string_view kCoreNamespace =
    "http://schemas.microsoft.com/3dmanufacturing/core/2015/02";
constexpr std::string_view kModelPath = "3D/3dmodel.model";
// <base displaycolor> is required; parts with a material but no colour are shown mid-grey.
constexpr std::array<std::uint8_t, 4> kDefaultRgba{0x80, 0x80, 0x80, 0xFF};

// XML attribute text. Control characters other than tab/newline/return cannot appear in XML 1.0.
Result<std::string> xml_escape(std::string_view s, std::string_view what) {
  std::string out;
  out.reserve(s.size());
  for (const char ch : s) {
    const auto c = static_cast<unsigned char>(ch);
    switch (ch) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&apos;";
        break;
      case '\t':
        out += "&#9;";
        break;
      case '\n':
        out += "&#10;";
        break;
      case '\r':
        out += "&#13;";
        break;
      default:
        if (c < 0x20)
          return invalid_argument(
              fmt::format("{} {} contains control character 0x{:02x}, which "
                          "XML cannot hold",
                          what, quote(s), c));
        out.push_back(ch);
    }
  }
  return out;
}

struct Material {
  std::string name;
  std::array<std::uint8_t, 4> rgba = kDefaultRgba;
  bool explicit_rgba = false;
  std::string first_part;
};

Result<std::string> build_model_xml(std::span<const MeshPart> parts, units::LengthUnit unit) {
  if (parts.empty()) return invalid_argument("3MF: no parts to write, expected at least one");
  // Materials in first-use order; a name given two different colours is ambiguous.
  std::vector<Material> materials;
  std::map<std::string, std::size_t, std::less<>> material_index;
  for (const MeshPart& part : parts) {
    if (part.material_name.empty()) continue;
    auto it = material_index.find(part.material_name);
    if (it == material_index.end()) {
      it = material_index.emplace(part.material_name, materials.size()).first;
      materials.push_back(Material{part.material_name, kDefaultRgba, false, part.name});
    }
    Material& m = materials[it->second];
    if (!part.rgba) continue;
    if (m.explicit_rgba && m.rgba != *part.rgba)
      return invalid_argument(fmt::format(
          "3MF: material '{}' has colour #{:02X}{:02X}{:02X}{:02X} in part '{}' but "
          "#{:02X}{:02X}{:02X}{:02X} in part '{}', expected one colour per material",
          m.name, m.rgba[0], m.rgba[1], m.rgba[2], m.rgba[3], m.first_part, (*part.rgba)[0],
          (*part.rgba)[1], (*part.rgba)[2], (*part.rgba)[3], part.name));
    m.rgba = *part.rgba;
    m.explicit_rgba = true;
    m.first_part = part.name;
  }

  std::size_t total = 0;
  for (const MeshPart& part : parts)
    total += static_cast<std::size_t>(part.mesh.num_vertices()) * 80 +
             static_cast<std::size_t>(part.mesh.num_triangles()) * 50;
  std::string xml;
  xml.reserve(total + 1024);
  xml += R"(<?xml version="1.0" encoding="UTF-8"?>)";
  xml += fmt::format("\n<model unit=\"{}\" xml:lang=\"en-US\" xmlns=\"{}\">\n <resources>\n",
                     units::to_3mf_name(unit), kCoreNamespace);
  constexpr int kMaterialsId = 1;
  if (!materials.empty()) {
    xml += fmt::format("  <basematerials id=\"{}\">\n", kMaterialsId);
    for (const Material& m : materials) {
      HC_ASSIGN_OR_RETURN(const std::string name, xml_escape(m.name, "3MF: material name"));
      xml += fmt::format("   <base name=\"{}\" displaycolor=\"#{:02X}{:02X}{:02X}{:02X}\"/>\n",
                         name, m.rgba[0], m.rgba[1], m.rgba[2], m.rgba[3]);
    }
    xml += "  </basematerials>\n";
  }
  const int first_object_id = materials.empty() ? 1 : kMaterialsId + 1;
  for (std::size_t i = 0; i < parts.size(); ++i) {
    const MeshPart& part = parts[i];
    const std::string what = fmt::format("3MF part {} ('{}')", i, part.name);
    HC_RETURN_IF_ERROR(check_writable(part.mesh, what));
    if (part.mesh.num_triangles() == 0)
      return invalid_argument(fmt::format("{}: has no triangles, 3MF needs at least one", what));
    HC_ASSIGN_OR_RETURN(const std::string name, xml_escape(part.name, "3MF: part name"));
    xml += fmt::format("  <object id=\"{}\" type=\"model\" name=\"{}\"",
                       first_object_id + static_cast<int>(i), name);
    if (!part.material_name.empty())
      xml += fmt::format(" pid=\"{}\" pindex=\"{}\"", kMaterialsId,
                         material_index.find(part.material_name)->second);
    xml += ">\n   <mesh>\n    <vertices>\n";
    const TriangleMesh& m = part.mesh;
    for (Eigen::Index v = 0; v < m.num_vertices(); ++v) {
      xml += "     <vertex x=\"";
      append_double(xml, m.vertices(v, 0));
      xml += "\" y=\"";
      append_double(xml, m.vertices(v, 1));
      xml += "\" z=\"";
      append_double(xml, m.vertices(v, 2));
      xml += "\"/>\n";
    }
    xml += "    </vertices>\n    <triangles>\n";
    for (Eigen::Index t = 0; t < m.num_triangles(); ++t) {
      const int a = m.triangles(t, 0), b = m.triangles(t, 1), c = m.triangles(t, 2);
      // 3MF Core §4.1.4: a triangle's three vertex indices must differ.
      if (a == b || b == c || a == c)
        return invalid_argument(fmt::format(
            "{}: triangle {} ({} {} {}) repeats a vertex, which 3MF forbids", what, t, a, b, c));
      xml += "     <triangle v1=\"";
      append_int(xml, a);
      xml += "\" v2=\"";
      append_int(xml, b);
      xml += "\" v3=\"";
      append_int(xml, c);
      xml += "\"/>\n";
    }
    xml += "    </triangles>\n   </mesh>\n  </object>\n";
  }
  xml += " </resources>\n <build>\n";
  for (std::size_t i = 0; i < parts.size(); ++i)
    xml += fmt::format("  <item objectid=\"{}\"/>\n", first_object_id + static_cast<int>(i));
  xml += " </build>\n</model>\n";
  return xml;
}

std::string zip_message(zip_error_t* ze) { return zip_error_strerror(ze); }

// Adds the three package parts. libzip reads the buffers at zip_close, so `model` must outlive it.
Status add_package_files(zip_t* za, const std::string& model) {
  const std::pair<const char*, std::string_view> files[] = {
      {"[Content_Types].xml", kContentTypes},
      {"_rels/.rels", kRels},
      {kModelPath.data(), model},
  };
  for (const auto& [path, data] : files) {
    zip_source_t* src = zip_source_buffer(za, data.data(), data.size(), 0);
    if (src == nullptr)
      return internal_error(
          fmt::format("3MF: libzip cannot buffer {}: {}", path, zip_message(zip_get_error(za))));
    if (zip_file_add(za, path, src, ZIP_FL_ENC_UTF_8 | ZIP_FL_OVERWRITE) < 0) {
      zip_source_free(src);
      return internal_error(
          fmt::format("3MF: libzip cannot add {}: {}", path, zip_message(zip_get_error(za))));
    }
  }
  return {};
}

}  // namespace

Status write_3mf_file(const std::filesystem::path& path, std::span<const MeshPart> parts,
                      units::LengthUnit unit) {
  auto model = build_model_xml(parts, unit);
  if (!model.ok()) return model.status().with_context(path.string());
  return write_file_atomic(path, [&](const std::filesystem::path& tmp) -> Status {
    int err = 0;
    zip_t* za = zip_open(tmp.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &err);
    if (za == nullptr) {
      zip_error_t ze;
      zip_error_init_with_code(&ze, err);
      Status s =
          io_error(fmt::format("{}: libzip cannot create: {}", path.string(), zip_message(&ze)));
      zip_error_fini(&ze);
      return s;
    }
    if (Status s = add_package_files(za, *model); !s.ok()) {
      zip_discard(za);
      return s.with_context(path.string());
    }
    if (zip_close(za) != 0) {
      Status s = io_error(fmt::format("{}: libzip cannot write the package: {}", path.string(),
                                      zip_message(zip_get_error(za))));
      zip_discard(za);
      return s;
    }
    return {};
  });
}

Result<std::string> format_3mf(std::span<const MeshPart> parts, units::LengthUnit unit) {
  HC_ASSIGN_OR_RETURN(const std::string model, build_model_xml(parts, unit));
  zip_error_t ze;
  zip_error_init(&ze);
  zip_source_t* mem = zip_source_buffer_create(nullptr, 0, 0, &ze);
  if (mem == nullptr) {
    Status s = internal_error(
        fmt::format("3MF: libzip cannot make a memory buffer: {}", zip_message(&ze)));
    zip_error_fini(&ze);
    return s;
  }
  zip_t* za = zip_open_from_source(mem, ZIP_TRUNCATE, &ze);
  if (za == nullptr) {
    Status s = internal_error(
        fmt::format("3MF: libzip cannot open a memory archive: {}", zip_message(&ze)));
    zip_source_free(mem);
    zip_error_fini(&ze);
    return s;
  }
  zip_error_fini(&ze);
  zip_source_keep(mem);  // read the bytes back after zip_close
  struct FreeSource {
    zip_source_t* s;
    ~FreeSource() { zip_source_free(s); }
  } free_mem{mem};
  if (Status s = add_package_files(za, model); !s.ok()) {
    zip_discard(za);
    return s;
  }
  if (zip_close(za) != 0) {
    Status s = internal_error(
        fmt::format("3MF: libzip cannot finish the package: {}", zip_message(zip_get_error(za))));
    zip_discard(za);
    return s;
  }
  zip_stat_t st;
  zip_stat_init(&st);
  if (zip_source_stat(mem, &st) != 0 || (st.valid & ZIP_STAT_SIZE) == 0 ||
      zip_source_open(mem) != 0)
    return internal_error(fmt::format("3MF: libzip cannot read the package back: {}",
                                      zip_message(zip_source_error(mem))));
  std::string out(static_cast<std::size_t>(st.size), '\0');
  const zip_int64_t got = zip_source_read(mem, out.data(), st.size);
  zip_source_close(mem);
  if (got < 0 || static_cast<zip_uint64_t>(got) != st.size)
    return internal_error("3MF: libzip returned a short package");
  return out;
}

}  // namespace hc::mesh_io
