// STL, binary and ASCII: reader (with vertex welding) and writer. Hand-written: Debian has no fast,
// robust, non-throwing STL reader.
#include <Eigen/Geometry>
#include <array>
#include <bit>

#include "mesh_io_internal.h"

namespace hc::mesh_io {
namespace {

constexpr std::size_t kBinaryHeaderBytes = 80;
constexpr std::size_t kBinaryPreambleBytes = 84;  // header + uint32 triangle count
constexpr std::size_t kBinaryTriangleBytes = 50;  // normal, 3 corners (12 floats), uint16 attribute
// How much of the file is looked at to tell text from binary.
constexpr std::size_t kTextSniffBytes = 1024;

template <typename T>
T load_le(const char* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  if constexpr (std::endian::native == std::endian::big) {
    auto bytes = std::bit_cast<std::array<char, sizeof(T)>>(v);
    std::reverse(bytes.begin(), bytes.end());
    v = std::bit_cast<T>(bytes);
  }
  return v;
}

// Merges corners whose three coordinates are bit-identical, numbering vertices in first-seen
// order. Open addressing with linear probing; each slot holds the full key so a probe touches one
// cache line, and the caller prefetches slots a few corners ahead to overlap the cache misses of
// a table far larger than the cache.
template <typename Bits>
class PositionWelder {
 public:
  using Real = std::conditional_t<sizeof(Bits) == 4, float, double>;

  explicit PositionWelder(std::size_t expected_unique) : vertices_(expected_unique) {
    std::size_t cap = 16;
    while (cap < 2 * expected_unique) cap *= 2;
    rebuild(cap);
  }

  static std::uint64_t hash(const Bits* k) {
    std::uint64_t h;
    if constexpr (sizeof(Bits) == 4) {
      const std::uint64_t a = k[0] | (static_cast<std::uint64_t>(k[1]) << 32);
      h = a * 0x9E3779B97F4A7C15ULL ^ (k[2] * 0xC2B2AE3D27D4EB4FULL);
    } else {
      h = k[0] * 0x9E3779B97F4A7C15ULL ^ (k[1] * 0xC2B2AE3D27D4EB4FULL) ^
          (k[2] * 0x165667B19E3779F9ULL);
    }
    h ^= h >> 29;
    return h * 0xBF58476D1CE4E5B9ULL;
  }

  void prefetch(const Bits* k) const { __builtin_prefetch(&slots_[slot_of(hash(k))]); }

  // The vertex index of this position, adding it if new.
  int insert(const Bits* k) {
    std::size_t i = slot_of(hash(k));
    for (;;) {
      const Slot& s = slots_[i];
      if (s.index < 0) break;
      if (s.k[0] == k[0] && s.k[1] == k[1] && s.k[2] == k[2]) return s.index;
      i = (i + 1) & mask_;
    }
    const auto index = static_cast<std::int32_t>(vertices_.size());
    slots_[i] = Slot{{k[0], k[1], k[2]}, index};
    vertices_.push(std::bit_cast<Real>(k[0]), std::bit_cast<Real>(k[1]), std::bit_cast<Real>(k[2]));
    if (2 * vertices_.size() > slots_.size()) rebuild(2 * slots_.size());
    return index;
  }

  std::size_t size() const { return vertices_.size(); }
  MatrixX3d take_vertices() && { return std::move(vertices_).take(); }

 private:
  struct Slot {
    Bits k[3];
    std::int32_t index;
  };

  std::size_t slot_of(std::uint64_t h) const { return static_cast<std::size_t>(h >> shift_); }

  void rebuild(std::size_t cap) {
    std::vector<Slot> old;
    old.swap(slots_);
    slots_.reserve(cap);
    advise_huge_pages(slots_.data(), cap * sizeof(Slot));
    slots_.assign(cap, Slot{{0, 0, 0}, -1});
    mask_ = cap - 1;
    shift_ = 64 - std::countr_zero(cap);
    for (const Slot& s : old) {
      if (s.index < 0) continue;
      std::size_t i = slot_of(hash(s.k));
      while (slots_[i].index >= 0) i = (i + 1) & mask_;
      slots_[i] = s;
    }
  }

  std::vector<Slot> slots_;
  std::size_t mask_ = 0;
  int shift_ = 64;
  VertexBuffer vertices_;
};

bool is_finite_float_bits(std::uint32_t bits) { return (bits & 0x7f800000u) != 0x7f800000u; }

Result<TriangleMesh> parse_binary(std::string_view bytes, std::string_view name,
                                  const MeshReadOptions& options, std::uint32_t n) {
  const std::size_t limit = element_limit(options);
  if (n == 0) return error_at(name, 0, "binary STL holds 0 triangles, expected a triangle mesh");
  if (n > limit)
    return error_at(name, 0,
                    fmt::format("binary STL holds {} triangles, more than the limit of {} "
                                "(MeshReadOptions::max_elements)",
                                n, limit));
  if (!options.weld_stl_vertices && 3ULL * n > limit)
    return error_at(name, 0,
                    fmt::format("binary STL holds {} unwelded corners, more than the limit of {} "
                                "(MeshReadOptions::max_elements)",
                                3ULL * n, limit));
  const char* const data = bytes.data() + kBinaryPreambleBytes;
  // Corner c's three coordinates follow the triangle's 12-byte normal.
  auto corner_ptr = [data](std::size_t corner) {
    return data + (corner / 3) * kBinaryTriangleBytes + 12 + (corner % 3) * 12;
  };
  auto load_corner = [&](std::size_t corner, std::uint32_t* k) {
    const char* p = corner_ptr(corner);
    k[0] = load_le<std::uint32_t>(p);
    k[1] = load_le<std::uint32_t>(p + 4);
    k[2] = load_le<std::uint32_t>(p + 8);
    return is_finite_float_bits(k[0]) && is_finite_float_bits(k[1]) && is_finite_float_bits(k[2]);
  };
  auto non_finite_error = [&](std::size_t corner, const std::uint32_t* k) {
    const int j = !is_finite_float_bits(k[0]) ? 0 : !is_finite_float_bits(k[1]) ? 1 : 2;
    const std::size_t offset = static_cast<std::size_t>(corner_ptr(corner) - bytes.data()) + 4 * j;
    return error_at(
        name, 0,
        fmt::format("byte {}: triangle {} corner {} has a non-finite coordinate (NaN or "
                    "infinity), expected a finite float",
                    offset, corner / 3, corner % 3));
  };
  const std::size_t corners = 3 * static_cast<std::size_t>(n);

  TriangleMesh mesh;
  mesh.triangles.resize(n, 3);
  advise_huge_pages(mesh.triangles.data(), corners * sizeof(int));
  int* const tri = mesh.triangles.data();
  if (!options.weld_stl_vertices) {
    mesh.vertices.resize(static_cast<Eigen::Index>(corners), 3);
    advise_huge_pages(mesh.vertices.data(), corners * 3 * sizeof(double));
    double* const v = mesh.vertices.data();
    for (std::size_t c = 0; c < corners; ++c) {
      std::uint32_t k[3];
      if (!load_corner(c, k)) return non_finite_error(c, k);
      for (int j = 0; j < 3; ++j) v[3 * c + j] = std::bit_cast<float>(k[j]);
      tri[c] = static_cast<int>(c);
    }
    return mesh;
  }

  // A closed mesh has about half as many vertices as triangles.
  PositionWelder<std::uint32_t> welder(n / 2 + 1);
  constexpr std::size_t kPrefetchDistance = 16;
  for (std::size_t c = 0; c < corners; ++c) {
    if (c + kPrefetchDistance < corners) {
      std::uint32_t ahead[3];
      load_corner(c + kPrefetchDistance, ahead);
      welder.prefetch(ahead);
    }
    std::uint32_t k[3];
    if (!load_corner(c, k)) return non_finite_error(c, k);
    tri[c] = welder.insert(k);
  }
  if (welder.size() > limit)
    return error_at(name, 0,
                    fmt::format("binary STL holds {} distinct vertices, more than the limit of {} "
                                "(MeshReadOptions::max_elements)",
                                welder.size(), limit));
  mesh.vertices = std::move(welder).take_vertices();
  return mesh;
}

// Expects the keyword `want` as the next token.
Status expect(TextScanner& sc, std::string_view want, std::string_view name,
              std::string_view context) {
  sc.skip_space_and_comments();
  const std::size_t line = sc.line();
  const std::string_view tok = sc.token();
  if (tok == want) return {};
  if (tok.empty())
    return error_at(name, line, fmt::format("file ends {}, expected '{}'", context, want));
  return error_at(name, line, fmt::format("expected '{}' {}, got {}", want, context, quote(tok)));
}

Result<TriangleMesh> parse_ascii(std::string_view bytes, std::string_view name,
                                 const MeshReadOptions& options) {
  const std::size_t limit = element_limit(options);
  TextScanner sc(bytes);
  // A facet's text is at least ~100 bytes: a fair first guess at the counts.
  const std::size_t guess = bytes.size() / 256 + 1;
  TriangleBuffer tris(guess);
  VertexBuffer soup(options.weld_stl_vertices ? 0 : 3 * guess);
  PositionWelder<std::uint64_t> welder(options.weld_stl_vertices ? guess / 2 + 1 : 0);
  auto add_corner = [&](const double* xyz) -> int {
    if (options.weld_stl_vertices) {
      const std::uint64_t k[3] = {std::bit_cast<std::uint64_t>(xyz[0]),
                                  std::bit_cast<std::uint64_t>(xyz[1]),
                                  std::bit_cast<std::uint64_t>(xyz[2])};
      return welder.insert(k);
    }
    soup.push(xyz[0], xyz[1], xyz[2]);
    return static_cast<int>(soup.size() - 1);
  };
  std::vector<double> polygon;
  bool in_solid = false;
  std::size_t solids = 0;
  for (;;) {
    sc.skip_space_and_comments();
    const std::size_t line = sc.line();
    const std::string_view tok = sc.token();
    if (tok.empty()) {
      if (in_solid) return error_at(name, line, "file ends inside a solid, expected 'endsolid'");
      break;
    }
    if (!in_solid) {
      if (tok != "solid")
        return error_at(
            name, line,
            fmt::format("expected 'solid' to start an ASCII STL solid, got {}", quote(tok)));
      sc.rest_of_line();  // the solid's name
      in_solid = true;
      ++solids;
      continue;
    }
    if (tok == "endsolid") {
      sc.rest_of_line();
      in_solid = false;
      continue;
    }
    if (tok != "facet")
      return error_at(name, line,
                      fmt::format("expected 'facet' or 'endsolid', got {}", quote(tok)));
    // The normal is recomputed from the corners by every consumer; some exporters write "nan" for
    // degenerate facets, so its values are skipped unread.
    HC_RETURN_IF_ERROR(expect(sc, "normal", name, "after 'facet'"));
    for (int k = 0; k < 3; ++k) {
      if (sc.token_before_comment().empty())
        return error_at(name, sc.line(), "facet normal has fewer than 3 components");
    }
    HC_RETURN_IF_ERROR(expect(sc, "outer", name, "after the facet normal"));
    HC_RETURN_IF_ERROR(expect(sc, "loop", name, "after 'outer'"));
    polygon.clear();
    for (;;) {
      sc.skip_space_and_comments();
      const std::size_t vline = sc.line();
      const std::string_view vt = sc.token();
      if (vt == "endloop") break;
      if (vt != "vertex")
        return error_at(name, vline,
                        vt.empty()
                            ? std::string("file ends inside a facet, expected 'vertex'")
                            : fmt::format("expected 'vertex' or 'endloop', got {}", quote(vt)));
      for (int k = 0; k < 3; ++k) {
        const std::string_view num = sc.token_before_comment();
        if (num.empty())
          return error_at(name, vline, fmt::format("vertex has {} coordinates, expected 3", k));
        double value = 0;
        switch (parse_double(num, value)) {
          case NumberParse::kOk:
            break;
          case NumberParse::kNotNumber:
            return error_at(
                name, vline,
                fmt::format("expected a number for vertex coordinate, got {}", quote(num)));
          case NumberParse::kNotFinite:
            return error_at(name, vline,
                            fmt::format("vertex coordinate {} is not finite", quote(num)));
        }
        polygon.push_back(value);
      }
    }
    const std::size_t nc = polygon.size() / 3;
    if (nc < 3)
      return error_at(name, sc.line(), fmt::format("facet has {} vertices, expected 3", nc));
    HC_RETURN_IF_ERROR(expect(sc, "endfacet", name, "after 'endloop'"));
    if (tris.size() + nc - 2 > limit)
      return error_at(name, sc.line(),
                      fmt::format("more than {} triangles (MeshReadOptions::max_elements)", limit));
    // Unwelded, each triangle gets its own corners (a fan shares c0 but STL corners are per facet).
    const int first = add_corner(&polygon[0]);
    for (std::size_t i = 1; i + 1 < nc; ++i) {
      const int a = i == 1 || options.weld_stl_vertices ? first : add_corner(&polygon[0]);
      const int b = add_corner(&polygon[3 * i]);
      const int c = add_corner(&polygon[3 * (i + 1)]);
      tris.push(a, b, c);
    }
    const std::size_t nv = options.weld_stl_vertices ? welder.size() : soup.size();
    if (nv > limit)
      return error_at(name, sc.line(),
                      fmt::format("more than {} vertices (MeshReadOptions::max_elements)", limit));
  }
  if (solids == 0) return error_at(name, 0, "no 'solid' found, expected an ASCII STL");
  if (tris.size() == 0) return error_at(name, 0, "no facets, expected a triangle mesh");
  TriangleMesh mesh;
  mesh.vertices =
      options.weld_stl_vertices ? std::move(welder).take_vertices() : std::move(soup).take();
  mesh.triangles = std::move(tris).take();
  return mesh;
}

// Text STL has no control characters other than whitespace (names may be UTF-8); binary STL has a
// NUL in its triangle count (byte 83) below 2^24 triangles, and zeros in its floats.
bool looks_like_text(std::string_view bytes) {
  const std::size_t n = std::min(bytes.size(), kTextSniffBytes);
  for (std::size_t i = 0; i < n; ++i) {
    const auto c = static_cast<unsigned char>(bytes[i]);
    if ((c < 0x20 && !is_space(static_cast<char>(c))) || c == 0x7f) return false;
  }
  return true;
}

bool starts_with_solid(std::string_view bytes) {
  std::size_t i = 0;
  while (i < bytes.size() && is_space(bytes[i])) ++i;
  return bytes.substr(i).starts_with("solid");
}

}  // namespace

Result<TriangleMesh> parse_stl(std::string_view bytes, std::string_view name,
                               const MeshReadOptions& options) {
  // Binary is recognised by its exact size, not by a missing "solid": many binary exporters start
  // their 80-byte header with "solid".
  std::uint32_t n = 0;
  if (bytes.size() >= kBinaryPreambleBytes) {
    n = load_le<std::uint32_t>(bytes.data() + kBinaryHeaderBytes);
    if (bytes.size() == kBinaryPreambleBytes + kBinaryTriangleBytes * std::uint64_t{n})
      return parse_binary(bytes, name, options, n);
  }
  if (starts_with_solid(bytes) && looks_like_text(bytes)) return parse_ascii(bytes, name, options);
  if (bytes.size() < kBinaryPreambleBytes)
    return error_at(
        name, 0,
        fmt::format("{} bytes is too short for a binary STL (at least {}) and it is not "
                    "an ASCII STL (starting with 'solid')",
                    bytes.size(), kBinaryPreambleBytes));
  return error_at(
      name, 0,
      fmt::format(
          "not a valid STL: as binary, the header's {} triangles need {} bytes but the file "
          "has {} (truncated or padded?); as ASCII, {}",
          n, kBinaryPreambleBytes + kBinaryTriangleBytes * std::uint64_t{n}, bytes.size(),
          starts_with_solid(bytes) ? "it contains binary bytes"
                                   : "it does not start with 'solid'"));
}

namespace {

std::array<float, 3> facet_normal(const TriangleMesh& mesh, Eigen::Index t) {
  const Eigen::Vector3d a = mesh.vertices.row(mesh.triangles(t, 0)).transpose();
  const Eigen::Vector3d b = mesh.vertices.row(mesh.triangles(t, 1)).transpose();
  const Eigen::Vector3d c = mesh.vertices.row(mesh.triangles(t, 2)).transpose();
  Eigen::Vector3d nrm = (b - a).cross(c - a);
  const double len = nrm.norm();
  // A degenerate facet gets a zero normal, which readers take as "compute it yourself".
  if (len > 0 && std::isfinite(len))
    nrm /= len;
  else
    nrm.setZero();
  return {static_cast<float>(nrm.x()), static_cast<float>(nrm.y()), static_cast<float>(nrm.z())};
}

}  // namespace

std::string format_stl(const TriangleMesh& mesh, bool binary) {
  const Eigen::Index nt = mesh.num_triangles();
  if (binary) {
    std::string out(kBinaryPreambleBytes + kBinaryTriangleBytes * static_cast<std::size_t>(nt),
                    '\0');
    constexpr std::string_view kHeader = "binary STL written by Hardcopy";
    std::memcpy(out.data(), kHeader.data(), kHeader.size());
    std::memset(out.data() + kHeader.size(), ' ', kBinaryHeaderBytes - kHeader.size());
    store_le(out.data() + kBinaryHeaderBytes, static_cast<std::uint32_t>(nt));
    char* p = out.data() + kBinaryPreambleBytes;
    for (Eigen::Index t = 0; t < nt; ++t, p += kBinaryTriangleBytes) {
      const auto nrm = facet_normal(mesh, t);
      for (int j = 0; j < 3; ++j) store_le(p + 4 * j, nrm[static_cast<std::size_t>(j)]);
      for (int c = 0; c < 3; ++c) {
        const int v = mesh.triangles(t, c);
        for (int j = 0; j < 3; ++j)
          store_le(p + 12 + 12 * c + 4 * j, static_cast<float>(mesh.vertices(v, j)));
      }
      store_le(p + 48, std::uint16_t{0});
    }
    return out;
  }
  std::string out;
  out.reserve(static_cast<std::size_t>(nt) * 260 + 64);
  out += "solid hardcopy\n";
  for (Eigen::Index t = 0; t < nt; ++t) {
    const auto nrm = facet_normal(mesh, t);
    out += "  facet normal ";
    for (int j = 0; j < 3; ++j) {
      if (j) out += ' ';
      append_float(out, nrm[static_cast<std::size_t>(j)]);
    }
    out += "\n    outer loop\n";
    for (int c = 0; c < 3; ++c) {
      const int v = mesh.triangles(t, c);
      out += "      vertex ";
      for (int j = 0; j < 3; ++j) {
        if (j) out += ' ';
        append_double(out, mesh.vertices(v, j));
      }
      out += '\n';
    }
    out += "    endloop\n  endfacet\n";
  }
  out += "endsolid hardcopy\n";
  return out;
}

}  // namespace hc::mesh_io
