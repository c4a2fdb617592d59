// Measured against simulated (thesis Fig. 4.5.2) and the error on the specimen's surface (Fig.
// 5.8.1): every example simulated with each material through material::evaluate_material.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "common/units.h"
#include "common/tet_mesh_io.h"
#include "figures/samples_figures.h"
#include "processing/material/fit.h"
#include "processing/material/material.h"

namespace hc::figures {
namespace {


struct Simulated {
  LabelledMaterial material;
  material::EvaluateSummary summary;
  std::vector<ProbeCurve> curves;
};

// Per-node error of one example: exact on measured nodes (visible or fixed); spread to the other
// surface nodes by repeated averaging over surface edges ("the error is only evaluated at the
// surface marker positions and then interpolated for visualization purposes", thesis 5.8.1).
struct NodeErrors {
  std::vector<double> error_m;      // #N (0 for nodes never reached)
  std::vector<std::uint8_t> known;  // 1 = measured
};

NodeErrors node_errors(const material::Samples& s, std::size_t example, const MatrixX3d& simulated,
                       const MatrixX3i& surface) {
  const material::Example& e = s.examples[example];
  const auto n = static_cast<std::size_t>(s.mesh.num_nodes());
  NodeErrors out{std::vector<double>(n, 0.0), std::vector<std::uint8_t>(n, 0)};
  const std::vector<std::uint8_t> visible =
      e.visible.empty() ? std::vector<std::uint8_t>(n, 1) : e.visible;
  for (std::size_t i = 0; i < n; ++i)
    if (visible[i] != 0) {
      const auto r = static_cast<Eigen::Index>(i);
      out.error_m[i] = (simulated.row(r) - e.positions_m.row(r)).norm();
      out.known[i] = 1;
    }
  for (int f : e.fixed_nodes) {
    const auto i = static_cast<std::size_t>(f);
    out.error_m[i] = (simulated.row(f) - s.mesh.nodes.row(f)).norm();
    out.known[i] = 1;
  }
  std::vector<std::vector<int>> neighbours(n);
  std::vector<std::uint8_t> on_surface(n, 0);
  for (Eigen::Index t = 0; t < surface.rows(); ++t)
    for (int k = 0; k < 3; ++k) {
      const int a = surface(t, k), b = surface(t, (k + 1) % 3);
      neighbours[static_cast<std::size_t>(a)].push_back(b);
      neighbours[static_cast<std::size_t>(b)].push_back(a);
      on_surface[static_cast<std::size_t>(a)] = 1;
    }
  std::vector<std::uint8_t> filled = out.known;
  for (int pass = 0; pass < 200; ++pass) {
    std::vector<std::pair<std::size_t, double>> updates;
    for (std::size_t i = 0; i < n; ++i) {
      if (!on_surface[i] || filled[i]) continue;
      double sum = 0;
      int count = 0;
      for (int j : neighbours[i])
        if (filled[static_cast<std::size_t>(j)]) {
          sum += out.error_m[static_cast<std::size_t>(j)];
          ++count;
        }
      if (count > 0) updates.emplace_back(i, sum / count);
    }
    if (updates.empty()) break;
    for (const auto& [i, v] : updates) {
      out.error_m[i] = v;
      filled[i] = 1;
    }
  }
  return out;
}

Result<Figure> error_map(const LabelledSamples& measured, const Simulated& sim,
                         std::string* vtu_out) {
  const material::Samples& s = measured.samples;
  // The example with the largest force along its probe.
  std::size_t best = 0;
  double best_force = -1;
  for (const ProbeCurve& c : sim.curves)
    for (const CurvePoint& p : c.points)
      if (p.force_n > best_force) {
        best_force = p.force_n;
        best = p.example;
      }
  const MatrixX3i surface = boundary_triangles(s.mesh);
  const MatrixX3d& simulated = sim.summary.positions[best];
  const NodeErrors err = node_errors(s, best, simulated, surface);
  const material::Example& e = s.examples[best];

  plot::SurfaceMap map;
  map.title = fmt::format("{}: position error, example {} ({:.1f} N)", sim.material.label, best,
                          best_force);
  map.value_label = "error (mm)";
  map.axis_unit = "mm";
  map.view_direction = {e.probe.direction.x(), e.probe.direction.y(), e.probe.direction.z()};
  for (Eigen::Index i = 0; i < s.mesh.num_nodes(); ++i) {
    map.vertices.push_back({units::m_to_mm(e.positions_m(i, 0)), units::m_to_mm(e.positions_m(i, 1)),
                            units::m_to_mm(e.positions_m(i, 2))});
    map.values.push_back(units::m_to_mm(err.error_m[static_cast<std::size_t>(i)]));
  }
  for (Eigen::Index t = 0; t < surface.rows(); ++t)
    map.triangles.push_back({surface(t, 0), surface(t, 1), surface(t, 2)});
  map.marks.push_back({units::m_to_mm(e.probe.position_m.x()), units::m_to_mm(e.probe.position_m.y()),
                       units::m_to_mm(e.probe.position_m.z())});

  Json nodes = Json::array();
  for (std::size_t i = 0; i < err.known.size(); ++i)
    if (err.known[i]) nodes.push_back(Json{{"node", i}, {"error_m", err.error_m[i]}});

  VtuData vtu;
  vtu.positions = e.positions_m;
  VtuArray meas{"measured_displacement_m", 3, {}}, simd{"simulated_displacement_m", 3, {}};
  VtuArray error{"error_m", 1, err.error_m}, known{"measured", 1, {}};
  for (Eigen::Index i = 0; i < s.mesh.num_nodes(); ++i) {
    for (int k = 0; k < 3; ++k) {
      meas.values.push_back(e.positions_m(i, k) - s.mesh.nodes(i, k));
      simd.values.push_back(simulated(i, k) - s.mesh.nodes(i, k));
    }
    known.values.push_back(err.known[static_cast<std::size_t>(i)]);
  }
  vtu.point_data = {meas, simd, error, known};
  HC_ASSIGN_OR_RETURN(*vtu_out, format_vtu(s.mesh, vtu));
  return Figure{"error_map",
                fmt::format("Distance between measured and simulated ({}) node positions on the "
                            "surface, example {} with the largest force; measured at {} nodes, "
                            "interpolated between them (also error_map.vtu for ParaView).",
                            sim.material.label, best, nodes.size()),
                map, Json{{"example", best}, {"material", sim.material.path}, {"nodes", nodes}}};
}

}  // namespace

Result<FigureSet> fit_figures(const LabelledSamples& measured,
                              const std::vector<LabelledMaterial>& materials,
                              const FitFigureOptions& options) {
  if (materials.empty()) return invalid_argument("no material to compare with");
  HC_ASSIGN_OR_RETURN(std::vector<ProbeCurve> meas,
                      probe_curves(measured.samples, nullptr, options.curves));
  std::vector<Simulated> sims;
  for (const LabelledMaterial& m : materials) {
    Result<std::unique_ptr<fem::MaterialModel>> model = material::load_material(m.path);
    if (!model.ok()) return model.status();
    material::EvaluateOptions eo;
    eo.steps = options.steps;
    Result<material::EvaluateSummary> ev =
        material::evaluate_material(**model, measured.samples, eo);
    if (!ev.ok()) return ev.status().with_context("simulating " + m.path);
    Result<std::vector<ProbeCurve>> curves =
        probe_curves(measured.samples, &ev->positions, options.curves);
    if (!curves.ok()) return curves.status();
    sims.push_back({m, std::move(*ev), std::move(*curves)});
  }
  FigureSet set;
  set.title = "Fit: " + measured.label;
  set.source = measured.path;
  Json per_material = Json::array();
  for (const Simulated& s : sims) {
    set.numbers[s.material.label + ".rms_error_m"] = s.summary.rms_error_m;
    set.numbers[s.material.label + ".max_error_m"] = s.summary.max_error_m;
    set.numbers[s.material.label + ".error_rel_max_disp"] = s.summary.error_rel_max_disp;
    per_material.push_back(Json{{"label", s.material.label},
                                {"material", s.material.path},
                                {"rms_error_m", s.summary.rms_error_m},
                                {"max_error_m", s.summary.max_error_m},
                                {"example_rms_error_m", s.summary.example_rms_error_m}});
  }
  set.numbers["max_displacement_m"] = sims.front().summary.max_displacement_m;
  for (std::size_t i = 0; i < meas.size() && i < options.max_location_charts; ++i) {
    plot::Chart chart;
    chart.title = fmt::format("{}: location {} ({:.1f}, {:.1f}) mm, measured vs simulated",
                              measured.label, i, units::m_to_mm(meas[i].position_m[0]),
                              units::m_to_mm(meas[i].position_m[1]));
    chart.x.label = "displacement under the probe (mm)";
    chart.y.label = "force (N)";
    chart.x.include_zero = chart.y.include_zero = true;
    const auto add = [&](const ProbeCurve& c, const std::string& label) {
      plot::Series s;
      s.label = label;
      for (const CurvePoint& p : c.points) {
        s.x.push_back(units::m_to_mm(p.displacement_m));
        s.y.push_back(p.force_n);
      }
      chart.series.push_back(std::move(s));
    };
    add(meas[i], "measured");
    chart.series.back().line = plot::LineStyle::kNone;
    chart.series.back().marker = plot::MarkerStyle::kCircle;
    chart.series.back().color = plot::Rgb{0.1, 0.1, 0.1};
    Json curves{{"measured", Json::array()}};
    for (const CurvePoint& p : meas[i].points)
      curves["measured"].push_back(
          Json{{"example", p.example}, {"force_n", p.force_n}, {"displacement_m", p.displacement_m}});
    for (std::size_t m = 0; m < sims.size(); ++m) {
      add(sims[m].curves[i], sims[m].material.label);
      chart.series.back().color = plot::palette_color(m);
      Json pts = Json::array();
      for (const CurvePoint& p : sims[m].curves[i].points)
        pts.push_back(Json{
            {"example", p.example}, {"force_n", p.force_n}, {"displacement_m", p.displacement_m}});
      curves[sims[m].material.label] = pts;
    }
    set.figures.push_back(
        {fmt::format("fit_loc{}", i),
         fmt::format("Location {}: measured force against displacement (markers) and each "
                     "material's simulation of the same forces (lines), thesis Fig. 4.5.2.",
                     i),
         chart,
         Json{{"samples", measured.path}, {"location", i}, {"curves", curves},
              {"materials", per_material}}});
  }
  std::string vtu;
  HC_ASSIGN_OR_RETURN(Figure map, error_map(measured, sims.front(), &vtu));
  set.figures.push_back(std::move(map));
  set.files.emplace_back("error_map.vtu", std::move(vtu));
  return set;
}

}  // namespace hc::figures
