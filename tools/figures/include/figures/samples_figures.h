// Figures of force–displacement samples (the files `hardcopy track` and `synth` write):
//  * the probe curves: per probe location, applied force against the probe's displacement;
//  * measured vs simulated after a fit (thesis Fig. 4.5.2): the same curves simulated with one or
//    more materials, and the position error on the specimen's surface (Fig. 5.8.1's error plot,
//    also as VTU for ParaView);
//  * several materials' curves in one chart (Fig. 5.7.1);
//  * a target against a design's (re)measured or simulated samples (Fig. 5.8.3).
//
// Per example, the force is the applied nodal forces' total along the probe direction (N) and the
// displacement is the force-weighted mean displacement of the loaded nodes along that direction (m):
// the indentation under the probe. Examples are grouped into probe locations by where their loaded
// nodes sit at rest, across the press direction (within `location_tolerance_m`).
#pragma once

#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include "common/mesh.h"
#include "common/status.h"
#include "figures/figure.h"
#include "processing/material/samples.h"

namespace hc::figures {

struct CurvePoint {
  std::size_t example = 0;
  double force_n = 0;
  double displacement_m = 0;
};

struct ProbeCurve {
  std::array<double, 3> position_m{};  // force-weighted rest position of the loaded nodes
  std::array<double, 3> direction{0, 0, -1};
  std::vector<CurvePoint> points;  // sorted by force
};

struct CurveOptions {
  // Examples whose loaded nodes are this close across the press direction share a location; 0:
  // half the probe radius, at least 1 mm.
  double location_tolerance_m = 0;
};

// Probe curves of `samples`; with `positions` (one #N x 3 matrix per example, e.g. simulated), the
// displacements are measured on those positions instead, with the same grouping and forces.
// kInvalidArgument when no example carries forces or `positions` does not match.
Result<std::vector<ProbeCurve>> probe_curves(const material::Samples& samples,
                                             const std::vector<MatrixX3d>* positions = nullptr,
                                             const CurveOptions& options = {});

// The boundary triangles of a tet mesh, oriented outward (faces that belong to one tet only).
MatrixX3i boundary_triangles(const TetMesh& mesh);

// A labelled samples file (the label names it in legends).
struct LabelledSamples {
  std::string label;
  std::string path;
  material::Samples samples;
};

// Curves of one samples file: a chart with one series per location (up to 8 shown; all in data).
Result<FigureSet> samples_figures(const LabelledSamples& input, const CurveOptions& options = {});

// A material file to compare with the measurements (thesis Fig. 4.5.2: "our method" and e.g. an
// average-fit linear co-rotational model).
struct LabelledMaterial {
  std::string label;
  std::string path;
};
struct FitFigureOptions {
  CurveOptions curves{};
  int steps = 8;  // load increments of each simulation (material::EvaluateOptions)
  std::size_t max_location_charts = 6;
};
// Simulates every example with each material; per location a chart of measured (markers) against
// simulated (lines); a surface error map of the first material on the example with the largest
// force (PNG/SVG and `error_map.vtu`: positions, measured and simulated displacement, error);
// numbers: each material's RMS / max error and error relative to the max displacement.
Result<FigureSet> fit_figures(const LabelledSamples& measured,
                              const std::vector<LabelledMaterial>& materials,
                              const FitFigureOptions& options = {});

// Several materials' curves in one chart (Fig. 5.7.1): per input its location with the most
// points (ties: nearest the specimen's centre across the press).
Result<FigureSet> materials_figures(const std::vector<LabelledSamples>& inputs,
                                    const CurveOptions& options = {});

// Target against design (Fig. 5.8.3): per target location, the design's curve at the nearest
// location; the design's displacement is interpolated at the target's forces (linearly between
// its points; forces outside its range are not compared) and the RMS difference reported per
// location (bar chart) and overall (numbers: rms_error_m, max_error_m, compared_points).
// kInvalidArgument when no location matches or no force overlaps.
struct Comparison {
  double rms_error_m = 0;
  double max_error_m = 0;
  std::size_t compared_points = 0;
  std::vector<double> location_rms_m;  // per target location (NaN when nothing compared)
};
Result<Comparison> compare_curves(const std::vector<ProbeCurve>& target,
                                  const std::vector<ProbeCurve>& design, double tolerance_m);
Result<FigureSet> comparison_figures(const LabelledSamples& target, const LabelledSamples& design,
                                     const CurveOptions& options = {});

}  // namespace hc::figures
