// TetGen .node/.ele reader and writer, VTK .vtu writer. Hand-written: TetGen's own loader
// (tetgenio::load_node) prints to stdout, calls exit()/terminates on malformed files and gives no
// line numbers; VTK is not a dependency, and the ASCII XML it needs is a few lines.
#include "common/tet_mesh_io.h"

#include <set>

#include "common/file_io.h"
#include "mesh_io_internal.h"

namespace hc {
namespace {

using mesh_io::error_at;
using mesh_io::NumberParse;
using mesh_io::parse_double;
using mesh_io::parse_int64;
using mesh_io::quote;
using mesh_io::TextScanner;

// Smallest text a point line ("1 0 0 0\n") and a tet line ("1 1 2 3 4\n") can take: header counts
// are checked against the bytes left before anything is allocated.
constexpr std::uint64_t kMinNodeLineBytes = 8;
constexpr std::uint64_t kMinEleLineBytes = 10;
// Attributes per point / tet: far above any real use, low enough to keep allocations sane.
constexpr std::int64_t kMaxAttributes = 64;

// The next token on the current line, or an error naming `what` if the line ended.
Result<std::string_view> next_token(TextScanner& sc, std::string_view name, std::string_view what) {
  std::string_view tok = sc.token_before_comment();
  if (tok.empty()) return error_at(name, sc.line(), fmt::format("line ends before {}", what));
  return tok;
}

Result<std::int64_t> next_int(TextScanner& sc, std::string_view name, std::string_view what) {
  HC_ASSIGN_OR_RETURN(const std::string_view tok, next_token(sc, name, what));
  std::int64_t v = 0;
  if (!parse_int64(tok, v))
    return error_at(name, sc.line(),
                    fmt::format("expected {} (an integer), got {}", what, quote(tok)));
  return v;
}

Result<double> next_double(TextScanner& sc, std::string_view name, std::string_view what) {
  HC_ASSIGN_OR_RETURN(const std::string_view tok, next_token(sc, name, what));
  double v = 0;
  switch (parse_double(tok, v)) {
    case NumberParse::kOk:
      return v;
    case NumberParse::kNotNumber:
      return error_at(name, sc.line(),
                      fmt::format("expected {} (a number), got {}", what, quote(tok)));
    case NumberParse::kNotFinite:
      break;
  }
  return error_at(name, sc.line(), fmt::format("{} is not finite: {}", what, quote(tok)));
}

// After the last expected value of a record: nothing but a comment may follow.
Status expect_line_end(TextScanner& sc, std::string_view name, std::string_view record) {
  if (!sc.at_line_end())
    return error_at(
        name, sc.line(),
        fmt::format("unexpected {} after {} (the header declares fewer values per line)",
                    quote(sc.token()), record));
  sc.next_line();
  return {};
}

// Moves to the first line holding a token; error if the file ends first.
Status to_next_record(TextScanner& sc, std::string_view name, std::string_view what) {
  sc.skip_space_and_comments();
  if (sc.at_end()) return error_at(name, sc.line(), fmt::format("file ends before {}", what));
  return {};
}

struct NodeHeader {
  std::int64_t count = 0;
  std::int64_t attributes = 0;
  bool markers = false;
};

Result<NodeHeader> read_node_header(TextScanner& sc, std::string_view name, std::size_t limit) {
  HC_RETURN_IF_ERROR(to_next_record(sc, name, "the header \"<#points> 3 <#attributes> <0|1>\""));
  NodeHeader h;
  HC_ASSIGN_OR_RETURN(h.count, next_int(sc, name, "the number of points"));
  const std::size_t line = sc.line();
  if (h.count < 0)
    return error_at(name, line, fmt::format("negative number of points {}", h.count));
  if (h.count == 0)
    return error_at(name, line,
                    "0 points: the points are not in this file (TetGen's 'points in .poly' form is "
                    "not supported here)");
  std::int64_t dim = 3;
  std::int64_t markers = 0;
  if (!sc.at_line_end()) {
    HC_ASSIGN_OR_RETURN(dim, next_int(sc, name, "the dimension"));
  }
  if (dim != 3) return error_at(name, line, fmt::format("dimension {}, expected 3", dim));
  if (!sc.at_line_end()) {
    HC_ASSIGN_OR_RETURN(h.attributes, next_int(sc, name, "the attribute count"));
  }
  if (h.attributes < 0 || h.attributes > kMaxAttributes)
    return error_at(
        name, line,
        fmt::format("attribute count {} out of range 0..{}", h.attributes, kMaxAttributes));
  if (!sc.at_line_end()) {
    HC_ASSIGN_OR_RETURN(markers, next_int(sc, name, "the boundary marker flag"));
  }
  if (markers != 0 && markers != 1)
    return error_at(name, line, fmt::format("boundary marker flag {}, expected 0 or 1", markers));
  h.markers = markers == 1;
  HC_RETURN_IF_ERROR(expect_line_end(sc, name, "the header"));
  if (static_cast<std::uint64_t>(h.count) > limit)
    return error_at(name, line,
                    fmt::format("header declares {} points, more than the limit of {} "
                                "(TetMeshReadOptions::max_elements)",
                                h.count, limit));
  const std::uint64_t per_line =
      kMinNodeLineBytes + 2 * static_cast<std::uint64_t>(h.attributes) + (h.markers ? 2 : 0);
  if (static_cast<std::uint64_t>(h.count) * per_line > sc.remaining() + 1)
    return error_at(
        name, line,
        fmt::format("header declares {} points, which need at least {} bytes, but only "
                    "{} bytes follow",
                    h.count, static_cast<std::uint64_t>(h.count) * per_line, sc.remaining()));
  return h;
}

Status parse_nodes(TextScanner& sc, std::string_view name, const NodeHeader& h, TetMesh& mesh,
                   std::int64_t& base) {
  const auto n = static_cast<Eigen::Index>(h.count);
  mesh.nodes.resize(n, 3);
  if (h.attributes > 0) mesh.node_attributes.resize(n, static_cast<Eigen::Index>(h.attributes));
  if (h.markers) mesh.node_markers.resize(static_cast<std::size_t>(n));
  for (Eigen::Index i = 0; i < n; ++i) {
    HC_RETURN_IF_ERROR(
        to_next_record(sc, name, fmt::format("point {} of {} (file truncated?)", i + 1, n)));
    HC_ASSIGN_OR_RETURN(const std::int64_t index, next_int(sc, name, "the point index"));
    if (i == 0) {
      if (index != 0 && index != 1)
        return error_at(name, sc.line(),
                        fmt::format("first point has index {}, expected 0 or 1", index));
      base = index;
    } else if (index != base + i) {
      return error_at(name, sc.line(),
                      fmt::format("point index {}, expected {} (indices must be consecutive)",
                                  index, base + i));
    }
    for (int k = 0; k < 3; ++k) {
      HC_ASSIGN_OR_RETURN(
          mesh.nodes(i, k),
          next_double(sc, name, fmt::format("coordinate {} of point {}", "xyz"[k], index)));
    }
    for (Eigen::Index a = 0; a < mesh.node_attributes.cols(); ++a) {
      HC_ASSIGN_OR_RETURN(mesh.node_attributes(i, a),
                          next_double(sc, name, fmt::format("attribute {} of point {}", a, index)));
    }
    if (h.markers) {
      HC_ASSIGN_OR_RETURN(
          const std::int64_t m,
          next_int(sc, name, fmt::format("the boundary marker of point {}", index)));
      if (m < std::numeric_limits<int>::min() || m > std::numeric_limits<int>::max())
        return error_at(name, sc.line(), fmt::format("boundary marker {} out of range", m));
      mesh.node_markers[static_cast<std::size_t>(i)] = static_cast<int>(m);
    }
    HC_RETURN_IF_ERROR(expect_line_end(sc, name, fmt::format("point {}", index)));
  }
  sc.skip_space_and_comments();
  if (!sc.at_end())
    return error_at(
        name, sc.line(),
        fmt::format("unexpected {} after the {} declared points", quote(sc.token()), n));
  return {};
}

Status parse_eles(TextScanner& sc, std::string_view name, std::int64_t base, std::size_t limit,
                  TetMesh& mesh) {
  HC_RETURN_IF_ERROR(
      to_next_record(sc, name, "the header \"<#tetrahedra> <4> <#region attributes>\""));
  HC_ASSIGN_OR_RETURN(const std::int64_t count, next_int(sc, name, "the number of tetrahedra"));
  const std::size_t line = sc.line();
  if (count <= 0)
    return error_at(name, line, fmt::format("number of tetrahedra {}, expected > 0", count));
  std::int64_t per_tet = 4;
  std::int64_t attributes = 0;
  if (!sc.at_line_end()) {
    HC_ASSIGN_OR_RETURN(per_tet, next_int(sc, name, "the nodes per tetrahedron"));
  }
  if (per_tet != 4)
    return error_at(name, line,
                    fmt::format("{} nodes per tetrahedron, only linear (4-node) tetrahedra are "
                                "supported",
                                per_tet));
  if (!sc.at_line_end()) {
    HC_ASSIGN_OR_RETURN(attributes, next_int(sc, name, "the region attribute count"));
  }
  if (attributes != 0 && attributes != 1)
    return error_at(name, line,
                    fmt::format("region attribute count {}, expected 0 or 1", attributes));
  HC_RETURN_IF_ERROR(expect_line_end(sc, name, "the header"));
  if (static_cast<std::uint64_t>(count) > limit)
    return error_at(name, line,
                    fmt::format("header declares {} tetrahedra, more than the limit of {} "
                                "(TetMeshReadOptions::max_elements)",
                                count, limit));
  const std::uint64_t per_line = kMinEleLineBytes + 2 * static_cast<std::uint64_t>(attributes);
  if (static_cast<std::uint64_t>(count) * per_line > sc.remaining() + 1)
    return error_at(
        name, line,
        fmt::format("header declares {} tetrahedra, which need at least {} bytes, but "
                    "only {} bytes follow",
                    count, static_cast<std::uint64_t>(count) * per_line, sc.remaining()));

  const auto t_count = static_cast<Eigen::Index>(count);
  const std::int64_t n = mesh.num_nodes();
  mesh.tets.resize(t_count, 4);
  if (attributes == 1) mesh.tet_regions.resize(static_cast<std::size_t>(count));
  std::int64_t ele_base = 0;
  for (Eigen::Index t = 0; t < t_count; ++t) {
    HC_RETURN_IF_ERROR(to_next_record(
        sc, name, fmt::format("tetrahedron {} of {} (file truncated?)", t + 1, count)));
    HC_ASSIGN_OR_RETURN(const std::int64_t index, next_int(sc, name, "the tetrahedron index"));
    if (t == 0) {
      if (index != 0 && index != 1)
        return error_at(name, sc.line(),
                        fmt::format("first tetrahedron has index {}, expected 0 or 1", index));
      ele_base = index;
    } else if (index != ele_base + t) {
      return error_at(name, sc.line(),
                      fmt::format("tetrahedron index {}, expected {} (indices must be consecutive)",
                                  index, ele_base + t));
    }
    for (int k = 0; k < 4; ++k) {
      HC_ASSIGN_OR_RETURN(const std::int64_t v,
                          next_int(sc, name, fmt::format("node {} of tetrahedron {}", k, index)));
      if (v < base || v >= base + n)
        return error_at(name, sc.line(),
                        fmt::format("tetrahedron {}: node index {} is out of range, expected "
                                    "{}..{} (the .node file's numbering)",
                                    index, v, base, base + n - 1));
      mesh.tets(t, k) = static_cast<int>(v - base);
    }
    if (attributes == 1) {
      HC_ASSIGN_OR_RETURN(
          const double r,
          next_double(sc, name, fmt::format("region attribute of tetrahedron {}", index)));
      if (r != std::round(r) || std::abs(r) > 1e9)
        return error_at(
            name, sc.line(),
            fmt::format("tetrahedron {}: region attribute {} is not an integer", index, r));
      mesh.tet_regions[static_cast<std::size_t>(t)] = static_cast<int>(r);
    }
    const std::size_t tet_line = sc.line();
    HC_RETURN_IF_ERROR(expect_line_end(sc, name, fmt::format("tetrahedron {}", index)));
    // Orientation and degeneracy, with a scale-aware tolerance (relative to the tet's own edges).
    const double v6 = 6.0 * tet_signed_volume(mesh, t);
    double l3 = 0;
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b)
        l3 = std::max(l3,
                      (mesh.nodes.row(mesh.tets(t, a)) - mesh.nodes.row(mesh.tets(t, b))).norm());
    l3 = l3 * l3 * l3;
    if (!(std::abs(v6) > 1e-12 * l3))
      return error_at(name, tet_line,
                      fmt::format("tetrahedron {} is degenerate (zero volume)", index));
    if (v6 < 0) std::swap(mesh.tets(t, 2), mesh.tets(t, 3));
  }
  sc.skip_space_and_comments();
  if (!sc.at_end())
    return error_at(
        name, sc.line(),
        fmt::format("unexpected {} after the {} declared tetrahedra", quote(sc.token()), count));
  return {};
}

std::size_t limit_of(const TetMeshReadOptions& options) {
  return std::min(options.max_elements, mesh_io::kMaxIndexable);
}

Status check_writable(const TetMesh& mesh) {
  const Eigen::Index n = mesh.num_nodes();
  if (n == 0) return invalid_argument("tet mesh has no nodes");
  if (!mesh.nodes.allFinite()) return invalid_argument("tet mesh has a non-finite coordinate");
  for (Eigen::Index t = 0; t < mesh.num_tets(); ++t)
    for (int k = 0; k < 4; ++k)
      if (mesh.tets(t, k) < 0 || mesh.tets(t, k) >= n)
        return invalid_argument(
            fmt::format("tet {}: node index {} out of range 0..{}", t, mesh.tets(t, k), n - 1));
  if (!mesh.node_markers.empty() && std::ssize(mesh.node_markers) != n)
    return invalid_argument(
        fmt::format("{} node markers for {} nodes", mesh.node_markers.size(), n));
  if (mesh.node_attributes.size() > 0 && mesh.node_attributes.rows() != n)
    return invalid_argument(
        fmt::format("{} rows of node attributes for {} nodes", mesh.node_attributes.rows(), n));
  if (!mesh.node_attributes.allFinite())
    return invalid_argument("tet mesh has a non-finite node attribute");
  if (!mesh.tet_regions.empty() && std::ssize(mesh.tet_regions) != mesh.num_tets())
    return invalid_argument(
        fmt::format("{} tet regions for {} tets", mesh.tet_regions.size(), mesh.num_tets()));
  return {};
}

}  // namespace

Result<TetMesh> parse_tetgen_node(std::string_view node_bytes, std::string_view node_name,
                                  const TetMeshReadOptions& options) {
  TextScanner sc(node_bytes);
  HC_ASSIGN_OR_RETURN(const NodeHeader h, read_node_header(sc, node_name, limit_of(options)));
  TetMesh mesh;
  std::int64_t base = 0;
  HC_RETURN_IF_ERROR(parse_nodes(sc, node_name, h, mesh, base));
  return mesh;
}

Result<TetMesh> parse_tetgen(std::string_view node_bytes, std::string_view ele_bytes,
                             std::string_view node_name, std::string_view ele_name,
                             const TetMeshReadOptions& options) {
  TextScanner sc(node_bytes);
  HC_ASSIGN_OR_RETURN(const NodeHeader h, read_node_header(sc, node_name, limit_of(options)));
  TetMesh mesh;
  std::int64_t base = 0;
  HC_RETURN_IF_ERROR(parse_nodes(sc, node_name, h, mesh, base));
  TextScanner se(ele_bytes);
  HC_RETURN_IF_ERROR(parse_eles(se, ele_name, base, limit_of(options), mesh));
  return mesh;
}

Result<TetMesh> read_tetgen(const std::filesystem::path& path, const TetMeshReadOptions& options) {
  std::filesystem::path base = path;
  if (base.extension() == ".node" || base.extension() == ".ele") base.replace_extension();
  const std::filesystem::path node = std::filesystem::path(base.string() + ".node");
  const std::filesystem::path ele = std::filesystem::path(base.string() + ".ele");
  HC_ASSIGN_OR_RETURN(const std::string node_bytes, read_file(node));
  HC_ASSIGN_OR_RETURN(const std::string ele_bytes, read_file(ele));
  return parse_tetgen(node_bytes, ele_bytes, node.string(), ele.string(), options);
}

Result<std::string> format_tetgen_node(const TetMesh& mesh) {
  HC_RETURN_IF_ERROR(check_writable(mesh));
  const bool markers = !mesh.node_markers.empty();
  const Eigen::Index na = mesh.node_attributes.size() > 0 ? mesh.node_attributes.cols() : 0;
  std::string out = fmt::format("# Hardcopy tetrahedral mesh: nodes (metres)\n{} 3 {} {}\n",
                                mesh.num_nodes(), na, markers ? 1 : 0);
  out.reserve(out.size() + static_cast<std::size_t>(mesh.num_nodes()) * 64);
  for (Eigen::Index i = 0; i < mesh.num_nodes(); ++i) {
    mesh_io::append_int(out, i + 1);
    for (int k = 0; k < 3; ++k) {
      out += ' ';
      mesh_io::append_double(out, mesh.nodes(i, k));
    }
    for (Eigen::Index a = 0; a < na; ++a) {
      out += ' ';
      mesh_io::append_double(out, mesh.node_attributes(i, a));
    }
    if (markers) {
      out += ' ';
      mesh_io::append_int(out, mesh.node_markers[static_cast<std::size_t>(i)]);
    }
    out += '\n';
  }
  return out;
}

Result<std::string> format_tetgen_ele(const TetMesh& mesh) {
  HC_RETURN_IF_ERROR(check_writable(mesh));
  if (mesh.num_tets() == 0) return invalid_argument("tet mesh has no tetrahedra");
  const bool regions = !mesh.tet_regions.empty();
  std::string out = fmt::format("# Hardcopy tetrahedral mesh: tetrahedra\n{} 4 {}\n",
                                mesh.num_tets(), regions ? 1 : 0);
  out.reserve(out.size() + static_cast<std::size_t>(mesh.num_tets()) * 40);
  for (Eigen::Index t = 0; t < mesh.num_tets(); ++t) {
    mesh_io::append_int(out, t + 1);
    for (int k = 0; k < 4; ++k) {
      out += ' ';
      mesh_io::append_int(out, mesh.tets(t, k) + 1);
    }
    if (regions) {
      out += ' ';
      mesh_io::append_int(out, mesh.tet_regions[static_cast<std::size_t>(t)]);
    }
    out += '\n';
  }
  return out;
}

Status write_tetgen(const std::filesystem::path& base, const TetMesh& mesh) {
  HC_ASSIGN_OR_RETURN(const std::string node, format_tetgen_node(mesh));
  HC_ASSIGN_OR_RETURN(const std::string ele, format_tetgen_ele(mesh));
  const std::filesystem::path node_path(base.string() + ".node");
  const std::filesystem::path ele_path(base.string() + ".ele");
  HC_RETURN_IF_ERROR(write_file_atomic(node_path, node));
  if (Status s = write_file_atomic(ele_path, ele); !s.ok()) {
    std::error_code ec;
    std::filesystem::remove(node_path, ec);
    return s;
  }
  return {};
}

namespace {

Status check_arrays(const std::vector<VtuArray>& arrays, Eigen::Index count, std::string_view where,
                    std::set<std::string>& names) {
  for (const VtuArray& a : arrays) {
    if (a.name.empty() || a.name.find_first_of("\"<>&") != std::string::npos)
      return invalid_argument(
          fmt::format("{} array name {} is empty or not XML-safe", where, quote(a.name)));
    if (!names.insert(std::string(where) + a.name).second)
      return invalid_argument(fmt::format("{} array \"{}\" given twice", where, a.name));
    if (a.components < 1 || a.components > 9)
      return invalid_argument(fmt::format("{} array \"{}\": {} components, expected 1..9", where,
                                          a.name, a.components));
    if (std::ssize(a.values) != count * a.components)
      return invalid_argument(fmt::format("{} array \"{}\" has {} values, expected {} ({} × {})",
                                          where, a.name, a.values.size(), count * a.components,
                                          count, a.components));
    for (std::size_t i = 0; i < a.values.size(); ++i)
      if (!std::isfinite(a.values[i]))
        return invalid_argument(fmt::format("{} array \"{}\": value {} (entry {}) is not finite",
                                            where, a.name, a.values[i], i));
  }
  return {};
}

void append_array(std::string& out, const VtuArray& a) {
  out += fmt::format(
      "        <DataArray type=\"Float64\" Name=\"{}\" NumberOfComponents=\"{}\" "
      "format=\"ascii\">\n",
      a.name, a.components);
  for (std::size_t i = 0; i < a.values.size(); ++i) {
    out += (i % static_cast<std::size_t>(a.components) == 0) ? "          " : " ";
    mesh_io::append_double(out, a.values[i]);
    if ((i + 1) % static_cast<std::size_t>(a.components) == 0) out += '\n';
  }
  out += "        </DataArray>\n";
}

void append_int_array(std::string& out, std::string_view name, const std::vector<int>& v) {
  out += fmt::format("        <DataArray type=\"Int32\" Name=\"{}\" format=\"ascii\">\n", name);
  for (int x : v) {
    out += "          ";
    mesh_io::append_int(out, x);
    out += '\n';
  }
  out += "        </DataArray>\n";
}

}  // namespace

Result<std::string> format_vtu(const TetMesh& mesh, const VtuData& data) {
  HC_RETURN_IF_ERROR(check_writable(mesh));
  const Eigen::Index n = mesh.num_nodes();
  const Eigen::Index nt = mesh.num_tets();
  const MatrixX3d& pos = data.positions.size() > 0 ? data.positions : mesh.nodes;
  if (pos.rows() != n)
    return invalid_argument(fmt::format("{} positions for {} nodes", pos.rows(), n));
  if (!pos.allFinite()) return invalid_argument("a written position is not finite");
  std::set<std::string> names;
  HC_RETURN_IF_ERROR(check_arrays(data.point_data, n, "point", names));
  HC_RETURN_IF_ERROR(check_arrays(data.cell_data, nt, "cell", names));
  const bool markers = data.include_regions_and_markers && !mesh.node_markers.empty();
  const bool regions = data.include_regions_and_markers && !mesh.tet_regions.empty();
  if (markers && names.contains("pointmarker"))
    return invalid_argument("point array \"marker\" clashes with the mesh's node markers");
  if (regions && names.contains("cellregion"))
    return invalid_argument("cell array \"region\" clashes with the mesh's tet regions");

  std::string out;
  out.reserve(static_cast<std::size_t>(n) * 80 + static_cast<std::size_t>(nt) * 60);
  out +=
      "<?xml version=\"1.0\"?>\n"
      "<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
      "  <UnstructuredGrid>\n";
  out += fmt::format("    <Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\n", n, nt);
  out += "      <PointData>\n";
  for (const VtuArray& a : data.point_data) append_array(out, a);
  if (markers) append_int_array(out, "marker", mesh.node_markers);
  out += "      </PointData>\n      <CellData>\n";
  for (const VtuArray& a : data.cell_data) append_array(out, a);
  if (regions) append_int_array(out, "region", mesh.tet_regions);
  out += "      </CellData>\n      <Points>\n";
  out +=
      "        <DataArray type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\" "
      "format=\"ascii\">\n";
  for (Eigen::Index i = 0; i < n; ++i) {
    out += "          ";
    for (int k = 0; k < 3; ++k) {
      if (k > 0) out += ' ';
      mesh_io::append_double(out, pos(i, k));
    }
    out += '\n';
  }
  out += "        </DataArray>\n      </Points>\n      <Cells>\n";
  out += "        <DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n";
  for (Eigen::Index t = 0; t < nt; ++t) {
    out += "          ";
    for (int k = 0; k < 4; ++k) {
      if (k > 0) out += ' ';
      mesh_io::append_int(out, mesh.tets(t, k));
    }
    out += '\n';
  }
  out += "        </DataArray>\n";
  out += "        <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n";
  for (Eigen::Index t = 0; t < nt; ++t) {
    out += "          ";
    mesh_io::append_int(out, 4 * (t + 1));
    out += '\n';
  }
  out += "        </DataArray>\n";
  out += "        <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
  // 10 = VTK_TETRA (vtkCellType.h).
  for (Eigen::Index t = 0; t < nt; ++t) out += "          10\n";
  out +=
      "        </DataArray>\n      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n"
      "</VTKFile>\n";
  return out;
}

Status write_vtu(const std::filesystem::path& path, const TetMesh& mesh, const VtuData& data) {
  HC_ASSIGN_OR_RETURN(const std::string text, format_vtu(mesh, data));
  return write_file_atomic(path, text);
}

}  // namespace hc
