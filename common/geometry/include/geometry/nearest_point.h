// The nearest of a fixed set of points, for many queries: CGAL's k-d tree (Kd_tree with
// Orthogonal_k_neighbor_search), built once. No CGAL type appears here.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <span>
#include <vector>

#include "common/status.h"

namespace hc::geometry {

struct NearestQuery {
  std::vector<double> distance;  // Euclidean distance to the nearest point
  std::vector<int> index;        // its index in the built set
};

class NearestPoint3 {
 public:
  // kInvalidArgument for no points or a non-finite one.
  static Result<NearestPoint3> build(std::span<const Eigen::Vector3d> points);
  // kInvalidArgument for a non-finite query.
  Result<NearestQuery> query(std::span<const Eigen::Vector3d> queries) const;

  NearestPoint3(NearestPoint3&&) noexcept;
  NearestPoint3& operator=(NearestPoint3&&) noexcept;
  ~NearestPoint3();

 private:
  struct Impl;
  explicit NearestPoint3(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace hc::geometry
