// TetGen .poly reader. Hand-written: tetgenio::load_poly crashes (segfault) on malformed input and
// gives no line numbers. The file is read as a stream of whitespace-separated tokens ('#' starts a
// comment to the end of the line), which is how TetGen's loader treats it too.
#include <fmt/format.h>

#include <charconv>
#include <cmath>
#include <limits>

#include "common/file_io.h"
#include "processing/meshing/tetrahedralize.h"

namespace hc::meshing {
namespace {

class Tokens {
 public:
  Tokens(std::string_view text, std::string_view name)
      : p_(text.data()), end_(p_ + text.size()), name_(name) {}

  std::size_t line() const { return line_; }
  std::size_t remaining() const { return static_cast<std::size_t>(end_ - p_); }
  bool at_end() {
    skip();
    return p_ == end_;
  }
  // True when another token follows on the current line (before a newline or comment).
  bool more_on_line() {
    while (p_ != end_ && (*p_ == ' ' || *p_ == '\t' || *p_ == '\r')) ++p_;
    return p_ != end_ && *p_ != '\n' && *p_ != '#';
  }
  Status error(std::string_view what) const { return parse_error(std::string(name_), line_, what); }

  Result<std::string_view> next(std::string_view what) {
    skip();
    if (p_ == end_) return error(fmt::format("file ends before {}", what));
    const char* b = p_;
    while (p_ != end_ && !is_space(*p_) && *p_ != '#') ++p_;
    return std::string_view(b, static_cast<std::size_t>(p_ - b));
  }
  Result<std::int64_t> next_int(std::string_view what) {
    HC_ASSIGN_OR_RETURN(const std::string_view tok, next(what));
    std::int64_t v = 0;
    const auto [ptr, ec] = std::from_chars(tok.data(), tok.data() + tok.size(), v);
    if (ec != std::errc{} || ptr != tok.data() + tok.size())
      return error(fmt::format("expected {} (an integer), got '{}'", what, clip(tok)));
    return v;
  }
  Result<double> next_double(std::string_view what) {
    HC_ASSIGN_OR_RETURN(const std::string_view tok, next(what));
    double v = 0;
    const auto [ptr, ec] = std::from_chars(tok.data(), tok.data() + tok.size(), v);
    if (ec != std::errc{} || ptr != tok.data() + tok.size())
      return error(fmt::format("expected {} (a number), got '{}'", what, clip(tok)));
    if (!std::isfinite(v)) return error(fmt::format("{} is not finite", what));
    return v;
  }
  // A count in [0, max] whose items need at least `min_bytes_each` bytes of what follows.
  Result<std::int64_t> next_count(std::string_view what, std::int64_t max,
                                  std::uint64_t min_bytes_each) {
    HC_ASSIGN_OR_RETURN(const std::int64_t v, next_int(what));
    if (v < 0 || v > max) return error(fmt::format("{} {} out of range 0..{}", what, v, max));
    if (static_cast<std::uint64_t>(v) * min_bytes_each > remaining() + 1)
      return error(fmt::format("{} {} needs at least {} bytes, but only {} follow", what, v,
                               static_cast<std::uint64_t>(v) * min_bytes_each, remaining()));
    return v;
  }

 private:
  static bool is_space(char c) {
    return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\f' || c == '\v';
  }
  static std::string clip(std::string_view s) {
    std::string out;
    for (char c : s.substr(0, 40)) {
      const auto u = static_cast<unsigned char>(c);
      out += (u >= 0x20 && u < 0x7f) ? std::string(1, c) : fmt::format("\\x{:02x}", u);
    }
    return out;
  }
  void skip() {
    while (p_ != end_) {
      if (*p_ == '\n') {
        ++line_;
        ++p_;
      } else if (is_space(*p_)) {
        ++p_;
      } else if (*p_ == '#') {
        while (p_ != end_ && *p_ != '\n') ++p_;
      } else {
        break;
      }
    }
  }

  const char* p_;
  const char* end_;
  std::string_view name_;
  std::size_t line_ = 1;
};

constexpr std::int64_t kMaxCount = std::int64_t{1} << 26;

Result<Eigen::Vector3d> read_point(Tokens& t, std::string_view what) {
  Eigen::Vector3d p;
  for (int k = 0; k < 3; ++k) {
    HC_ASSIGN_OR_RETURN(p[k], t.next_double(fmt::format("coordinate {} of {}", "xyz"[k], what)));
  }
  return p;
}

}  // namespace

Result<Plc> parse_poly(std::string_view bytes, std::string_view name) {
  Tokens t(bytes, name);
  Plc plc;
  // Part 1: points.
  HC_ASSIGN_OR_RETURN(const std::int64_t np, t.next_count("the number of points", kMaxCount, 8));
  if (np == 0)
    return t.error("0 points: points in a separate .node file are not supported, put them inline");
  HC_ASSIGN_OR_RETURN(const std::int64_t dim, t.next_int("the dimension"));
  if (dim != 3) return t.error(fmt::format("dimension {}, expected 3", dim));
  HC_ASSIGN_OR_RETURN(const std::int64_t nattr, t.next_count("the attribute count", 64, 0));
  HC_ASSIGN_OR_RETURN(const std::int64_t markers, t.next_int("the boundary marker flag"));
  if (markers != 0 && markers != 1)
    return t.error(fmt::format("boundary marker flag {}, expected 0 or 1", markers));
  plc.points.resize(np, 3);
  std::int64_t base = 0;
  for (std::int64_t i = 0; i < np; ++i) {
    HC_ASSIGN_OR_RETURN(const std::int64_t index, t.next_int("a point index"));
    if (i == 0) {
      if (index != 0 && index != 1)
        return t.error(fmt::format("first point has index {}, expected 0 or 1", index));
      base = index;
    } else if (index != base + i) {
      return t.error(fmt::format("point index {}, expected {}", index, base + i));
    }
    HC_ASSIGN_OR_RETURN(const Eigen::Vector3d p, read_point(t, fmt::format("point {}", index)));
    plc.points.row(i) = p.transpose();
    for (std::int64_t a = 0; a < nattr + markers; ++a) {
      HC_ASSIGN_OR_RETURN(const double ignored, t.next_double("a point attribute or marker"));
      (void)ignored;
    }
  }
  // Part 2: facets.
  HC_ASSIGN_OR_RETURN(const std::int64_t nf, t.next_count("the number of facets", kMaxCount, 4));
  HC_ASSIGN_OR_RETURN(const std::int64_t facet_markers, t.next_int("the facet marker flag"));
  if (facet_markers != 0 && facet_markers != 1)
    return t.error(fmt::format("facet marker flag {}, expected 0 or 1", facet_markers));
  plc.facets.resize(static_cast<std::size_t>(nf));
  for (std::int64_t f = 0; f < nf; ++f) {
    Plc::Facet& facet = plc.facets[static_cast<std::size_t>(f)];
    HC_ASSIGN_OR_RETURN(
        const std::int64_t npoly,
        t.next_count(fmt::format("the polygon count of facet {}", f + base), kMaxCount, 4));
    if (npoly == 0) return t.error(fmt::format("facet {} has no polygon", f + base));
    // "<#polygons> [#holes] [marker]": the optional fields are on the same line when present.
    std::int64_t nholes = 0;
    if (t.more_on_line()) {
      HC_ASSIGN_OR_RETURN(
          nholes, t.next_count(fmt::format("the hole count of facet {}", f + base), kMaxCount, 8));
    }
    if (facet_markers == 1 && t.more_on_line()) {
      HC_ASSIGN_OR_RETURN(const std::int64_t m, t.next_int("a facet marker"));
      if (m < std::numeric_limits<int>::min() || m > std::numeric_limits<int>::max())
        return t.error(fmt::format("facet marker {} out of range", m));
      facet.marker = static_cast<int>(m);
    }
    facet.polygons.resize(static_cast<std::size_t>(npoly));
    for (auto& poly : facet.polygons) {
      HC_ASSIGN_OR_RETURN(
          const std::int64_t nc,
          t.next_count(fmt::format("the corner count of a polygon of facet {}", f + base),
                       kMaxCount, 2));
      if (nc < 1) return t.error(fmt::format("a polygon of facet {} has no corner", f + base));
      poly.resize(static_cast<std::size_t>(nc));
      for (int& c : poly) {
        HC_ASSIGN_OR_RETURN(const std::int64_t v, t.next_int("a polygon corner"));
        if (v < base || v >= base + np)
          return t.error(fmt::format("facet {}: point index {} out of range {}..{}", f + base, v,
                                     base, base + np - 1));
        c = static_cast<int>(v - base);
      }
    }
    for (std::int64_t h = 0; h < nholes; ++h) {
      HC_ASSIGN_OR_RETURN(const std::int64_t index, t.next_int("a facet hole index"));
      (void)index;
      HC_ASSIGN_OR_RETURN(const Eigen::Vector3d p,
                          read_point(t, fmt::format("hole {} of facet {}", h, f + base)));
      facet.holes.push_back(p);
    }
  }
  // Part 3: volume holes (the section may be missing at the end of the file).
  if (t.at_end()) return plc;
  HC_ASSIGN_OR_RETURN(const std::int64_t nh, t.next_count("the number of holes", kMaxCount, 8));
  for (std::int64_t h = 0; h < nh; ++h) {
    HC_ASSIGN_OR_RETURN(const std::int64_t index, t.next_int("a hole index"));
    HC_ASSIGN_OR_RETURN(const Eigen::Vector3d p, read_point(t, fmt::format("hole {}", index)));
    plc.holes.push_back(p);
  }
  // Part 4: regions (optional).
  if (t.at_end()) return plc;
  HC_ASSIGN_OR_RETURN(const std::int64_t nr, t.next_count("the number of regions", kMaxCount, 12));
  for (std::int64_t r = 0; r < nr; ++r) {
    HC_ASSIGN_OR_RETURN(const std::int64_t index, t.next_int("a region index"));
    RegionSeed seed;
    HC_ASSIGN_OR_RETURN(seed.seed, read_point(t, fmt::format("region {}", index)));
    HC_ASSIGN_OR_RETURN(const double attr, t.next_double("a region attribute"));
    if (attr != std::round(attr) || std::abs(attr) > 1e9)
      return t.error(fmt::format("region {}: attribute {} is not an integer", index, attr));
    seed.attribute = static_cast<int>(attr);
    HC_ASSIGN_OR_RETURN(seed.max_volume, t.next_double("a region volume constraint"));
    plc.regions.push_back(seed);
  }
  if (!t.at_end()) return t.error("unexpected text after the region list");
  return plc;
}

Result<Plc> read_poly(const std::filesystem::path& path) {
  if (path.extension() != ".poly")
    return invalid_argument(fmt::format("{}: expected a .poly file", path.string()));
  HC_ASSIGN_OR_RETURN(const std::string bytes, read_file(path, std::size_t{1} << 30));
  return parse_poly(bytes, path.string());
}

}  // namespace hc::meshing
