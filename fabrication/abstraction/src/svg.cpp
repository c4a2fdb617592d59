// SVG paths in and out (svg.h). expat does the XML; the path grammar, transforms and curve
// flattening follow SVG 1.1 (paths: section 8.3; arcs: implementation notes F.6).
#include "fabrication/abstraction/svg.h"

#include <expat.h>
#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstring>
#include <numbers>
#include <vector>

#include "common/file_io.h"

namespace hc::abstraction {
namespace {

using Affine = Eigen::Matrix<double, 2, 3>;  // [A | t]: p -> A p + t

Affine identity() {
  Affine m;
  m << 1, 0, 0, 0, 1, 0;
  return m;
}
Affine compose(const Affine& a, const Affine& b) {  // a after b
  Affine m;
  m.leftCols<2>() = a.leftCols<2>() * b.leftCols<2>();
  m.col(2) = a.leftCols<2>() * b.col(2) + a.col(2);
  return m;
}
Eigen::Vector2d apply(const Affine& m, const Eigen::Vector2d& p) {
  return m.leftCols<2>() * p + m.col(2);
}

// A cursor over an attribute value: numbers separated by whitespace and commas.
class Scanner {
 public:
  explicit Scanner(std::string_view s) : s_(s) {}
  void skip() {
    while (i_ < s_.size() && (std::isspace(static_cast<unsigned char>(s_[i_])) || s_[i_] == ','))
      ++i_;
  }
  bool done() {
    skip();
    return i_ >= s_.size();
  }
  char peek() {
    skip();
    return i_ < s_.size() ? s_[i_] : '\0';
  }
  char get() { return s_[i_++]; }
  bool number_next() {
    const char c = peek();
    return c == '-' || c == '+' || c == '.' || std::isdigit(static_cast<unsigned char>(c));
  }
  Result<double> number() {
    skip();
    double v = 0;
    const char* b = s_.data() + i_;
    const char* e = s_.data() + s_.size();
    if (b < e && *b == '+') ++b;
    const auto [p, ec] = std::from_chars(b, e, v);
    if (ec != std::errc() || !std::isfinite(v)) {
      return invalid_argument(fmt::format("expected a number at \"{}\"", s_.substr(i_, 20)));
    }
    i_ = static_cast<std::size_t>(p - s_.data());
    return v;
  }
  // Arc flags may be written without separators ("a1 1 0 00 1 1").
  Result<bool> flag() {
    const char c = peek();
    if (c != '0' && c != '1') return invalid_argument("expected an arc flag 0 or 1");
    ++i_;
    return c == '1';
  }

 private:
  std::string_view s_;
  std::size_t i_ = 0;
};

Result<Affine> parse_transform(std::string_view text) {
  Affine m = identity();
  std::size_t i = 0;
  while (i < text.size()) {
    while (i < text.size() && (std::isspace(static_cast<unsigned char>(text[i])) || text[i] == ','))
      ++i;
    if (i >= text.size()) break;
    const std::size_t open = text.find('(', i);
    const std::size_t close = text.find(')', i);
    if (open == std::string_view::npos || close == std::string_view::npos || close < open) {
      return invalid_argument(fmt::format("bad transform \"{}\"", text));
    }
    std::string_view name = text.substr(i, open - i);
    while (!name.empty() && std::isspace(static_cast<unsigned char>(name.back())))
      name.remove_suffix(1);
    Scanner sc(text.substr(open + 1, close - open - 1));
    std::vector<double> a;
    while (!sc.done()) {
      HC_ASSIGN_OR_RETURN(double v, sc.number());
      a.push_back(v);
    }
    Affine t = identity();
    const auto need = [&](std::size_t lo, std::size_t hi) -> Status {
      if (a.size() < lo || a.size() > hi) {
        return invalid_argument(
            fmt::format("transform {} takes {} to {} numbers, got {}", name, lo, hi, a.size()));
      }
      return {};
    };
    if (name == "matrix") {
      HC_RETURN_IF_ERROR(need(6, 6));
      t << a[0], a[2], a[4], a[1], a[3], a[5];
    } else if (name == "translate") {
      HC_RETURN_IF_ERROR(need(1, 2));
      t(0, 2) = a[0];
      t(1, 2) = a.size() > 1 ? a[1] : 0.0;
    } else if (name == "scale") {
      HC_RETURN_IF_ERROR(need(1, 2));
      t(0, 0) = a[0];
      t(1, 1) = a.size() > 1 ? a[1] : a[0];
    } else if (name == "rotate") {
      HC_RETURN_IF_ERROR(need(1, 3));
      const double r = a[0] * std::numbers::pi / 180.0;
      Affine rot;
      rot << std::cos(r), -std::sin(r), 0, std::sin(r), std::cos(r), 0;
      if (a.size() == 3) {
        Affine to = identity(), back = identity();
        to.col(2) << a[1], a[2];
        back.col(2) << -a[1], -a[2];
        rot = compose(to, compose(rot, back));
      } else if (a.size() == 2) {
        return invalid_argument("transform rotate takes 1 or 3 numbers");
      }
      t = rot;
    } else if (name == "skewX" || name == "skewY") {
      HC_RETURN_IF_ERROR(need(1, 1));
      const double k = std::tan(a[0] * std::numbers::pi / 180.0);
      (name == "skewX" ? t(0, 1) : t(1, 0)) = k;
    } else {
      return invalid_argument(fmt::format("unknown transform \"{}\"", name));
    }
    m = compose(m, t);
    i = close + 1;
  }
  return m;
}

// Flattening: a curve whose second derivative is at most `curvature` (in length per unit
// parameter squared) deviates from its n-piece chord polyline by at most curvature / (8 n^2).
// NaN (non-finite coordinates or a degenerate transform, which validate() rejects) gives one piece.
int pieces(double curvature, double flatness) {
  const double n = std::ceil(std::sqrt(curvature / (8.0 * flatness)));
  if (!(n >= 1.0)) return 1;
  return static_cast<int>(std::min(n, 10000.0));
}

// The most points a document may flatten to (160 MB): beyond it the reader stops with an error
// instead of exhausting memory on a few kilobytes of curves with a tiny flatness.
constexpr std::size_t kMaxPoints = 10'000'000;

struct PathBuilder {
  const Affine* m = nullptr;
  double flatness = 0.01;  // in user units
  Polygon2* out = nullptr;
  std::size_t* points = nullptr;  // flattened so far, over the whole document
  Loop2 loop;
  void add(const Eigen::Vector2d& p) {
    if (*points >= kMaxPoints) return;  // parse_svg reports it
    const Eigen::Vector2d q = apply(*m, p);
    if (loop.empty() || loop.back() != q) {
      loop.push_back(q);
      ++*points;
    }
  }
  void close() {
    while (loop.size() > 1 && loop.back() == loop.front()) loop.pop_back();
    if (loop.size() >= 3 && signed_area(loop) != 0.0) out->loops.push_back(loop);
    loop.clear();
  }
  void cubic(const Eigen::Vector2d& p0, const Eigen::Vector2d& p1, const Eigen::Vector2d& p2,
             const Eigen::Vector2d& p3) {
    // |B''| <= 6 max(|p2 - 2 p1 + p0|, |p3 - 2 p2 + p1|).
    const int n =
        pieces(6 * std::max((p2 - 2 * p1 + p0).norm(), (p3 - 2 * p2 + p1).norm()), flatness);
    for (int i = 1; i <= n; ++i) {
      const double t = static_cast<double>(i) / n, s = 1 - t;
      add(s * s * s * p0 + 3 * s * s * t * p1 + 3 * s * t * t * p2 + t * t * t * p3);
    }
  }
  void quadratic(const Eigen::Vector2d& p0, const Eigen::Vector2d& p1, const Eigen::Vector2d& p2) {
    const int n = pieces(2 * (p2 - 2 * p1 + p0).norm(), flatness);  // |B''| = 2 |p2 - 2 p1 + p0|
    for (int i = 1; i <= n; ++i) {
      const double t = static_cast<double>(i) / n, s = 1 - t;
      add(s * s * p0 + 2 * s * t * p1 + t * t * p2);
    }
  }
  // SVG 1.1 F.6.5: endpoint to centre parameterisation.
  void arc(const Eigen::Vector2d& p0, double rx, double ry, double phi_deg, bool large, bool sweep,
           const Eigen::Vector2d& p1) {
    rx = std::abs(rx);
    ry = std::abs(ry);
    if (rx == 0 || ry == 0 || p0 == p1) {
      add(p1);
      return;
    }
    const double phi = phi_deg * std::numbers::pi / 180.0;
    const double c = std::cos(phi), s = std::sin(phi);
    const Eigen::Vector2d h = 0.5 * (p0 - p1);
    const Eigen::Vector2d q(c * h.x() + s * h.y(), -s * h.x() + c * h.y());
    const double lambda = q.x() * q.x() / (rx * rx) + q.y() * q.y() / (ry * ry);
    if (lambda > 1) {
      rx *= std::sqrt(lambda);
      ry *= std::sqrt(lambda);
    }
    const double num = rx * rx * ry * ry - rx * rx * q.y() * q.y() - ry * ry * q.x() * q.x();
    const double den = rx * rx * q.y() * q.y() + ry * ry * q.x() * q.x();
    double k = std::sqrt(std::max(0.0, num / den));
    if (large == sweep) k = -k;
    const Eigen::Vector2d cq(k * rx * q.y() / ry, -k * ry * q.x() / rx);
    const Eigen::Vector2d centre =
        Eigen::Vector2d(c * cq.x() - s * cq.y(), s * cq.x() + c * cq.y()) + 0.5 * (p0 + p1);
    const auto angle = [](const Eigen::Vector2d& u, const Eigen::Vector2d& v) {
      return std::atan2(u.x() * v.y() - u.y() * v.x(), u.dot(v));
    };
    const Eigen::Vector2d u((q.x() - cq.x()) / rx, (q.y() - cq.y()) / ry);
    const Eigen::Vector2d v((-q.x() - cq.x()) / rx, (-q.y() - cq.y()) / ry);
    const double theta = angle(Eigen::Vector2d(1, 0), u);
    double delta = angle(u, v);
    if (!sweep && delta > 0) delta -= 2 * std::numbers::pi;
    if (sweep && delta < 0) delta += 2 * std::numbers::pi;
    // Over a parameter range |delta| the ellipse's second derivative is at most max(rx, ry)
    // delta^2.
    const int n = pieces(std::max(rx, ry) * delta * delta, flatness);
    for (int i = 1; i <= n; ++i) {
      const double t = theta + delta * i / n;
      const Eigen::Vector2d e(rx * std::cos(t), ry * std::sin(t));
      add(i == n ? p1
                 : Eigen::Vector2d(c * e.x() - s * e.y() + centre.x(),
                                   s * e.x() + c * e.y() + centre.y()));
    }
  }
};

Status parse_path(std::string_view d, PathBuilder* b) {
  Scanner sc(d);
  Eigen::Vector2d cur(0, 0), start(0, 0), last_ctrl(0, 0);
  char cmd = 0, prev = 0;
  while (!sc.done()) {
    if (std::isalpha(static_cast<unsigned char>(sc.peek()))) {
      cmd = sc.get();
    } else if (cmd == 0) {
      return invalid_argument("path data must start with a command");
    } else if (cmd == 'M') {
      cmd = 'L';  // coordinates after a moveto are linetos
    } else if (cmd == 'm') {
      cmd = 'l';
    } else if (cmd == 'Z' || cmd == 'z') {
      return invalid_argument("numbers after Z");
    }
    const bool rel = std::islower(static_cast<unsigned char>(cmd)) != 0;
    const Eigen::Vector2d base = rel ? cur : Eigen::Vector2d::Zero();
    const auto point = [&]() -> Result<Eigen::Vector2d> {
      HC_ASSIGN_OR_RETURN(double x, sc.number());
      HC_ASSIGN_OR_RETURN(double y, sc.number());
      return Eigen::Vector2d(Eigen::Vector2d(x, y) + base);
    };
    const char up = static_cast<char>(std::toupper(static_cast<unsigned char>(cmd)));
    switch (up) {
      case 'M': {
        b->close();
        HC_ASSIGN_OR_RETURN(cur, point());
        start = cur;
        b->add(cur);
        break;
      }
      case 'L': {
        HC_ASSIGN_OR_RETURN(cur, point());
        b->add(cur);
        break;
      }
      case 'H':
      case 'V': {
        HC_ASSIGN_OR_RETURN(double v, sc.number());
        if (up == 'H')
          cur.x() = v + (rel ? cur.x() : 0.0);
        else
          cur.y() = v + (rel ? cur.y() : 0.0);
        b->add(cur);
        break;
      }
      case 'C':
      case 'S': {
        Eigen::Vector2d c1;
        if (up == 'C') {
          HC_ASSIGN_OR_RETURN(c1, point());
        } else {
          const char p = static_cast<char>(std::toupper(static_cast<unsigned char>(prev)));
          c1 = (p == 'C' || p == 'S') ? Eigen::Vector2d(2 * cur - last_ctrl) : cur;
        }
        HC_ASSIGN_OR_RETURN(Eigen::Vector2d c2, point());
        HC_ASSIGN_OR_RETURN(Eigen::Vector2d p, point());
        b->cubic(cur, c1, c2, p);
        last_ctrl = c2;
        cur = p;
        break;
      }
      case 'Q':
      case 'T': {
        Eigen::Vector2d c1;
        if (up == 'Q') {
          HC_ASSIGN_OR_RETURN(c1, point());
        } else {
          const char p = static_cast<char>(std::toupper(static_cast<unsigned char>(prev)));
          c1 = (p == 'Q' || p == 'T') ? Eigen::Vector2d(2 * cur - last_ctrl) : cur;
        }
        HC_ASSIGN_OR_RETURN(Eigen::Vector2d p, point());
        b->quadratic(cur, c1, p);
        last_ctrl = c1;
        cur = p;
        break;
      }
      case 'A': {
        HC_ASSIGN_OR_RETURN(double rx, sc.number());
        HC_ASSIGN_OR_RETURN(double ry, sc.number());
        HC_ASSIGN_OR_RETURN(double phi, sc.number());
        HC_ASSIGN_OR_RETURN(bool large, sc.flag());
        HC_ASSIGN_OR_RETURN(bool sweep, sc.flag());
        HC_ASSIGN_OR_RETURN(Eigen::Vector2d p, point());
        b->arc(cur, rx, ry, phi, large, sweep, p);
        cur = p;
        break;
      }
      case 'Z': {
        b->close();
        cur = start;
        break;
      }
      default:
        return invalid_argument(fmt::format("unknown path command '{}'", cmd));
    }
    prev = cmd;
  }
  b->close();
  return {};
}

Result<double> attribute_number(const char* value, std::string_view name) {
  Scanner sc(value);
  auto v = sc.number();
  if (!v.ok()) return invalid_argument(fmt::format("attribute {}: {}", name, v.status().message()));
  return v;
}

// Length with an optional unit, in millimetres; unit-less means CSS pixels.
Result<std::pair<double, bool>> length_mm(std::string_view s) {
  double v = 0;
  const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || !std::isfinite(v))
    return invalid_argument(fmt::format("bad length \"{}\"", s));
  const std::string_view unit = s.substr(static_cast<std::size_t>(p - s.data()));
  if (unit == "mm") return std::pair{v, true};
  if (unit == "cm") return std::pair{10 * v, true};
  if (unit == "in") return std::pair{25.4 * v, true};
  if (unit == "pt") return std::pair{25.4 / 72 * v, true};
  if (unit == "px" || unit.empty()) return std::pair{25.4 / 96 * v, false};
  return invalid_argument(fmt::format("unsupported length unit in \"{}\"", s));
}

struct Parser {
  SvgReadOptions options;
  XML_Parser xml = nullptr;
  std::vector<Affine> stack;
  Polygon2 out;
  std::size_t points = 0;
  Status error;
  bool root_seen = false;

  const char* attr(const char** atts, std::string_view name) {
    for (int i = 0; atts[i]; i += 2) {
      if (name == atts[i]) return atts[i + 1];
    }
    return nullptr;
  }
  Status root(const char** atts) {
    Affine m = identity();
    const double px = 25.4 / 96;
    m(0, 0) = m(1, 1) = px;
    const char* w = attr(atts, "width");
    const char* vb = attr(atts, "viewBox");
    if (vb) {
      Scanner sc(vb);
      std::array<double, 4> box{};
      for (double& x : box) {
        HC_ASSIGN_OR_RETURN(x, sc.number());
      }
      if (!(box[2] > 0) || !(box[3] > 0))
        return invalid_argument("viewBox width and height must be > 0");
      double scale = px;
      if (w) {
        HC_ASSIGN_OR_RETURN(auto len, length_mm(w));
        scale = len.first / box[2];
      }
      // Scale only: the viewBox origin is not subtracted, so coordinates round-trip.
      m << scale, 0, 0, 0, scale, 0;
    }
    stack.back() = m;
    return {};
  }
  Status element(std::string_view name, const char** atts) {
    Affine m = stack.back();
    if (const char* t = attr(atts, "transform")) {
      HC_ASSIGN_OR_RETURN(Affine local, parse_transform(t));
      m = compose(m, local);
    }
    stack.push_back(m);
    const double scale = std::sqrt(std::abs(m.leftCols<2>().determinant()));
    PathBuilder b{&stack.back(), options.flatness_mm / std::max(scale, 1e-300), &out, &points, {}};
    const auto num = [&](std::string_view key, double fallback) -> Result<double> {
      const char* v = attr(atts, key);
      if (!v) return fallback;
      return attribute_number(v, key);
    };
    if (name == "path") {
      const char* d = attr(atts, "d");
      if (d) return parse_path(d, &b);
    } else if (name == "polygon" || name == "polyline") {
      const char* pts = attr(atts, "points");
      if (!pts) return {};
      Scanner sc(pts);
      while (!sc.done()) {
        HC_ASSIGN_OR_RETURN(double x, sc.number());
        HC_ASSIGN_OR_RETURN(double y, sc.number());
        b.add({x, y});
      }
      b.close();
    } else if (name == "rect") {
      HC_ASSIGN_OR_RETURN(double x, num("x", 0));
      HC_ASSIGN_OR_RETURN(double y, num("y", 0));
      HC_ASSIGN_OR_RETURN(double w, num("width", 0));
      HC_ASSIGN_OR_RETURN(double h, num("height", 0));
      if (w > 0 && h > 0) {
        for (const auto& p : {Eigen::Vector2d(x, y), Eigen::Vector2d(x + w, y),
                              Eigen::Vector2d(x + w, y + h), Eigen::Vector2d(x, y + h)})
          b.add(p);
        b.close();
      }
    } else if (name == "circle" || name == "ellipse") {
      HC_ASSIGN_OR_RETURN(double cx, num("cx", 0));
      HC_ASSIGN_OR_RETURN(double cy, num("cy", 0));
      HC_ASSIGN_OR_RETURN(double rx, num(name == "circle" ? "r" : "rx", 0));
      HC_ASSIGN_OR_RETURN(double ry, num(name == "circle" ? "r" : "ry", 0));
      if (rx > 0 && ry > 0) {
        b.add({cx + rx, cy});
        b.arc({cx + rx, cy}, rx, ry, 0, false, true, {cx - rx, cy});
        b.arc({cx - rx, cy}, rx, ry, 0, false, true, {cx + rx, cy});
        b.close();
      }
    }
    return {};
  }

  static void start(void* data, const char* el, const char** atts) {
    auto* p = static_cast<Parser*>(data);
    if (!p->error.ok()) return;
    std::string_view name = el;
    if (const auto colon = name.rfind(':'); colon != std::string_view::npos)
      name = name.substr(colon + 1);
    Status s;
    if (!p->root_seen) {
      p->root_seen = true;
      if (name != "svg") {
        s = invalid_argument(fmt::format("the root element is <{}>, expected <svg>", name));
      } else {
        s = p->root(atts);
      }
      p->stack.push_back(p->stack.back());
    } else {
      s = p->element(name, atts);
    }
    if (!s.ok()) {
      p->error =
          s.with_context(fmt::format("line {}: <{}>", XML_GetCurrentLineNumber(p->xml), name));
      XML_StopParser(p->xml, XML_FALSE);
    }
  }
  static void end(void* data, const char*) {
    auto* p = static_cast<Parser*>(data);
    if (p->stack.size() > 1) p->stack.pop_back();
  }
};

}  // namespace

Result<Polygon2> parse_svg(std::string_view text, std::string_view name,
                           const SvgReadOptions& options) {
  if (!(options.flatness_mm > 0)) return invalid_argument("svg: flatness must be > 0");
  Parser p;
  p.options = options;
  p.stack.push_back(identity());
  p.xml = XML_ParserCreate(nullptr);
  if (!p.xml) return internal_error("svg: cannot create an XML parser");
  XML_SetUserData(p.xml, &p);
  XML_SetElementHandler(p.xml, &Parser::start, &Parser::end);
  const bool ok =
      XML_Parse(p.xml, text.data(), static_cast<int>(text.size()), XML_TRUE) == XML_STATUS_OK;
  const std::string xml_error = ok ? "" : XML_ErrorString(XML_GetErrorCode(p.xml));
  const auto line = XML_GetCurrentLineNumber(p.xml);
  XML_ParserFree(p.xml);
  if (!p.error.ok()) return p.error.with_context(name);
  if (p.points >= kMaxPoints) {
    return invalid_argument(fmt::format(
        "{}: the outline flattens to more than {} points; raise the flatness (now {} mm)", name,
        kMaxPoints, options.flatness_mm));
  }
  if (!ok)
    return invalid_argument(fmt::format("{}: line {}: malformed XML: {}", name, line, xml_error));
  if (!p.root_seen) return invalid_argument(fmt::format("{}: not an SVG document", name));
  if (p.out.loops.empty()) {
    return invalid_argument(
        fmt::format("{}: no closed path, polygon, rect, circle or ellipse with an area", name));
  }
  HC_RETURN_IF_ERROR(validate(p.out, name));
  return std::move(p.out);
}

Result<Polygon2> read_svg(const std::filesystem::path& path, const SvgReadOptions& options) {
  HC_ASSIGN_OR_RETURN(std::string text, read_file(path, std::size_t{256} << 20));
  return parse_svg(text, path.string(), options);
}

std::string format_svg(const Polygon2& polygon) {
  const Eigen::AlignedBox2d box = polygon.bounding_box();
  const double margin = 0.05 * std::max(box.diagonal().norm(), 1e-9);
  const Eigen::Vector2d lo = box.min().array() - margin;
  const Eigen::Vector2d size = box.diagonal().array() + 2 * margin;
  std::string d;
  for (const auto& loop : polygon.loops) {
    for (std::size_t i = 0; i < loop.size(); ++i) {
      d += fmt::format("{}{:.9g},{:.9g} ", i == 0 ? "M" : "L", loop[i].x(), loop[i].y());
    }
    d += "Z ";
  }
  if (!d.empty()) d.pop_back();
  return fmt::format(
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
      "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{0:.9g}mm\" height=\"{1:.9g}mm\" "
      "viewBox=\"{2:.9g} {3:.9g} {0:.9g} {1:.9g}\">\n"
      "  <path fill=\"black\" fill-rule=\"evenodd\" stroke=\"none\" d=\"{4}\"/>\n</svg>\n",
      size.x(), size.y(), lo.x(), lo.y(), d);
}

Status write_svg(const std::filesystem::path& path, const Polygon2& polygon) {
  return write_file_atomic(path, format_svg(polygon));
}

}  // namespace hc::abstraction
