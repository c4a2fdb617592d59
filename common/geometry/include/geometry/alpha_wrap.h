// CGAL's 3-D alpha wrapping (Portaneri et al. 2022): a closed, manifold, self-intersection-free
// surface enclosing any triangle soup (open, non-manifold, self-intersecting input included) at
// a resolution alpha and an offset. The fallback for inputs no repair or union can make closed,
// and the baseline that scale-aware abstraction is measured against.
#pragma once

#include "common/mesh.h"
#include "common/status.h"

namespace hc::geometry {

struct AlphaWrapOptions {
  // Largest empty ball the wrap may not enter, in the mesh's unit (> 0): cavities and gaps
  // narrower than about alpha are closed over. CGAL's default is 1/20 of the bounding-box
  // diagonal; printers want about their feature size.
  double alpha = 0.0;
  // Distance of the wrap from the input, in the mesh's unit (> 0). CGAL's default is 1/30 of
  // alpha's default; smaller values follow the input more closely and cost time.
  double offset = 0.0;

  Status validate() const;
};

// Wraps the triangles of `soup` (indices in range, coordinates finite; orientation and
// connectivity are not needed). The result is outward oriented. kInvalidArgument on bad options
// or an empty soup, kInternal when CGAL fails.
Result<TriangleMesh> alpha_wrap(const TriangleMesh& soup, const AlphaWrapOptions& options);

}  // namespace hc::geometry
