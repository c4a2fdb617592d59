#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "common/units.h"
#include "figures/samples_figures.h"

namespace hc::figures {
namespace {

// Probe directions closer than this (cosine) are the same direction.
constexpr double kSameDirectionCos = 0.999;
constexpr std::size_t kMaxSeriesPerChart = 8;

Eigen::Vector3d vec(const std::array<double, 3>& a) { return {a[0], a[1], a[2]}; }
std::array<double, 3> arr(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

Eigen::Vector3d across(const Eigen::Vector3d& p, const Eigen::Vector3d& d) {
  return p - p.dot(d) * d;
}

double tolerance_of(const material::Samples& s, const CurveOptions& o) {
  if (o.location_tolerance_m > 0) return o.location_tolerance_m;
  double radius = 0;
  for (const material::Example& e : s.examples) radius = std::max(radius, e.probe.radius_m);
  return std::max(1e-3, 0.5 * radius);
}

Json curves_json(const std::vector<ProbeCurve>& curves) {
  Json j = Json::array();
  for (const ProbeCurve& c : curves) {
    Json pts = Json::array();
    for (const CurvePoint& p : c.points)
      pts.push_back(Json{
          {"example", p.example}, {"force_n", p.force_n}, {"displacement_m", p.displacement_m}});
    j.push_back(Json{{"position_m", c.position_m}, {"direction", c.direction}, {"points", pts}});
  }
  return j;
}

plot::Series curve_series(const ProbeCurve& c, std::string label) {
  plot::Series s;
  s.label = std::move(label);
  for (const CurvePoint& p : c.points) {
    s.x.push_back(units::m_to_mm(p.displacement_m));
    s.y.push_back(p.force_n);
  }
  return s;
}

plot::Chart force_chart(std::string title) {
  plot::Chart c;
  c.title = std::move(title);
  c.x.label = "displacement under the probe (mm)";
  c.y.label = "force (N)";
  c.x.include_zero = true;
  c.y.include_zero = true;
  return c;
}

std::string location_label(const ProbeCurve& c, std::size_t i) {
  return fmt::format("location {} ({:.1f}, {:.1f}) mm", i, units::m_to_mm(c.position_m[0]),
                     units::m_to_mm(c.position_m[1]));
}

// Linear interpolation of displacement at `force` along a curve sorted by force; nullopt outside.
std::optional<double> displacement_at(const ProbeCurve& c, double force) {
  const auto& p = c.points;
  if (p.empty() || force < p.front().force_n || force > p.back().force_n) return std::nullopt;
  for (std::size_t k = 1; k < p.size(); ++k) {
    if (force > p[k].force_n) continue;
    const double df = p[k].force_n - p[k - 1].force_n;
    if (df <= 0) return 0.5 * (p[k].displacement_m + p[k - 1].displacement_m);
    const double t = (force - p[k - 1].force_n) / df;
    return p[k - 1].displacement_m + t * (p[k].displacement_m - p[k - 1].displacement_m);
  }
  return p.back().displacement_m;  // a single point at exactly this force
}

}  // namespace

Result<std::vector<ProbeCurve>> probe_curves(const material::Samples& samples,
                                             const std::vector<MatrixX3d>* positions,
                                             const CurveOptions& options) {
  const Eigen::Index n = samples.mesh.num_nodes();
  if (positions != nullptr) {
    if (positions->size() != samples.examples.size())
      return invalid_argument(fmt::format("{} position sets for {} examples", positions->size(),
                                          samples.examples.size()));
    for (std::size_t i = 0; i < positions->size(); ++i)
      if ((*positions)[i].rows() != n)
        return invalid_argument(fmt::format("positions of example {}: {} rows for {} nodes", i,
                                            (*positions)[i].rows(), n));
  }
  const double tol = tolerance_of(samples, options);
  std::vector<ProbeCurve> curves;
  std::vector<std::vector<Eigen::Vector3d>> centroids;  // per curve, for its mean position
  for (std::size_t i = 0; i < samples.examples.size(); ++i) {
    const material::Example& e = samples.examples[i];
    const Eigen::Vector3d d = e.probe.direction.normalized();
    const MatrixX3d& x = positions != nullptr ? (*positions)[i] : e.positions_m;
    double force = 0, weight = 0, disp = 0;
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (const material::NodalForce& f : e.forces) {
      const double w = f.force_n.norm();
      const Eigen::Vector3d rest = samples.mesh.nodes.row(f.node).transpose();
      const Eigen::Vector3d moved = x.row(f.node).transpose();
      force += f.force_n.dot(d);
      weight += w;
      disp += w * (moved - rest).dot(d);
      centroid += w * rest;
    }
    if (!(weight > 0)) continue;  // an unloaded example has no point on a curve
    centroid /= weight;
    disp /= weight;
    std::size_t g = curves.size();
    for (std::size_t k = 0; k < curves.size(); ++k) {
      const Eigen::Vector3d dk = vec(curves[k].direction);
      if (dk.dot(d) < kSameDirectionCos) continue;
      if ((across(vec(curves[k].position_m), d) - across(centroid, d)).norm() <= tol) {
        g = k;
        break;
      }
    }
    if (g == curves.size()) {
      curves.push_back({arr(centroid), arr(d), {}});
      centroids.emplace_back();
    }
    curves[g].points.push_back({i, force, disp});
    centroids[g].push_back(centroid);
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& c : centroids[g]) mean += c;
    curves[g].position_m = arr(mean / static_cast<double>(centroids[g].size()));
  }
  if (curves.empty())
    return invalid_argument("no example carries forces: there is no force-displacement curve");
  for (ProbeCurve& c : curves)
    std::stable_sort(c.points.begin(), c.points.end(),
                     [](const CurvePoint& a, const CurvePoint& b) { return a.force_n < b.force_n; });
  return curves;
}

MatrixX3i boundary_triangles(const TetMesh& mesh) {
  // The outward faces of a positively oriented tet (a, b, c, d).
  static constexpr int kFaces[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  std::map<std::array<int, 3>, std::pair<int, std::array<int, 3>>> faces;
  for (Eigen::Index t = 0; t < mesh.num_tets(); ++t)
    for (const auto& f : kFaces) {
      const std::array<int, 3> tri{mesh.tets(t, f[0]), mesh.tets(t, f[1]), mesh.tets(t, f[2])};
      std::array<int, 3> key = tri;
      std::sort(key.begin(), key.end());
      auto [it, inserted] = faces.try_emplace(key, 0, tri);
      ++it->second.first;
    }
  std::vector<std::array<int, 3>> out;
  for (const auto& [key, v] : faces)
    if (v.first == 1) out.push_back(v.second);
  MatrixX3i m(static_cast<Eigen::Index>(out.size()), 3);
  for (std::size_t i = 0; i < out.size(); ++i)
    for (int k = 0; k < 3; ++k) m(static_cast<Eigen::Index>(i), k) = out[i][k];
  return m;
}

Result<FigureSet> samples_figures(const LabelledSamples& input, const CurveOptions& options) {
  HC_ASSIGN_OR_RETURN(std::vector<ProbeCurve> curves, probe_curves(input.samples, nullptr, options));
  FigureSet set;
  set.title = "Samples " + input.label;
  set.source = input.path;
  set.numbers["examples"] = input.samples.examples.size();
  set.numbers["nodes"] = input.samples.mesh.num_nodes();
  set.numbers["tets"] = input.samples.mesh.num_tets();
  set.numbers["locations"] = curves.size();
  set.numbers["max_displacement_m"] = input.samples.max_displacement_m();
  plot::Chart chart = force_chart(input.label + ": force against displacement per probe location");
  for (std::size_t i = 0; i < curves.size() && i < kMaxSeriesPerChart; ++i) {
    chart.series.push_back(curve_series(curves[i], location_label(curves[i], i)));
    chart.series.back().marker = plot::MarkerStyle::kCircle;
  }
  set.figures.push_back({"curves",
                         fmt::format("Force against the displacement under the probe, per probe "
                                     "location ({} of {} shown).",
                                     chart.series.size(), curves.size()),
                         chart, Json{{"samples", input.path}, {"curves", curves_json(curves)}}});
  return set;
}

Result<FigureSet> materials_figures(const std::vector<LabelledSamples>& inputs,
                                    const CurveOptions& options) {
  if (inputs.empty()) return invalid_argument("no materials to plot");
  FigureSet set;
  set.title = "Base materials";
  plot::Chart chart = force_chart("Base materials: force against displacement");
  Json data = Json::array();
  for (std::size_t m = 0; m < inputs.size(); ++m) {
    const LabelledSamples& in = inputs[m];
    Result<std::vector<ProbeCurve>> curves = probe_curves(in.samples, nullptr, options);
    if (!curves.ok()) return curves.status().with_context(in.path);
    // The mesh's centre across the press, for ties.
    const Eigen::Vector3d centre = in.samples.mesh.nodes.colwise().mean().transpose();
    std::size_t best = 0;
    double best_dist = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < curves->size(); ++i) {
      const ProbeCurve& c = (*curves)[i];
      const Eigen::Vector3d d = vec(c.direction);
      const double dist = (across(vec(c.position_m), d) - across(centre, d)).norm();
      const std::size_t np = c.points.size(), bp = (*curves)[best].points.size();
      if (np > bp || (np == bp && dist < best_dist) || i == 0) {
        best = i;
        best_dist = dist;
      }
    }
    chart.series.push_back(curve_series((*curves)[best], in.label));
    chart.series.back().marker = plot::MarkerStyle::kCircle;
    if (!in.path.empty()) set.source += (set.source.empty() ? "" : " ") + in.path;
    data.push_back(Json{{"label", in.label},
                        {"samples", in.path},
                        {"location", best},
                        {"curve", curves_json({(*curves)[best]})[0]}});
  }
  set.numbers["materials"] = inputs.size();
  set.figures.push_back(
      {"materials",
       "Each material's force against displacement at its most-probed location (thesis Fig. "
       "5.7.1).",
       chart, Json{{"materials", data}}});
  return set;
}

Result<Comparison> compare_curves(const std::vector<ProbeCurve>& target,
                                  const std::vector<ProbeCurve>& design, double tolerance_m) {
  Comparison c;
  double sum = 0;
  for (const ProbeCurve& t : target) {
    const Eigen::Vector3d d = vec(t.direction);
    const ProbeCurve* match = nullptr;
    double best = tolerance_m;
    for (const ProbeCurve& k : design) {
      if (vec(k.direction).dot(d) < kSameDirectionCos) continue;
      const double dist = (across(vec(k.position_m), d) - across(vec(t.position_m), d)).norm();
      if (dist <= best) {
        best = dist;
        match = &k;
      }
    }
    double loc_sum = 0;
    std::size_t loc_n = 0;
    if (match != nullptr)
      for (const CurvePoint& p : t.points) {
        const std::optional<double> u = displacement_at(*match, p.force_n);
        if (!u) continue;
        const double e = p.displacement_m - *u;
        loc_sum += e * e;
        ++loc_n;
        c.max_error_m = std::max(c.max_error_m, std::abs(e));
      }
    sum += loc_sum;
    c.compared_points += loc_n;
    c.location_rms_m.push_back(loc_n > 0 ? std::sqrt(loc_sum / static_cast<double>(loc_n))
                                         : std::numeric_limits<double>::quiet_NaN());
  }
  if (c.compared_points == 0)
    return invalid_argument(
        "target and design share no probe location with overlapping forces; nothing to compare");
  c.rms_error_m = std::sqrt(sum / static_cast<double>(c.compared_points));
  return c;
}

Result<FigureSet> comparison_figures(const LabelledSamples& target, const LabelledSamples& design,
                                     const CurveOptions& options) {
  HC_ASSIGN_OR_RETURN(std::vector<ProbeCurve> t, probe_curves(target.samples, nullptr, options));
  HC_ASSIGN_OR_RETURN(std::vector<ProbeCurve> d, probe_curves(design.samples, nullptr, options));
  const double tol = tolerance_of(target.samples, options);
  HC_ASSIGN_OR_RETURN(Comparison cmp, compare_curves(t, d, tol));
  FigureSet set;
  set.title = "Target " + target.label + " vs design " + design.label;
  set.source = target.path + " " + design.path;
  set.numbers["rms_error_m"] = cmp.rms_error_m;
  set.numbers["max_error_m"] = cmp.max_error_m;
  set.numbers["compared_points"] = cmp.compared_points;
  set.numbers["target_locations"] = t.size();

  plot::Chart bars;
  bars.title = "RMS displacement difference per location";
  bars.y.label = "RMS difference (mm)";
  Json loc_rms = Json::array();
  for (std::size_t i = 0; i < t.size(); ++i) {
    loc_rms.push_back(finite_or_null(cmp.location_rms_m[i]));
    if (std::isfinite(cmp.location_rms_m[i]))
      bars.bars.push_back({fmt::format("location {}", i), units::m_to_mm(cmp.location_rms_m[i]), {}});
  }
  const Json data{{"target", target.path},         {"design", design.path},
                  {"target_curves", curves_json(t)}, {"design_curves", curves_json(d)},
                  {"rms_error_m", cmp.rms_error_m},  {"location_rms_m", loc_rms}};
  set.figures.push_back({"target_vs_design_rms",
                         "RMS difference between the target's and the design's displacement at "
                         "the target's forces, per probe location (thesis Fig. 5.8.3, top).",
                         bars, data});
  for (std::size_t i = 0; i < t.size() && i < kMaxSeriesPerChart; ++i) {
    plot::Chart chart = force_chart(fmt::format("Target vs design, {}", location_label(t[i], i)));
    chart.series.push_back(curve_series(t[i], target.label));
    chart.series.back().line = plot::LineStyle::kNone;
    chart.series.back().marker = plot::MarkerStyle::kCircle;
    const Eigen::Vector3d dir = vec(t[i].direction);
    for (const ProbeCurve& k : d)
      if (vec(k.direction).dot(dir) >= kSameDirectionCos &&
          (across(vec(k.position_m), dir) - across(vec(t[i].position_m), dir)).norm() <= tol) {
        chart.series.push_back(curve_series(k, design.label));
        break;
      }
    set.figures.push_back(
        {fmt::format("target_vs_design_loc{}", i),
         fmt::format("Location {}: the target's curve (markers) and the design's (line).", i), chart,
         data});
  }
  return set;
}

}  // namespace hc::figures
