#include "processing/meshing/size_field.h"

#include <fmt/format.h>
#include <tetgen.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <unordered_map>

namespace hc::meshing {

namespace {

constexpr int kMaxDepth = 20;  // octree levels (cell corners are addressed on a 2^20 lattice)
// TetGen 1.5 with quality bound 1.414 and a uniform size h on boxes: 19,285 tets in 5e-4 m³ at
// h = 5 mm, i.e. a mean tet volume of 0.21 h³ (152,793 at 2.5 mm: 0.20 h³).
constexpr double kTetVolumePerSizeCubed = 0.21;

struct Cell {
  std::array<std::int64_t, 3> lo;  // lattice units
  int depth;
};

struct Octree {
  Eigen::Vector3d origin;
  double unit = 0;  // lattice unit length
  std::vector<Cell> leaves;
};

Result<double> checked_size(const EdgeSizeFunction& size, const Eigen::Vector3d& p) {
  const double h = size(p);
  if (!std::isfinite(h) || !(h > 0))
    return invalid_argument(fmt::format("mesh size function returned {} at ({}, {}, {})", h, p.x(),
                                        p.y(), p.z()));
  return h;
}

// Leaves of the octree over `box`: a cell is split while its side exceeds twice the size at its
// centre and it meets the box.
Result<Octree> build_octree(const EdgeSizeFunction& size, const Eigen::AlignedBox3d& box,
                            long max_cells) {
  Octree tree;
  const double side = 1.05 * box.sizes().maxCoeff();
  if (!(side > 0) || !std::isfinite(side)) return invalid_argument("mesh size field: empty box");
  tree.origin = box.center() - Eigen::Vector3d::Constant(0.5 * side);
  tree.unit = side / static_cast<double>(std::int64_t{1} << kMaxDepth);
  std::vector<Cell> stack = {{{0, 0, 0}, 0}};
  while (!stack.empty()) {
    const Cell c = stack.back();
    stack.pop_back();
    const std::int64_t n = std::int64_t{1} << (kMaxDepth - c.depth);  // side in lattice units
    const double s = static_cast<double>(n) * tree.unit;
    const Eigen::Vector3d lo =
        tree.origin + tree.unit * Eigen::Vector3d(static_cast<double>(c.lo[0]),
                                                  static_cast<double>(c.lo[1]),
                                                  static_cast<double>(c.lo[2]));
    const Eigen::AlignedBox3d cell(lo, lo + Eigen::Vector3d::Constant(s));
    HC_ASSIGN_OR_RETURN(const double h, checked_size(size, cell.center()));
    if (c.depth >= kMaxDepth || s <= 2 * h || !cell.intersects(box)) {
      tree.leaves.push_back(c);
      continue;
    }
    if (static_cast<long>(tree.leaves.size() + stack.size()) + 8 > max_cells)
      return invalid_argument(fmt::format(
          "mesh size field: more than {} background cells (size {:.3g} at ({:.4g}, {:.4g}, "
          "{:.4g}) is far below the domain's {:.3g})",
          max_cells, h, cell.center().x(), cell.center().y(), cell.center().z(), side));
    const std::int64_t half = n / 2;
    for (int k = 0; k < 8; ++k)
      stack.push_back({{c.lo[0] + ((k & 1) ? half : 0), c.lo[1] + ((k & 2) ? half : 0),
                        c.lo[2] + ((k & 4) ? half : 0)},
                       c.depth + 1});
  }
  return tree;
}

}  // namespace

double GradedSize::operator()(const Eigen::Vector3d& p) const {
  const double d = (p - centre).norm();
  if (d <= radius) return fine;
  return std::min(coarse, fine + growth * (d - radius));
}

Result<TetMesh> background_mesh(const EdgeSizeFunction& size, const Eigen::AlignedBox3d& box,
                                long max_cells) {
  if (!size) return invalid_argument("mesh size field: no size function");
  HC_ASSIGN_OR_RETURN(const Octree tree, build_octree(size, box, max_cells));
  // Unique cell corners.
  std::unordered_map<std::uint64_t, int> index;
  std::vector<double> points;
  for (const Cell& c : tree.leaves) {
    const std::int64_t n = std::int64_t{1} << (kMaxDepth - c.depth);
    for (int k = 0; k < 8; ++k) {
      const std::int64_t x = c.lo[0] + ((k & 1) ? n : 0), y = c.lo[1] + ((k & 2) ? n : 0),
                         z = c.lo[2] + ((k & 4) ? n : 0);
      const std::uint64_t key = (static_cast<std::uint64_t>(x) << 42) |
                                (static_cast<std::uint64_t>(y) << 21) |
                                static_cast<std::uint64_t>(z);
      if (index.emplace(key, static_cast<int>(points.size() / 3)).second) {
        points.push_back(tree.origin.x() + tree.unit * static_cast<double>(x));
        points.push_back(tree.origin.y() + tree.unit * static_cast<double>(y));
        points.push_back(tree.origin.z() + tree.unit * static_cast<double>(z));
      }
    }
  }
  tetgenio in, out;
  in.firstnumber = 0;
  in.numberofpoints = static_cast<int>(points.size() / 3);
  in.pointlist = new REAL[points.size()];
  std::memcpy(in.pointlist, points.data(), points.size() * sizeof(double));
  try {
    tetgenbehavior b;
    char switches[] = "zQ";  // Delaunay tetrahedralisation of the points, zero-based, quiet
    if (!b.parse_commandline(switches)) return internal_error("TetGen rejected \"zQ\"");
    tetrahedralize(&b, &in, &out);
  } catch (...) {
    return internal_error("mesh size field: TetGen failed on the background points");
  }
  TetMesh bg;
  bg.nodes = Eigen::Map<const MatrixX3d>(out.pointlist, out.numberofpoints, 3);
  bg.tets = Eigen::Map<const MatrixX4i>(out.tetrahedronlist, out.numberoftetrahedra, 4);
  bg.node_attributes.resize(bg.num_nodes(), 1);
  for (Eigen::Index i = 0; i < bg.num_nodes(); ++i) {
    HC_ASSIGN_OR_RETURN(bg.node_attributes(i, 0),
                        checked_size(size, bg.nodes.row(i).transpose()));
  }
  return bg;
}

double estimate_tet_count(const EdgeSizeFunction& size, const Eigen::AlignedBox3d& box) {
  Result<Octree> tree = build_octree(size, box, 2000000);
  if (!tree.ok()) return std::numeric_limits<double>::infinity();
  double count = 0;
  for (const Cell& c : tree->leaves) {
    const double s =
        static_cast<double>(std::int64_t{1} << (kMaxDepth - c.depth)) * tree->unit;
    const Eigen::Vector3d lo =
        tree->origin + tree->unit * Eigen::Vector3d(static_cast<double>(c.lo[0]),
                                                    static_cast<double>(c.lo[1]),
                                                    static_cast<double>(c.lo[2]));
    const Eigen::AlignedBox3d cell(lo, lo + Eigen::Vector3d::Constant(s));
    const double inside = cell.intersection(box).volume();
    if (!(inside > 0)) continue;
    // Mean of 1/h³ over the corners and the centre.
    double density = 1.0 / std::pow(size(cell.center()), 3);
    for (int k = 0; k < 8; ++k)
      density += 1.0 / std::pow(size(cell.corner(static_cast<Eigen::AlignedBox3d::CornerType>(k))), 3);
    count += inside * density / 9.0 / kTetVolumePerSizeCubed;
  }
  return count;
}

}  // namespace hc::meshing
