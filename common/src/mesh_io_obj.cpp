// Wavefront OBJ: reader (positions and faces only) and writer. Hand-written: Debian has no fast,
// robust, non-throwing OBJ reader.
#include <array>

#include "mesh_io_internal.h"

namespace hc::mesh_io {
namespace {

// Statements that carry nothing a triangle mesh needs. Anything else is an error, so that a file
// that is not OBJ at all (binary garbage, another format) is reported rather than read as empty.
bool is_ignored_statement(std::string_view kw) {
  static constexpr std::array<std::string_view, 37> kIgnored{
      "vt",        "vn",     "vp",       "l",        "p",    "g",      "o",      "s",
      "usemtl",    "mtllib", "cstype",   "deg",      "bmat", "step",   "curv",   "curv2",
      "surf",      "parm",   "trim",     "hole",     "scrv", "sp",     "end",    "con",
      "mg",        "bevel",  "c_interp", "d_interp", "lod",  "maplib", "usemap", "shadow_obj",
      "trace_obj", "ctech",  "stech",    "call",     "csh"};
  for (std::string_view s : kIgnored)
    if (s == kw) return true;
  return false;
}

}  // namespace

Result<TriangleMesh> parse_obj(std::string_view bytes, std::string_view name,
                               const MeshReadOptions& options) {
  const std::size_t limit = element_limit(options);
  TextScanner sc(bytes);
  VertexBuffer verts;
  TriangleBuffer tris;
  std::vector<int> corners;
  // Positive indices may refer forward (some exporters write faces first), so they are checked
  // against the final vertex count; remember the largest and where it was.
  std::int64_t max_index = -1;
  std::size_t max_index_line = 0;

  while (!sc.at_end()) {
    const std::string_view kw = sc.token_before_comment();
    if (kw.empty()) {
      sc.next_line();
      continue;
    }
    if (kw == "v") {
      if (verts.size() >= limit)
        return error_at(
            name, sc.line(),
            fmt::format("more than {} vertices (MeshReadOptions::max_elements)", limit));
      double xyz[3];
      for (int k = 0; k < 3; ++k) {
        const std::string_view tok = sc.token_before_comment();
        if (tok.empty())
          return error_at(name, sc.line(),
                          fmt::format("vertex has {} coordinates, expected 3 (x y z)", k));
        double value = 0;
        switch (parse_double(tok, value)) {
          case NumberParse::kOk:
            break;
          case NumberParse::kNotNumber:
            return error_at(
                name, sc.line(),
                fmt::format("expected a number for vertex coordinate, got {}", quote(tok)));
          case NumberParse::kNotFinite:
            return error_at(name, sc.line(),
                            fmt::format("vertex coordinate {} is not finite", quote(tok)));
        }
        xyz[k] = value;
      }
      verts.push(xyz[0], xyz[1], xyz[2]);
    } else if (kw == "f") {
      corners.clear();
      const auto nv = static_cast<std::int64_t>(verts.size());
      for (;;) {
        std::string_view tok = sc.token_before_comment();
        if (tok == "\\") {  // line continuation
          sc.next_line();
          continue;
        }
        if (tok.empty()) break;
        // "v", "v/vt", "v/vt/vn" or "v//vn": only the position index matters.
        const std::string_view idx_text = tok.substr(0, tok.find('/'));
        std::int64_t idx = 0;
        if (!parse_int64(idx_text, idx))
          return error_at(name, sc.line(),
                          fmt::format("expected a vertex index in face, got {}", quote(tok)));
        if (idx == 0)
          return error_at(name, sc.line(), "vertex index 0 in face (OBJ indices start at 1)");
        if (idx < 0) {
          idx += nv;  // relative: -1 is the last vertex read so far
          if (idx < 0)
            return error_at(name, sc.line(),
                            fmt::format("relative vertex index {} reaches before the first vertex "
                                        "({} vertices read so far)",
                                        idx - nv, nv));
        } else {
          idx -= 1;
          if (idx >= static_cast<std::int64_t>(limit))
            return error_at(
                name, sc.line(),
                fmt::format("vertex index {} is beyond the limit of {} vertices", idx + 1, limit));
          if (idx > max_index) {
            max_index = idx;
            max_index_line = sc.line();
          }
        }
        corners.push_back(static_cast<int>(idx));
      }
      if (corners.size() < 3)
        return error_at(name, sc.line(),
                        fmt::format("face has {} vertices, expected at least 3", corners.size()));
      if (tris.size() + corners.size() - 2 > limit)
        return error_at(
            name, sc.line(),
            fmt::format("more than {} triangles (MeshReadOptions::max_elements)", limit));
      fan_triangulate(corners, tris);
    } else if (!is_ignored_statement(kw)) {
      return error_at(
          name, sc.line(),
          fmt::format("unknown statement {}, expected v, f or another OBJ keyword", quote(kw)));
    }
    sc.next_line();
  }

  const auto nv = static_cast<std::int64_t>(verts.size());
  if (max_index >= nv)
    return error_at(name, max_index_line,
                    fmt::format("vertex index {} is out of range: the file has {} vertices",
                                max_index + 1, nv));
  if (tris.size() == 0) return error_at(name, 0, "no faces ('f' lines), expected a triangle mesh");
  return make_mesh(std::move(verts), std::move(tris));
}

std::string format_obj(const TriangleMesh& mesh) {
  std::string out = "# written by Hardcopy\n";
  append_text_rows(out, mesh, "v ", "f ", 1);
  return out;
}

}  // namespace hc::mesh_io
