// Shared pieces of the mesh readers and writers (mesh_io*.cpp). Not a public header: the public
// interface is common/mesh_io.h.
#pragma once

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <span>
#include <string>
#include <string_view>
#include <system_error>
#include <type_traits>
#include <vector>

#include "common/file_io.h"
#include "common/huge_pages.h"
#include "common/mesh.h"
#include "common/mesh_io.h"
#include "common/status.h"
#include "common/units.h"

namespace hc::mesh_io {

// ---- Readers (bytes are never empty: parse_mesh rejects that first) ----
Result<TriangleMesh> parse_obj(std::string_view bytes, std::string_view name,
                               const MeshReadOptions& options);
Result<TriangleMesh> parse_off(std::string_view bytes, std::string_view name,
                               const MeshReadOptions& options);
Result<TriangleMesh> parse_stl(std::string_view bytes, std::string_view name,
                               const MeshReadOptions& options);
// Accepts gzip-compressed bytes too.
Result<TriangleMesh> parse_ply(std::string_view bytes, std::string_view name,
                               const MeshReadOptions& options);

// ---- Writers (the mesh has passed check_writable) ----
// Finite coordinates and every index in [0, #V): what every writer needs to produce a valid file.
Status check_writable(const TriangleMesh& mesh, std::string_view what);
std::string format_obj(const TriangleMesh& mesh);
std::string format_off(const TriangleMesh& mesh);
std::string format_stl(const TriangleMesh& mesh, bool binary);
std::string format_ply(const TriangleMesh& mesh, bool binary);
// The 3MF package as bytes, and written straight to a file (libzip wants a path).
Result<std::string> format_3mf(std::span<const MeshPart> parts, units::LengthUnit unit);
Status write_3mf_file(const std::filesystem::path& path, std::span<const MeshPart> parts,
                      units::LengthUnit unit);

// ---- gzip ----
inline bool is_gzip(std::string_view bytes) {
  return bytes.size() >= 2 && static_cast<unsigned char>(bytes[0]) == 0x1f &&
         static_cast<unsigned char>(bytes[1]) == 0x8b;
}
Result<std::string> gzip_compress(std::string_view bytes);

// Inflates gzip data, giving up with kInvalidArgument once the output would exceed the cap that
// `cap_for` returns. The cap is asked again after every chunk with the output so far, so a caller
// can tighten it once it has seen a header that says how big the rest can be.
class InflateCap {
 public:
  virtual ~InflateCap() = default;
  // Largest total output allowed given what has been inflated so far; may return an error.
  virtual Result<std::size_t> cap(std::string_view inflated_so_far) = 0;
};
Result<std::string> gzip_inflate(std::string_view bytes, std::string_view name, InflateCap& cap);

// ---- Errors ----
inline Status error_at(std::string_view name, std::size_t line, std::string_view what) {
  return parse_error(std::filesystem::path(name), line, what);
}

// A token for an error message: at most 40 characters, non-printable bytes as \xNN, so that binary
// garbage gives a readable message.
std::string quote(std::string_view token);

// ---- Numbers ----
enum class NumberParse { kOk, kNotNumber, kNotFinite };

// Whole-token parse of a decimal floating-point number ("+1.5", "-2e-3"). Infinity, NaN and values
// that overflow a double are kNotFinite; values that underflow become the nearest double.
inline NumberParse parse_double(std::string_view token, double& out) {
  const char* b = token.data();
  const char* e = b + token.size();
  // from_chars rejects the leading '+' that some exporters write.
  if (e - b >= 2 && *b == '+' && b[1] != '-' && b[1] != '+') ++b;
  if (b == e) return NumberParse::kNotNumber;
  const auto [ptr, ec] = std::from_chars(b, e, out);
  if (ptr != e) return NumberParse::kNotNumber;
  if (ec == std::errc::result_out_of_range) {
    // Tell overflow (infinite) from underflow (a denormal or zero, which is a fine coordinate).
    const std::string copy(b, e);
    out = std::strtod(copy.c_str(), nullptr);
    return std::isfinite(out) ? NumberParse::kOk : NumberParse::kNotFinite;
  }
  if (ec != std::errc{}) return NumberParse::kNotNumber;
  return std::isfinite(out) ? NumberParse::kOk : NumberParse::kNotFinite;
}

// Whole-token parse of a decimal integer with optional sign.
inline bool parse_int64(std::string_view token, std::int64_t& out) {
  const char* b = token.data();
  const char* e = b + token.size();
  if (e - b >= 2 && *b == '+' && b[1] != '-' && b[1] != '+') ++b;
  if (b == e) return false;
  const auto [ptr, ec] = std::from_chars(b, e, out);
  return ec == std::errc{} && ptr == e;
}

// ---- Text scanning ----
inline bool is_blank(char c) {
  return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v';
}
inline bool is_space(char c) { return c == '\n' || is_blank(c); }

// A cursor over a text file that counts lines (1-based) for error messages.
class TextScanner {
 public:
  // `first_line` is the line number of the text's first line (when scanning part of a file).
  explicit TextScanner(std::string_view text, std::size_t first_line = 1)
      : begin_(text.data()), p_(text.data()), end_(text.data() + text.size()), line_(first_line) {}

  std::size_t line() const { return line_; }
  bool at_end() const { return p_ == end_; }
  std::size_t offset() const { return static_cast<std::size_t>(p_ - begin_); }
  std::size_t remaining() const { return static_cast<std::size_t>(end_ - p_); }

  void skip_blanks() {
    while (p_ != end_ && is_blank(*p_)) ++p_;
  }
  // True at a newline, a '#' comment or the end of the text (blanks skipped first).
  bool at_line_end() {
    skip_blanks();
    return p_ == end_ || *p_ == '\n' || *p_ == '#';
  }
  // Moves past the next newline, or to the end.
  void next_line() {
    const void* nl = std::memchr(p_, '\n', static_cast<std::size_t>(end_ - p_));
    if (nl == nullptr) {
      p_ = end_;
    } else {
      p_ = static_cast<const char*>(nl) + 1;
      ++line_;
    }
  }
  // Skips whitespace and newlines up to the next token.
  void skip_space() {
    while (p_ != end_ && is_space(*p_)) {
      if (*p_ == '\n') ++line_;
      ++p_;
    }
  }
  // Skips whitespace, newlines and '#' comments up to the next token.
  void skip_space_and_comments() {
    while (p_ != end_) {
      if (*p_ == '\n') {
        ++line_;
        ++p_;
      } else if (is_blank(*p_)) {
        ++p_;
      } else if (*p_ == '#') {
        next_line();
      } else {
        break;
      }
    }
  }
  // The next run of non-space characters on this line; empty at the end of the line.
  std::string_view token() {
    skip_blanks();
    const char* b = p_;
    while (p_ != end_ && !is_space(*p_)) ++p_;
    return {b, static_cast<std::size_t>(p_ - b)};
  }
  // Like token(), but a '#' ends the line: a comment is not a token.
  std::string_view token_before_comment() {
    if (at_line_end()) return {};
    return token();
  }
  // The rest of the current line, without the newline or a trailing '\r'.
  std::string_view rest_of_line() {
    const char* b = p_;
    const void* nl = std::memchr(p_, '\n', static_cast<std::size_t>(end_ - p_));
    const char* e = nl == nullptr ? end_ : static_cast<const char*>(nl);
    p_ = e;
    std::string_view s(b, static_cast<std::size_t>(e - b));
    if (!s.empty() && s.back() == '\r') s.remove_suffix(1);
    return s;
  }

 private:
  const char* begin_;
  const char* p_;
  const char* end_;
  std::size_t line_;
};

// ---- Building the result ----
// The largest count a mesh can hold: indices are int.
inline constexpr std::size_t kMaxIndexable =
    static_cast<std::size_t>(std::numeric_limits<int>::max());

inline std::size_t element_limit(const MeshReadOptions& options) {
  return std::min(options.max_elements, kMaxIndexable);
}

// Rows of a #N by 3 matrix appended one at a time straight into the matrix's own storage, so the
// result needs no copy. Grows by doubling.
template <typename Matrix>
class RowBuffer {
 public:
  using Scalar = typename Matrix::Scalar;

  explicit RowBuffer(std::size_t expected_rows = 0) {
    if (expected_rows > 0) grow(expected_rows);
  }
  std::size_t size() const { return rows_; }
  void push(Scalar a, Scalar b, Scalar c) {
    if (rows_ == capacity_) grow(std::max<std::size_t>(16, 2 * capacity_));
    Scalar* p = m_.data() + 3 * rows_;
    p[0] = a;
    p[1] = b;
    p[2] = c;
    ++rows_;
  }
  Matrix take() && {
    if (rows_ != capacity_) m_.conservativeResize(static_cast<Eigen::Index>(rows_), 3);
    capacity_ = rows_;
    return std::move(m_);
  }

 private:
  void grow(std::size_t capacity) {
    m_.conservativeResize(static_cast<Eigen::Index>(capacity), 3);
    advise_huge_pages(m_.data() + 3 * rows_, (capacity - rows_) * 3 * sizeof(Scalar));
    capacity_ = capacity;
  }

  Matrix m_;
  std::size_t rows_ = 0;
  std::size_t capacity_ = 0;
};

using VertexBuffer = RowBuffer<MatrixX3d>;
using TriangleBuffer = RowBuffer<MatrixX3i>;

// Corners of a polygon to triangles (c0, ci, ci+1): exact for convex polygons, which is what
// mesh exporters write.
inline void fan_triangulate(std::span<const int> corners, TriangleBuffer& triangles) {
  for (std::size_t i = 1; i + 1 < corners.size(); ++i)
    triangles.push(corners[0], corners[i], corners[i + 1]);
}

inline TriangleMesh make_mesh(VertexBuffer&& vertices, TriangleBuffer&& triangles) {
  TriangleMesh mesh;
  mesh.vertices = std::move(vertices).take();
  mesh.triangles = std::move(triangles).take();
  return mesh;
}

// ---- Formatting numbers ----
// Shortest text that reads back to the same double.
inline void append_double(std::string& out, double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, r.ptr);
}
inline void append_float(std::string& out, float v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, r.ptr);
}
inline void append_int(std::string& out, long long v) {
  char buf[24];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, r.ptr);
}

// Appends the vertex and triangle lines shared by the text formats: "<vertex_prefix>x y z" per
// vertex, then "<face_prefix>a b c" per triangle with indices offset by `index_base` (OBJ counts
// from 1, OFF and PLY from 0).
inline void append_text_rows(std::string& out, const TriangleMesh& mesh,
                             std::string_view vertex_prefix, std::string_view face_prefix,
                             long long index_base) {
  out.reserve(out.size() + static_cast<std::size_t>(mesh.num_vertices()) * 60 +
              static_cast<std::size_t>(mesh.num_triangles()) * 24);
  for (Eigen::Index i = 0; i < mesh.num_vertices(); ++i) {
    out += vertex_prefix;
    append_double(out, mesh.vertices(i, 0));
    out += ' ';
    append_double(out, mesh.vertices(i, 1));
    out += ' ';
    append_double(out, mesh.vertices(i, 2));
    out += '\n';
  }
  for (Eigen::Index t = 0; t < mesh.num_triangles(); ++t) {
    out += face_prefix;
    append_int(out, mesh.triangles(t, 0) + index_base);
    out += ' ';
    append_int(out, mesh.triangles(t, 1) + index_base);
    out += ' ';
    append_int(out, mesh.triangles(t, 2) + index_base);
    out += '\n';
  }
}

// Little-endian stores for the binary writers.
template <typename T>
inline void store_le(char* dst, T v) {
  static_assert(std::is_trivially_copyable_v<T>);
  if constexpr (std::endian::native == std::endian::big) {
    char tmp[sizeof(T)];
    std::memcpy(tmp, &v, sizeof(T));
    for (std::size_t i = 0; i < sizeof(T); ++i) dst[i] = tmp[sizeof(T) - 1 - i];
  } else {
    std::memcpy(dst, &v, sizeof(T));
  }
}

}  // namespace hc::mesh_io
