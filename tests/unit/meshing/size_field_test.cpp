// Mesh sizing functions (size_field.h): the background mesh carries the size function exactly at
// its nodes, TetGen follows it (fine at the focus, coarse far away), and the tet count estimate
// is of the right size.
#include "processing/meshing/size_field.h"

#include <gtest/gtest.h>

#include <cmath>

#include "processing/meshing/tetrahedralize.h"

namespace hc::meshing {
namespace {

// Mean length of the edges with both ends within `radius` of `centre`, and of those beyond 4x it.
void edge_lengths(const TetMesh& m, const Eigen::Vector3d& centre, double radius, double* near,
                  double* far) {
  double sn = 0, sf = 0;
  int nn = 0, nf = 0;
  for (Eigen::Index t = 0; t < m.num_tets(); ++t)
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) {
        const Eigen::Vector3d p = m.nodes.row(m.tets(t, a)), q = m.nodes.row(m.tets(t, b));
        const double dp = (p - centre).norm(), dq = (q - centre).norm();
        if (dp < radius && dq < radius) {
          sn += (p - q).norm();
          ++nn;
        } else if (dp > 4 * radius && dq > 4 * radius) {
          sf += (p - q).norm();
          ++nf;
        }
      }
  *near = nn ? sn / nn : 0;
  *far = nf ? sf / nf : 0;
}

TEST(SizeField, GradedSizeIsFineInsideAndGrowsLinearlyToTheCap) {
  GradedSize g;
  g.centre = {1, 2, 3};
  g.radius = 0.5;
  g.fine = 0.1;
  g.growth = 0.3;
  g.coarse = 1.0;
  EXPECT_DOUBLE_EQ(g({1, 2, 3.4}), 0.1);
  EXPECT_DOUBLE_EQ(g({1, 2, 4.5}), 0.1 + 0.3 * 1.0);
  EXPECT_DOUBLE_EQ(g({1, 2, 13}), 1.0);
}

TEST(SizeField, BackgroundMeshHoldsTheSizesAtItsNodesAndCoversTheBox) {
  GradedSize g{{0.05, 0.05, 0.05}, 0.002, 0.001, 0.3, 0.02};
  const Eigen::AlignedBox3d box(Eigen::Vector3d::Zero(), Eigen::Vector3d(0.1, 0.1, 0.05));
  Result<TetMesh> bg = background_mesh(g, box);
  ASSERT_TRUE(bg.ok()) << bg.status().to_string();
  ASSERT_EQ(bg->node_attributes.cols(), 1);
  double volume = 0;
  for (Eigen::Index t = 0; t < bg->num_tets(); ++t) volume += std::abs(tet_signed_volume(*bg, t));
  EXPECT_GE(volume, box.volume());  // the octree's cube around the box
  for (Eigen::Index i = 0; i < bg->num_nodes(); ++i)
    EXPECT_DOUBLE_EQ(bg->node_attributes(i, 0), g(bg->nodes.row(i).transpose()));
  // A few hundred cells, not the ~10^5 of a uniform grid at the fine size.
  EXPECT_LT(bg->num_nodes(), 5000);
  // Bad size functions are refused with the point named.
  EXPECT_FALSE(background_mesh([](const Eigen::Vector3d&) { return -1.0; }, box).ok());
  EXPECT_FALSE(background_mesh([](const Eigen::Vector3d&) { return 1e-9; }, box, 10000).ok());
}

TEST(SizeField, TetgenFollowsTheSizeFunction) {
  GradedSize g{{0.05, 0.05, 0.05}, 0.003, 0.001, 0.3, 0.0125};
  TetrahedralizeOptions options;
  options.max_radius_edge_ratio = 1.414;
  options.edge_size = g;
  EXPECT_NE(options.tetgen_switches().find('m'), std::string::npos);
  TetrahedralizeSummary summary;
  Result<TetMesh> m = box_tet_mesh({0.1, 0.1, 0.05}, options, &summary);
  ASSERT_TRUE(m.ok()) << m.status().to_string();
  double near = 0, far = 0;
  edge_lengths(*m, g.centre, g.radius, &near, &far);
  // TetGen's edges come out ~1.2-1.3 x the size (measured on uniform sizes, size_field.h).
  EXPECT_GT(near, 0.7 * g.fine);
  EXPECT_LT(near, 2.0 * g.fine);
  EXPECT_GT(far, 4 * near);
  // The estimate is of the right size (within 2x).
  const double estimate =
      estimate_tet_count(g, Eigen::AlignedBox3d(Eigen::Vector3d::Zero(), Eigen::Vector3d(0.1, 0.1, 0.05)));
  EXPECT_GT(estimate, 0.5 * static_cast<double>(m->num_tets()));
  EXPECT_LT(estimate, 2.0 * static_cast<double>(m->num_tets()));
  std::printf("%ld tets (estimate %.0f), edges %.3g mm near, %.3g mm far\n",
              static_cast<long>(m->num_tets()), estimate, 1e3 * near, 1e3 * far);
}

}  // namespace
}  // namespace hc::meshing
