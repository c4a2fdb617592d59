// Object File Format (OFF, as written by CGAL and Geomview): reader and writer. Hand-written:
// Debian has no fast, robust, non-throwing OFF reader.
//
// Each vertex and each face is read from its own line, and whatever follows the coordinates or the
// indices on that line (normals, colours, texture coordinates of COFF/NOFF/STOFF) is ignored.
#include "mesh_io_internal.h"

namespace hc::mesh_io {
namespace {

// Smallest text a vertex ("0 0 0\n") and a triangle ("3 0 1 2\n") can take: what a header's counts
// are checked against before anything is allocated.
constexpr std::uint64_t kMinVertexBytes = 6;
constexpr std::uint64_t kMinFaceBytes = 8;

// "[ST][C][N][4][n]OFF". Only 3-D positions are supported: 4OFF / nOFF are refused.
Status check_header_keyword(std::string_view kw, std::string_view name, std::size_t line) {
  std::string_view s = kw;
  if (s.starts_with("ST")) s.remove_prefix(2);
  if (s.starts_with("C")) s.remove_prefix(1);
  if (s.starts_with("N")) s.remove_prefix(1);
  if (s.starts_with("4") || s.starts_with("n"))
    return error_at(
        name, line,
        fmt::format("{} declares non-3-D vertices, only 3-D OFF is supported", quote(kw)));
  if (s != "OFF")
    return error_at(
        name, line,
        fmt::format("expected the OFF header keyword (OFF, COFF, NOFF, ...), got {}", quote(kw)));
  return {};
}

// The next count token; `pending` is one already read from the header line ("OFF 8 6 0").
Result<std::int64_t> read_count(TextScanner& sc, std::string_view& pending, std::string_view name,
                                std::string_view what) {
  std::string_view tok = pending;
  pending = {};
  if (tok.empty()) {
    sc.skip_space_and_comments();
    if (sc.at_end())
      return error_at(name, sc.line(), fmt::format("file ends before the {} count", what));
    tok = sc.token();
  }
  std::int64_t v = 0;
  if (!parse_int64(tok, v) || v < 0)
    return error_at(
        name, sc.line(),
        fmt::format("expected the {} count (a non-negative integer), got {}", what, quote(tok)));
  return v;
}

}  // namespace

Result<TriangleMesh> parse_off(std::string_view bytes, std::string_view name,
                               const MeshReadOptions& options) {
  const std::size_t limit = element_limit(options);
  TextScanner sc(bytes);
  sc.skip_space_and_comments();
  if (sc.at_end()) return error_at(name, sc.line(), "no OFF header, the file holds only comments");
  const std::string_view kw = sc.token();
  HC_RETURN_IF_ERROR(check_header_keyword(kw, name, sc.line()));
  std::string_view pending;
  if (!sc.at_line_end()) {
    pending = sc.token();
    if (pending == "BINARY") return error_at(name, sc.line(), "binary OFF is not supported");
  }
  HC_ASSIGN_OR_RETURN(const std::int64_t nv, read_count(sc, pending, name, "vertex"));
  HC_ASSIGN_OR_RETURN(const std::int64_t nf, read_count(sc, pending, name, "face"));
  const std::size_t count_line = sc.line();
  if (!sc.at_line_end()) {
    const std::string_view tok = sc.token();
    std::int64_t ne = 0;
    if (!parse_int64(tok, ne) || ne < 0)
      return error_at(
          name, count_line,
          fmt::format("expected the edge count (a non-negative integer), got {}", quote(tok)));
  }
  if (static_cast<std::uint64_t>(nv) > limit || static_cast<std::uint64_t>(nf) > limit)
    return error_at(name, count_line,
                    fmt::format("header declares {} vertices and {} faces, more than the limit of "
                                "{} (MeshReadOptions::max_elements)",
                                nv, nf, limit));
  const std::uint64_t need = static_cast<std::uint64_t>(nv) * kMinVertexBytes +
                             static_cast<std::uint64_t>(nf) * kMinFaceBytes;
  if (need > sc.remaining() + 1)
    return error_at(name, count_line,
                    fmt::format("header declares {} vertices and {} faces, which need at least {} "
                                "bytes, but only {} bytes follow",
                                nv, nf, need, sc.remaining()));
  if (nf == 0)
    return error_at(name, count_line, "header declares 0 faces, expected a triangle mesh");
  sc.next_line();

  VertexBuffer verts(static_cast<std::size_t>(nv));
  for (std::int64_t i = 0; i < nv; ++i) {
    sc.skip_space_and_comments();
    if (sc.at_end())
      return error_at(name, sc.line(), fmt::format("file ends after {} of {} vertices", i, nv));
    double xyz[3];
    for (int k = 0; k < 3; ++k) {
      const std::string_view tok = sc.token_before_comment();
      if (tok.empty())
        return error_at(name, sc.line(),
                        fmt::format("vertex {} has {} coordinates, expected 3", i, k));
      double value = 0;
      switch (parse_double(tok, value)) {
        case NumberParse::kOk:
          break;
        case NumberParse::kNotNumber:
          return error_at(name, sc.line(),
                          fmt::format("vertex {}: expected a number, got {}", i, quote(tok)));
        case NumberParse::kNotFinite:
          return error_at(name, sc.line(),
                          fmt::format("vertex {}: coordinate {} is not finite", i, quote(tok)));
      }
      xyz[k] = value;
    }
    verts.push(xyz[0], xyz[1], xyz[2]);
    sc.next_line();
  }

  TriangleBuffer tris(static_cast<std::size_t>(nf));
  std::vector<int> corners;
  for (std::int64_t f = 0; f < nf; ++f) {
    sc.skip_space_and_comments();
    if (sc.at_end())
      return error_at(name, sc.line(), fmt::format("file ends after {} of {} faces", f, nf));
    const std::string_view count_tok = sc.token();
    std::int64_t k = 0;
    if (!parse_int64(count_tok, k))
      return error_at(
          name, sc.line(),
          fmt::format("face {}: expected the vertex count, got {}", f, quote(count_tok)));
    if (k < 3)
      return error_at(name, sc.line(),
                      fmt::format("face {} has {} vertices, expected at least 3", f, k));
    // Each index takes at least two bytes ("0 "): a larger count cannot be real.
    if (static_cast<std::uint64_t>(k) > sc.remaining() / 2 + 1)
      return error_at(name, sc.line(),
                      fmt::format("face {} declares {} vertices, more than the rest of the file "
                                  "can hold",
                                  f, k));
    corners.clear();
    for (std::int64_t j = 0; j < k; ++j) {
      const std::string_view tok = sc.token_before_comment();
      if (tok.empty())
        return error_at(name, sc.line(),
                        fmt::format("face {} has {} vertex indices, expected {}", f, j, k));
      std::int64_t idx = 0;
      if (!parse_int64(tok, idx))
        return error_at(name, sc.line(),
                        fmt::format("face {}: expected a vertex index, got {}", f, quote(tok)));
      if (idx < 0 || idx >= nv)
        return error_at(name, sc.line(),
                        fmt::format("face {}: vertex index {} is out of range, expected 0..{}", f,
                                    idx, nv - 1));
      corners.push_back(static_cast<int>(idx));
    }
    if (tris.size() + corners.size() - 2 > limit)
      return error_at(name, sc.line(),
                      fmt::format("more than {} triangles (MeshReadOptions::max_elements)", limit));
    fan_triangulate(corners, tris);
    sc.next_line();
  }
  return make_mesh(std::move(verts), std::move(tris));
}

std::string format_off(const TriangleMesh& mesh) {
  std::string out = "OFF\n";
  append_int(out, mesh.num_vertices());
  out += ' ';
  append_int(out, mesh.num_triangles());
  out += " 0\n";
  append_text_rows(out, mesh, "", "3 ", 0);
  return out;
}

}  // namespace hc::mesh_io
