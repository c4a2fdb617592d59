// The fabrication mesh F (thesis Sec. 6.2.1): the character's components welded, repaired and
// united into one closed, manifold, self-intersection-free surface that carries the skinning
// weights. Components that cannot be made closed solids (open, non-orientable or
// self-intersecting soups, common in game characters) are wrapped instead: CGAL's 3-D alpha wrap
// at the printer's feature size, a closed manifold around the whole soup. Either way the weights
// move to F's vertices from the closest point of the input surface (barycentric interpolation).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>

#include "common/mesh.h"
#include "common/progress.h"
#include "common/status.h"
#include "fabrication/articulation/skinned_character.h"

namespace hc::articulation {

struct FabricationMeshOptions {
  // Vertices closer than this fraction of the bounding-box diagonal are welded (CesiumMan is
  // closed only after welding by position).
  double weld_fraction = 1e-6;
  double wrap_alpha_m = 0.5e-3;  // the printer's smallest feature
  double wrap_offset_m = 0.0;    // 0: alpha / 10
  bool force_wrap = false;       // wrap even when a union works
  ProgressReporter* progress = nullptr;
  Status validate() const;
};

struct FabricationMeshSummary {
  // "as is", "repaired", "union" (several closed components united), "alpha wrap".
  std::string method;
  std::string why_wrapped;  // what made the union impossible
  std::int64_t input_components = 0;
  std::int64_t merged_vertices = 0;
  std::int64_t triangles = 0;
  double volume_m3 = 0.0;
  std::int64_t self_intersecting_pairs = 0;  // of F (0 expected)
  bool closed = false;
  bool manifold = false;
  double time_s = 0.0;
};

struct FabricationMesh {
  TriangleMesh mesh;          // F, metres
  Eigen::MatrixXd weights;    // #V(F) by #bones, rows sum to 1
  FabricationMeshSummary summary;
};

Result<FabricationMesh> build_fabrication_mesh(const SkinnedCharacter& character,
                                               const FabricationMeshOptions& options);

// Weights at `points` (#P by 3) from the closest point of `source` (any soup) and the
// barycentric blend of its triangle's vertex weights (`source_weights`, #V by #bones).
Result<Eigen::MatrixXd> transfer_weights(const TriangleMesh& source,
                                         const Eigen::MatrixXd& source_weights,
                                         const MatrixX3d& points);

}  // namespace hc::articulation
