// The surface between the interior and exterior balls (thesis Sec. 7.4.1, Amenta et al. 2001):
// the power faces of the power diagram dual to the regular-triangulation edges that join an
// interior to an exterior ball. It bounds the union of the interior balls' power cells, so it is
// closed, and, each power vertex having 4 (3-D) or 3 (2-D) cells around it in the triangulation,
// manifold by construction. The power vertices are correctly rounded doubles (see
// geometry/regular_triangulation.h); every 3-D result is checked for self-intersections after
// that rounding (check_mesh), and a result that fails is repaired or refused, never returned.
#pragma once

#include <cstdint>
#include <span>

#include "common/mesh.h"
#include "common/status.h"
#include "fabrication/abstraction/medial_balls.h"
#include "fabrication/abstraction/polygon.h"
#include "geometry/regular_triangulation.h"
#include "geometry/triangulation_2d.h"

namespace hc::abstraction {

struct CrustSummary {
  std::size_t balls = 0;
  std::size_t hidden_balls = 0;  // balls with an empty power cell
  std::size_t faces = 0;         // power faces (3-D) or edges (2-D) of the crust
  std::size_t vertices = 0;
  std::size_t triangles = 0;  // 3-D
  std::size_t loops = 0;      // 2-D
  bool closed = false;
  bool manifold = false;
  std::int64_t self_intersecting_pairs = -1;  // after rounding; -1 not checked
  std::size_t repaired_pairs = 0;  // pairs removed by CGAL's repair (geometry/mesh_ops.h)
  std::size_t perturbations = 0;   // 3-D: perturbations tried (power_weights seeds)
  double time_s = 0.0;
};

// The squared radii of the balls as weights, each lowered by a fixed pseudo-random fraction of at
// most kWeightPerturbation. Medial balls are degenerate by construction: every sample lies on the
// sphere of each ball it defines, so it is a common power vertex of all of them, and every
// predicate of the regular triangulation near it is exactly zero. The exact-predicate fallback
// then runs for nearly every insertion (a 16k-ball cube: 3.9 s rather than 0.7 s). The
// perturbation puts the balls in general position for the predicates; the power vertices that the
// unperturbed balls share exactly are then snapped to their sample (crust_faces_3d).
// `seed` picks another fixed perturbation (0: the default one).
inline constexpr double kWeightPerturbation = 1e-9;
template <int D>
std::vector<double> power_weights(const Balls<D>& balls, std::uint64_t seed = 0);

// power_crust_3d rebuilds a crust that is not a valid solid with up to this many perturbations.
inline constexpr std::uint64_t kPerturbations = 3;

// The 2-D crust as closed loops, interior on the left (counter-clockwise outer boundaries).
// kInvalidArgument for fewer than 3 balls or no interior/exterior pair; kInternal when the crust
// reaches an unbounded power cell (the exterior balls did not enclose the interior ones).
Result<Polygon2> power_crust_2d(const Balls2& balls, CrustSummary* summary = nullptr);

// The 3-D crust, outward oriented, checked as described above; a crust that fails is rebuilt with
// another perturbation of the weights (kPerturbations in all).
Result<TriangleMesh> power_crust_3d(const Balls3& balls, CrustSummary* summary = nullptr);

// The crust of a regular triangulation of `balls` already built (weights power_weights; centres
// needed at least between interior and exterior balls: Triangulate3Options::centres_between),
// unchecked; what power_crust_3d runs before its checks. With balls.defining set, a power vertex
// whose four balls share a sample is placed on that sample (the nearest such, if several), vertices
// at the same position are merged, triangles that lose a corner are dropped and opposite pairs
// cancel. Samples in `no_snap` are not snapped to, and vertices near a `no_merge` point are not
// merged (power_crust_3d retries with the samples and points where a crust touched itself).
Result<TriangleMesh> crust_faces_3d(const geometry::Triangulation3& rt, const Balls3& balls,
                                    const std::vector<std::uint8_t>& no_snap = {},
                                    const std::vector<Eigen::Vector3d>& no_merge = {});

// The power face dual to the regular-triangulation edge a-b (input indices), found from a finite
// cell containing both: the cells around the edge in order, turning counter-clockwise about
// b - a (so the face's normal points from ball a to ball b). kInternal when the ring reaches an
// infinite cell (the face is unbounded).
Result<std::vector<int>> power_face(const geometry::Triangulation3& rt, int cell, int a, int b);

// Checks `mesh` (closed, manifold, self-intersections after rounding) and, when intersecting pairs
// remain, removes them with geometry::resolve_self_intersections within `max_deviation`.
// kInternal when the result is still not a valid solid. Fills the check fields of `summary`.
Status check_crust(double max_deviation, TriangleMesh* mesh, CrustSummary* summary);

}  // namespace hc::abstraction
