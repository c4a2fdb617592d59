// PLY (ascii, binary_little_endian, binary_big_endian, and gzip-compressed): reader and writer.
// Hand-written: Debian has no fast, robust, non-throwing PLY reader.
#include <array>
#include <bit>

#include "common/file_io.h"
#include "mesh_io_internal.h"

namespace hc::mesh_io {
namespace {

enum class PlyType : std::uint8_t {
  kInt8,
  kUint8,
  kInt16,
  kUint16,
  kInt32,
  kUint32,
  kFloat32,
  kFloat64
};
enum class PlyEncoding { kAscii, kBinaryLittle, kBinaryBig };
// What a property means to us; everything else is read past.
enum class Role : std::uint8_t { kNone, kX, kY, kZ, kFaceIndices };

std::size_t size_of(PlyType t) {
  switch (t) {
    case PlyType::kInt8:
    case PlyType::kUint8:
      return 1;
    case PlyType::kInt16:
    case PlyType::kUint16:
      return 2;
    case PlyType::kInt32:
    case PlyType::kUint32:
    case PlyType::kFloat32:
      return 4;
    case PlyType::kFloat64:
      return 8;
  }
  return 1;
}

bool is_integral(PlyType t) { return t != PlyType::kFloat32 && t != PlyType::kFloat64; }

std::optional<PlyType> type_from_name(std::string_view s) {
  struct Entry {
    std::string_view name;
    PlyType type;
  };
  static constexpr Entry kTypes[] = {
      {"char", PlyType::kInt8},       {"int8", PlyType::kInt8},       {"uchar", PlyType::kUint8},
      {"uint8", PlyType::kUint8},     {"short", PlyType::kInt16},     {"int16", PlyType::kInt16},
      {"ushort", PlyType::kUint16},   {"uint16", PlyType::kUint16},   {"int", PlyType::kInt32},
      {"int32", PlyType::kInt32},     {"uint", PlyType::kUint32},     {"uint32", PlyType::kUint32},
      {"float", PlyType::kFloat32},   {"float32", PlyType::kFloat32}, {"double", PlyType::kFloat64},
      {"float64", PlyType::kFloat64},
  };
  for (const auto& e : kTypes)
    if (e.name == s) return e.type;
  return std::nullopt;
}

struct Property {
  std::string name;
  bool is_list = false;
  PlyType type = PlyType::kFloat32;      // scalar type, or list item type
  PlyType count_type = PlyType::kUint8;  // lists only
  Role role = Role::kNone;
};

struct Element {
  std::string name;
  std::uint64_t count = 0;
  std::vector<Property> props;
  std::size_t line = 0;
  bool fixed_size() const {
    for (const auto& p : props)
      if (p.is_list) return false;
    return true;
  }
  // Bytes of one binary record with every list empty: a lower bound on the record's size.
  std::size_t min_binary_bytes() const {
    std::size_t n = 0;
    for (const auto& p : props) n += size_of(p.is_list ? p.count_type : p.type);
    return n;
  }
};

struct Header {
  PlyEncoding encoding = PlyEncoding::kAscii;
  std::vector<Element> elements;
  std::size_t body_offset = 0;  // first byte after "end_header\n"
  std::size_t body_line = 0;    // line number of that byte
  std::size_t vertex_element = SIZE_MAX;
  std::size_t face_element = SIZE_MAX;
};

constexpr std::size_t kMaxHeaderBytes = std::size_t{1} << 20;
// Least text an ASCII value takes ("0" and a separator).
constexpr std::uint64_t kMinAsciiValueBytes = 2;
// For the gzip cap: the most bytes one record is allowed when its size is not fixed (ASCII, or
// binary with lists). Generous for real files (an ASCII vertex with normals and colours is ~80
// bytes, a triangle ~12) while keeping a hostile header's claim bounded.
constexpr std::uint64_t kMaxVariableRecordBytes = 1024;
constexpr std::uint64_t kMaxVariableBytesPerProperty = 64;
// Trailing whitespace and padding allowed after the last element in a gzip stream.
constexpr std::uint64_t kInflateSlackBytes = std::uint64_t{1} << 20;

std::vector<std::string_view> split(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && is_blank(line[i])) ++i;
    const std::size_t b = i;
    while (i < line.size() && !is_blank(line[i])) ++i;
    if (i > b) out.push_back(line.substr(b, i - b));
  }
  return out;
}

// Parses the header of `text`, which may hold only the start of the file (the gzip cap reads the
// header before the body is inflated). Checks every count against max_elements, but not against
// the body size (the caller does that once the body is there).
Result<Header> parse_header(std::string_view text, std::string_view name,
                            const MeshReadOptions& options) {
  const std::size_t limit = element_limit(options);
  TextScanner sc(text);
  Header h;
  bool seen_format = false;
  bool ended = false;
  while (!sc.at_end()) {
    const std::size_t line = sc.line();
    if (sc.offset() > kMaxHeaderBytes)
      return error_at(name, line,
                      fmt::format("no 'end_header' in the first {} bytes", kMaxHeaderBytes));
    const std::string_view content = sc.rest_of_line();
    sc.next_line();
    if (line == 1) {
      if (content != "ply")
        return error_at(name, 1,
                        fmt::format("expected 'ply' as the first line, got {}", quote(content)));
      continue;
    }
    const auto tok = split(content);
    if (tok.empty()) continue;
    const std::string_view kw = tok[0];
    if (kw == "comment" || kw == "obj_info") continue;
    if (kw == "end_header") {
      ended = true;
      break;
    }
    if (kw == "format") {
      if (tok.size() != 3)
        return error_at(name, line,
                        "expected 'format <ascii|binary_little_endian|binary_big_endian> 1.0'");
      if (tok[1] == "ascii")
        h.encoding = PlyEncoding::kAscii;
      else if (tok[1] == "binary_little_endian")
        h.encoding = PlyEncoding::kBinaryLittle;
      else if (tok[1] == "binary_big_endian")
        h.encoding = PlyEncoding::kBinaryBig;
      else
        return error_at(name, line,
                        fmt::format("unknown format {}, expected ascii, binary_little_endian or "
                                    "binary_big_endian",
                                    quote(tok[1])));
      seen_format = true;
    } else if (kw == "element") {
      std::int64_t count = 0;
      if (tok.size() != 3 || !parse_int64(tok[2], count) || count < 0)
        return error_at(name, line,
                        "expected 'element <name> <count>' with a non-negative integer count");
      if (static_cast<std::uint64_t>(count) > limit)
        return error_at(name, line,
                        fmt::format("element '{}' declares {} items, more than the limit of {} "
                                    "(MeshReadOptions::max_elements)",
                                    tok[1], count, limit));
      h.elements.push_back(
          Element{std::string(tok[1]), static_cast<std::uint64_t>(count), {}, line});
    } else if (kw == "property") {
      if (h.elements.empty()) return error_at(name, line, "'property' before any 'element'");
      Property p;
      if (tok.size() >= 2 && tok[1] == "list") {
        if (tok.size() != 5)
          return error_at(name, line, "expected 'property list <count type> <item type> <name>'");
        const auto ct = type_from_name(tok[2]);
        const auto it = type_from_name(tok[3]);
        if (!ct || !it)
          return error_at(name, line,
                          fmt::format("unknown property type {}", quote(!ct ? tok[2] : tok[3])));
        if (!is_integral(*ct))
          return error_at(name, line,
                          fmt::format("list count type {} is not an integer type", quote(tok[2])));
        p.is_list = true;
        p.count_type = *ct;
        p.type = *it;
        p.name = std::string(tok[4]);
      } else {
        if (tok.size() != 3) return error_at(name, line, "expected 'property <type> <name>'");
        const auto t = type_from_name(tok[1]);
        if (!t) return error_at(name, line, fmt::format("unknown property type {}", quote(tok[1])));
        p.type = *t;
        p.name = std::string(tok[2]);
      }
      h.elements.back().props.push_back(std::move(p));
    } else {
      return error_at(name, line,
                      fmt::format("unknown header line {}, expected format, element, property, "
                                  "comment or end_header",
                                  quote(content)));
    }
  }
  if (!ended) return error_at(name, sc.line(), "file ends before 'end_header'");
  if (!seen_format) return error_at(name, 0, "header has no 'format' line");
  h.body_offset = sc.offset();
  h.body_line = sc.line();

  for (std::size_t e = 0; e < h.elements.size(); ++e) {
    Element& el = h.elements[e];
    if (el.name == "vertex") {
      if (h.vertex_element != SIZE_MAX) return error_at(name, el.line, "second 'vertex' element");
      h.vertex_element = e;
      for (Property& p : el.props) {
        const Role r = p.name == "x"   ? Role::kX
                       : p.name == "y" ? Role::kY
                       : p.name == "z" ? Role::kZ
                                       : Role::kNone;
        if (r == Role::kNone) continue;
        if (p.is_list)
          return error_at(name, el.line, fmt::format("vertex property '{}' is a list", p.name));
        p.role = r;
      }
      for (const Role r : {Role::kX, Role::kY, Role::kZ}) {
        int n = 0;
        for (const Property& p : el.props) n += p.role == r;
        if (n != 1)
          return error_at(name, el.line,
                          fmt::format("vertex element has {} '{}' properties, expected 1", n,
                                      r == Role::kX   ? "x"
                                      : r == Role::kY ? "y"
                                                      : "z"));
      }
    } else if (el.name == "face") {
      if (h.face_element != SIZE_MAX) return error_at(name, el.line, "second 'face' element");
      h.face_element = e;
      for (Property& p : el.props) {
        if (p.name != "vertex_indices" && p.name != "vertex_index") continue;
        if (!p.is_list)
          return error_at(name, el.line, fmt::format("face property '{}' is not a list", p.name));
        if (!is_integral(p.type))
          return error_at(name, el.line,
                          fmt::format("face property '{}' has floating-point items, expected "
                                      "integer vertex indices",
                                      p.name));
        p.role = Role::kFaceIndices;
        break;
      }
      bool found = false;
      for (const Property& p : el.props) found = found || p.role == Role::kFaceIndices;
      if (!found)
        return error_at(name, el.line,
                        "face element has no 'vertex_indices' (or 'vertex_index') list property");
    }
  }
  if (h.vertex_element == SIZE_MAX) return error_at(name, 0, "header has no 'vertex' element");
  if (h.face_element == SIZE_MAX)
    return error_at(name, 0, "header has no 'face' element, expected a triangle mesh");
  if (h.elements[h.face_element].count == 0)
    return error_at(name, h.elements[h.face_element].line,
                    "header declares 0 faces, expected a triangle mesh");
  return h;
}

// Checks the declared counts against the bytes that follow the header, before any allocation.
Status check_counts_fit(const Header& h, std::size_t body_bytes, std::string_view name) {
  std::uint64_t need = 0;
  for (const Element& el : h.elements) {
    const std::uint64_t per = h.encoding == PlyEncoding::kAscii
                                  ? kMinAsciiValueBytes * el.props.size()
                                  : el.min_binary_bytes();
    // count <= max_elements <= 2^31 and per is small: no overflow.
    need += el.count * per;
    if (need > body_bytes + 1)
      return error_at(name, el.line,
                      fmt::format("element '{}' declares {} items; with the elements before it "
                                  "they need at least {} bytes, but only {} bytes follow the "
                                  "header",
                                  el.name, el.count, need, body_bytes));
  }
  return {};
}

template <typename T>
T byteswap(T v) {
  if constexpr (sizeof(T) == 1) {
    return v;
  } else if constexpr (sizeof(T) == 2) {
    return std::bit_cast<T>(__builtin_bswap16(std::bit_cast<std::uint16_t>(v)));
  } else if constexpr (sizeof(T) == 4) {
    return std::bit_cast<T>(__builtin_bswap32(std::bit_cast<std::uint32_t>(v)));
  } else {
    return std::bit_cast<T>(__builtin_bswap64(std::bit_cast<std::uint64_t>(v)));
  }
}

template <bool kSwap, typename T>
T load(const char* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  if constexpr (kSwap) v = byteswap(v);
  return v;
}

template <bool kSwap>
double load_double(const char* p, PlyType t) {
  switch (t) {
    case PlyType::kInt8:
      return load<kSwap, std::int8_t>(p);
    case PlyType::kUint8:
      return load<kSwap, std::uint8_t>(p);
    case PlyType::kInt16:
      return load<kSwap, std::int16_t>(p);
    case PlyType::kUint16:
      return load<kSwap, std::uint16_t>(p);
    case PlyType::kInt32:
      return load<kSwap, std::int32_t>(p);
    case PlyType::kUint32:
      return load<kSwap, std::uint32_t>(p);
    case PlyType::kFloat32:
      return load<kSwap, float>(p);
    case PlyType::kFloat64:
      return load<kSwap, double>(p);
  }
  return 0;
}

// Integer types only (the header parser made sure).
template <bool kSwap>
std::int64_t load_int(const char* p, PlyType t) {
  switch (t) {
    case PlyType::kInt8:
      return load<kSwap, std::int8_t>(p);
    case PlyType::kUint8:
      return load<kSwap, std::uint8_t>(p);
    case PlyType::kInt16:
      return load<kSwap, std::int16_t>(p);
    case PlyType::kUint16:
      return load<kSwap, std::uint16_t>(p);
    case PlyType::kInt32:
      return load<kSwap, std::int32_t>(p);
    case PlyType::kUint32:
      return load<kSwap, std::uint32_t>(p);
    case PlyType::kFloat32:
    case PlyType::kFloat64:
      break;
  }
  return -1;
}

// The output being built, shared by the ASCII and binary body readers.
struct Builder {
  TriangleMesh mesh;  // vertices sized from the header; triangles arrive in `tris`
  TriangleBuffer tris;
  std::vector<int> corners;
  std::int64_t num_vertices = 0;
  std::size_t limit = 0;
};

std::string_view role_name(Role r) {
  switch (r) {
    case Role::kX:
      return "x";
    case Role::kY:
      return "y";
    case Role::kZ:
      return "z";
    default:
      return "";
  }
}

template <bool kSwap>
Status read_binary_body(std::string_view bytes, const Header& h, std::string_view name,
                        Builder& b) {
  const char* const base = bytes.data();
  const char* p = base + h.body_offset;
  const char* const end = base + bytes.size();
  auto offset = [base](const char* q) { return static_cast<std::size_t>(q - base); };

  for (std::size_t e = 0; e < h.elements.size(); ++e) {
    const Element& el = h.elements[e];
    if (el.props.empty()) continue;
    const bool is_vertex = e == h.vertex_element;
    const bool is_face = e == h.face_element;
    if (el.fixed_size()) {
      const std::size_t rec = el.min_binary_bytes();
      if (el.count > static_cast<std::uint64_t>(end - p) / rec)
        return error_at(name, 0,
                        fmt::format("byte {}: element '{}' needs {} × {} bytes, but only {} bytes "
                                    "are left (truncated file?)",
                                    offset(p), el.name, el.count, rec, end - p));
      if (!is_vertex) {
        p += el.count * rec;
        continue;
      }
      // The hot loop of a binary PLY: fixed offsets of x, y, z within each record.
      std::size_t off[3] = {0, 0, 0};
      PlyType type[3] = {PlyType::kFloat32, PlyType::kFloat32, PlyType::kFloat32};
      std::size_t at = 0;
      for (const Property& prop : el.props) {
        if (prop.role != Role::kNone) {
          const int k = static_cast<int>(prop.role) - static_cast<int>(Role::kX);
          off[k] = at;
          type[k] = prop.type;
        }
        at += size_of(prop.type);
      }
      double* v = b.mesh.vertices.data();
      const bool all_float = type[0] == PlyType::kFloat32 && type[1] == PlyType::kFloat32 &&
                             type[2] == PlyType::kFloat32;
      for (std::uint64_t i = 0; i < el.count; ++i, p += rec, v += 3) {
        if (all_float) {
          v[0] = load<kSwap, float>(p + off[0]);
          v[1] = load<kSwap, float>(p + off[1]);
          v[2] = load<kSwap, float>(p + off[2]);
        } else {
          v[0] = load_double<kSwap>(p + off[0], type[0]);
          v[1] = load_double<kSwap>(p + off[1], type[1]);
          v[2] = load_double<kSwap>(p + off[2], type[2]);
        }
        if (!std::isfinite(v[0]) || !std::isfinite(v[1]) || !std::isfinite(v[2])) {
          const int k = !std::isfinite(v[0]) ? 0 : !std::isfinite(v[1]) ? 1 : 2;
          return error_at(name, 0,
                          fmt::format("byte {}: vertex {} has a non-finite {} coordinate, expected "
                                      "a finite number",
                                      offset(p + off[k]), i, "xyz"[k]));
        }
      }
      continue;
    }
    // Records with lists: walk property by property.
    for (std::uint64_t i = 0; i < el.count; ++i) {
      for (const Property& prop : el.props) {
        if (!prop.is_list) {
          const std::size_t sz = size_of(prop.type);
          if (static_cast<std::size_t>(end - p) < sz)
            return error_at(name, 0,
                            fmt::format("byte {}: file ends in {} {}, expected property '{}'",
                                        offset(p), el.name, i, prop.name));
          if (is_vertex && prop.role != Role::kNone) {
            const double value = load_double<kSwap>(p, prop.type);
            if (!std::isfinite(value))
              return error_at(name, 0,
                              fmt::format("byte {}: vertex {} has a non-finite {} coordinate, "
                                          "expected a finite number",
                                          offset(p), i, role_name(prop.role)));
            b.mesh.vertices(static_cast<Eigen::Index>(i),
                            static_cast<int>(prop.role) - static_cast<int>(Role::kX)) = value;
          }
          p += sz;
          continue;
        }
        const std::size_t csz = size_of(prop.count_type);
        if (static_cast<std::size_t>(end - p) < csz)
          return error_at(name, 0,
                          fmt::format("byte {}: file ends in {} {}, expected the length of list "
                                      "'{}'",
                                      offset(p), el.name, i, prop.name));
        const std::int64_t n = load_int<kSwap>(p, prop.count_type);
        const char* const list_at = p;
        p += csz;
        const std::size_t isz = size_of(prop.type);
        if (n < 0 || static_cast<std::uint64_t>(n) > static_cast<std::uint64_t>(end - p) / isz)
          return error_at(name, 0,
                          fmt::format("byte {}: {} {}: list '{}' declares {} items, but only {} "
                                      "bytes are left",
                                      offset(list_at), el.name, i, prop.name, n, end - p));
        if (!(is_face && prop.role == Role::kFaceIndices)) {
          p += static_cast<std::size_t>(n) * isz;
          continue;
        }
        if (n < 3)
          return error_at(name, 0,
                          fmt::format("byte {}: face {} has {} vertices, expected at least 3",
                                      offset(list_at), i, n));
        b.corners.clear();
        for (std::int64_t j = 0; j < n; ++j, p += isz) {
          const std::int64_t idx = load_int<kSwap>(p, prop.type);
          if (idx < 0 || idx >= b.num_vertices)
            return error_at(name, 0,
                            fmt::format("byte {}: face {}: vertex index {} is out of range, "
                                        "expected 0..{}",
                                        offset(p), i, idx, b.num_vertices - 1));
          b.corners.push_back(static_cast<int>(idx));
        }
        if (b.tris.size() + b.corners.size() - 2 > b.limit)
          return error_at(name, 0,
                          fmt::format("byte {}: more than {} triangles "
                                      "(MeshReadOptions::max_elements)",
                                      offset(list_at), b.limit));
        fan_triangulate(b.corners, b.tris);
      }
    }
  }
  return {};
}

Status read_ascii_body(std::string_view bytes, const Header& h, std::string_view name, Builder& b) {
  TextScanner sc(bytes.substr(h.body_offset), h.body_line);
  auto next = [&sc]() {
    sc.skip_space();
    return sc.token();
  };
  for (std::size_t e = 0; e < h.elements.size(); ++e) {
    const Element& el = h.elements[e];
    if (el.props.empty()) continue;
    const bool is_vertex = e == h.vertex_element;
    const bool is_face = e == h.face_element;
    for (std::uint64_t i = 0; i < el.count; ++i) {
      for (const Property& prop : el.props) {
        const std::string_view tok = next();
        if (tok.empty())
          return error_at(
              name, sc.line(),
              fmt::format("file ends in {} {}, expected property '{}'", el.name, i, prop.name));
        if (!prop.is_list) {
          double value = 0;
          const NumberParse r = parse_double(tok, value);
          if (r == NumberParse::kNotNumber)
            return error_at(name, sc.line(),
                            fmt::format("{} {}: expected a number for '{}', got {}", el.name, i,
                                        prop.name, quote(tok)));
          if (is_vertex && prop.role != Role::kNone) {
            if (r == NumberParse::kNotFinite)
              return error_at(name, sc.line(),
                              fmt::format("vertex {}: coordinate {} is not finite", i, quote(tok)));
            b.mesh.vertices(static_cast<Eigen::Index>(i),
                            static_cast<int>(prop.role) - static_cast<int>(Role::kX)) = value;
          }
          continue;
        }
        std::int64_t n = 0;
        if (!parse_int64(tok, n) || n < 0)
          return error_at(name, sc.line(),
                          fmt::format("{} {}: expected the length of list '{}', got {}", el.name, i,
                                      prop.name, quote(tok)));
        if (static_cast<std::uint64_t>(n) > sc.remaining() / kMinAsciiValueBytes + 1)
          return error_at(name, sc.line(),
                          fmt::format("{} {}: list '{}' declares {} items, more than the rest of "
                                      "the file can hold",
                                      el.name, i, prop.name, n));
        const bool indices = is_face && prop.role == Role::kFaceIndices;
        if (indices && n < 3)
          return error_at(name, sc.line(),
                          fmt::format("face {} has {} vertices, expected at least 3", i, n));
        b.corners.clear();
        for (std::int64_t j = 0; j < n; ++j) {
          const std::string_view item = next();
          if (item.empty())
            return error_at(name, sc.line(),
                            fmt::format("file ends in {} {}, list '{}' has {} of {} items", el.name,
                                        i, prop.name, j, n));
          if (!indices) continue;
          std::int64_t idx = 0;
          if (!parse_int64(item, idx))
            return error_at(
                name, sc.line(),
                fmt::format("face {}: expected a vertex index, got {}", i, quote(item)));
          if (idx < 0 || idx >= b.num_vertices)
            return error_at(name, sc.line(),
                            fmt::format("face {}: vertex index {} is out of range, expected 0..{}",
                                        i, idx, b.num_vertices - 1));
          b.corners.push_back(static_cast<int>(idx));
        }
        if (!indices) continue;
        if (b.tris.size() + b.corners.size() - 2 > b.limit)
          return error_at(
              name, sc.line(),
              fmt::format("more than {} triangles (MeshReadOptions::max_elements)", b.limit));
        fan_triangulate(b.corners, b.tris);
      }
    }
  }
  return {};
}

Result<TriangleMesh> parse_plain(std::string_view bytes, std::string_view name,
                                 const MeshReadOptions& options) {
  HC_ASSIGN_OR_RETURN(const Header h, parse_header(bytes, name, options));
  HC_RETURN_IF_ERROR(check_counts_fit(h, bytes.size() - h.body_offset, name));
  Builder b;
  b.limit = element_limit(options);
  b.num_vertices = static_cast<std::int64_t>(h.elements[h.vertex_element].count);
  b.mesh.vertices.resize(b.num_vertices, 3);
  advise_huge_pages(b.mesh.vertices.data(), b.mesh.vertices.size() * sizeof(double));
  b.tris = TriangleBuffer(static_cast<std::size_t>(h.elements[h.face_element].count));
  switch (h.encoding) {
    case PlyEncoding::kAscii:
      HC_RETURN_IF_ERROR(read_ascii_body(bytes, h, name, b));
      break;
    case PlyEncoding::kBinaryLittle:
      HC_RETURN_IF_ERROR(
          read_binary_body<std::endian::native == std::endian::big>(bytes, h, name, b));
      break;
    case PlyEncoding::kBinaryBig:
      HC_RETURN_IF_ERROR(
          read_binary_body<std::endian::native == std::endian::little>(bytes, h, name, b));
      break;
  }
  b.mesh.triangles = std::move(b.tris).take();
  return std::move(b.mesh);
}

// Caps the inflated size of a .ply.gz: the header alone first, then what its counts allow.
class PlyInflateCap final : public InflateCap {
 public:
  PlyInflateCap(std::string_view name, const MeshReadOptions& options)
      : name_(name), options_(options) {}

  Result<std::size_t> cap(std::string_view so_far) override {
    if (body_cap_) return *body_cap_;
    if (so_far.find("end_header") == std::string_view::npos) {
      if (so_far.size() >= kMaxHeaderBytes)
        return error_at(
            name_, 0,
            fmt::format("no 'end_header' in the first {} inflated bytes", kMaxHeaderBytes));
      return kMaxHeaderBytes;
    }
    // The header may still be cut mid-line: only trust it once its end is in.
    // "end_header" may be cut mid-line or sit in a comment; until the header parses, keep
    // inflating up to the header limit (parse_plain reports the header's own error afterwards).
    auto header = parse_header(so_far, name_, options_);
    if (!header.ok()) {
      if (so_far.size() < kMaxHeaderBytes) return kMaxHeaderBytes;
      return header.status();
    }
    std::uint64_t total = header->body_offset + kInflateSlackBytes;
    for (const Element& el : header->elements) {
      const std::uint64_t per =
          header->encoding != PlyEncoding::kAscii && el.fixed_size()
              ? el.min_binary_bytes()
              : kMaxVariableRecordBytes + kMaxVariableBytesPerProperty * el.props.size();
      // count <= 2^31 and per < 2^24 (the header is at most 1 MiB): the product cannot
      // overflow, and stopping at the file-size limit keeps the sum from overflowing.
      total += el.count * per;
      if (total >= kDefaultMaxFileBytes) break;
    }
    body_cap_ = static_cast<std::size_t>(std::min<std::uint64_t>(total, kDefaultMaxFileBytes));
    return *body_cap_;
  }

 private:
  std::string_view name_;
  const MeshReadOptions& options_;
  std::optional<std::size_t> body_cap_;
};

}  // namespace

Result<TriangleMesh> parse_ply(std::string_view bytes, std::string_view name,
                               const MeshReadOptions& options) {
  if (!is_gzip(bytes)) return parse_plain(bytes, name, options);
  PlyInflateCap cap(name, options);
  HC_ASSIGN_OR_RETURN(const std::string text, gzip_inflate(bytes, name, cap));
  if (text.empty()) return error_at(name, 0, "gzip data inflates to nothing, expected a PLY file");
  // Byte offsets in messages are into the inflated data.
  return parse_plain(text, fmt::format("{} (inflated)", name), options);
}

std::string format_ply(const TriangleMesh& mesh, bool binary) {
  const auto nv = static_cast<std::size_t>(mesh.num_vertices());
  const auto nt = static_cast<std::size_t>(mesh.num_triangles());
  std::string out = fmt::format(
      "ply\nformat {} 1.0\ncomment written by Hardcopy\nelement vertex {}\n"
      "property double x\nproperty double y\nproperty double z\nelement face {}\n"
      "property list uchar int vertex_indices\nend_header\n",
      binary ? "binary_little_endian" : "ascii", nv, nt);
  if (binary) {
    constexpr std::size_t kVertexBytes = 3 * sizeof(double);
    constexpr std::size_t kFaceBytes = 1 + 3 * sizeof(std::int32_t);
    std::size_t at = out.size();
    out.resize(at + nv * kVertexBytes + nt * kFaceBytes);
    char* p = out.data() + at;
    for (std::size_t i = 0; i < nv; ++i)
      for (int k = 0; k < 3; ++k, p += sizeof(double))
        store_le(p, mesh.vertices(static_cast<Eigen::Index>(i), k));
    for (std::size_t t = 0; t < nt; ++t) {
      *p++ = 3;
      for (int k = 0; k < 3; ++k, p += sizeof(std::int32_t))
        store_le(p, static_cast<std::int32_t>(mesh.triangles(static_cast<Eigen::Index>(t), k)));
    }
    return out;
  }
  append_text_rows(out, mesh, "", "3 ", 0);
  return out;
}

}  // namespace hc::mesh_io
