// The engraving-depth calibration part (thesis Sec. 7.3, Fig. 7.3.1): a block with cylindrical
// intrusions of graded depths (rows) and diameters (columns) on three faces, so that a printer's
// minimal engraving depth can be read off in all three orientations (top: along -z; front:
// along +y; right: along -x). Each row and column is labelled by a tally of small square pits
// beside it (row i: i + 1 pits to its left; column j: j + 1 pits above it). The block minus the
// cutters is one exact boolean (CGAL corefinement, geometry/booleans.h).
#pragma once

#include <string>
#include <vector>

#include "common/mesh.h"
#include "common/status.h"

namespace hc::abstraction {

struct CalibrationPartOptions {
  std::vector<double> depths;     // > 0, in the part's unit (mm at the CLI)
  std::vector<double> diameters;  // > 0
  int segments = 48;              // polygon sides of each cylinder (vertices on the circle)
  Status validate() const;
};

struct CalibrationPart {
  TriangleMesh mesh;
  double size = 0.0;                // edge of the cubic block
  std::vector<std::string> legend;  // one line per row and column: what its tally means
};

Result<CalibrationPart> calibration_part(const CalibrationPartOptions& options);

// "A:B:STEP" (inclusive, STEP > 0) or a comma list "a,b,c" -> values; kInvalidArgument naming
// `what` on bad syntax, non-positive values or more than 20 entries.
Result<std::vector<double>> parse_range(std::string_view text, std::string_view what);

}  // namespace hc::abstraction
