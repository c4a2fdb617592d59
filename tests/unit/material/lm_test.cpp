// The own Levenberg–Marquardt's matrix-free path (processing/material/src/lm.h) on a linear least-
// squares problem whose exact minimiser is known: ‖J q − y‖² + γ ‖L q‖² with L the path graph's
// Laplacian, as the material fits regularise (a squared Laplacian in the normal equations). Its
// preconditioner keeps RᵀR whole when the products are costly enough (the joint fit's case) and
// falls back to block-Jacobi otherwise (one example's fit); both must reach the same minimiser,
// and the whole one in far fewer CG iterations.
#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/SparseCore>
#include <cmath>
#include <memory>
#include <vector>

#include "../../../processing/material/src/lm.h"
#include "processing/material/fit.h"

namespace hc::material::detail {
namespace {

// J: 2 parameters per block, each observed once with weight a_e (blocks far apart in stiffness),
// plus the sum of each block: a block-diagonal J with 3 rows per block.
struct Problem {
  int blocks = 200;
  Eigen::MatrixXd j;  // dense copy for the reference solution
  Eigen::VectorXd y;
  Eigen::SparseMatrix<double> laplacian;  // the path's umbrella Laplacian (one channel)
  Eigen::SparseMatrix<double> reg;

  Problem() {
    const int n = 2 * blocks;
    j = Eigen::MatrixXd::Zero(3 * blocks, n);
    y.resize(3 * blocks);
    for (int e = 0; e < blocks; ++e) {
      const double a = 1.0 + 0.5 * std::sin(0.37 * e);
      j(3 * e, 2 * e) = a;
      j(3 * e + 1, 2 * e + 1) = 0.3 * a;
      j(3 * e + 2, 2 * e) = 0.2;
      j(3 * e + 2, 2 * e + 1) = 0.1;
      y.segment<3>(3 * e) << std::cos(0.1 * e), std::sin(0.05 * e), 0.3;
    }
    std::vector<Eigen::Triplet<double>> t;
    for (int e = 0; e < blocks; ++e) {
      t.emplace_back(e, e, (e > 0) + (e + 1 < blocks));
      if (e > 0) t.emplace_back(e, e - 1, -1.0);
      if (e + 1 < blocks) t.emplace_back(e, e + 1, -1.0);
    }
    laplacian.resize(blocks, blocks);
    laplacian.setFromTriplets(t.begin(), t.end());
    // sqrt(γ) L ⊗ I₂ with a heavy γ: smooth modes are then decided by the regulariser.
    const double sg = std::sqrt(50.0);
    t.clear();
    for (int k = 0; k < laplacian.outerSize(); ++k)
      for (Eigen::SparseMatrix<double>::InnerIterator it(laplacian, k); it; ++it)
        for (int c = 0; c < 2; ++c)
          t.emplace_back(static_cast<int>(2 * it.row() + c), static_cast<int>(2 * it.col() + c),
                         sg * it.value());
    reg.resize(n, n);
    reg.setFromTriplets(t.begin(), t.end());
  }

  Eigen::VectorXd exact() const {
    const Eigen::MatrixXd rd(reg);
    const Eigen::MatrixXd a = j.transpose() * j + rd.transpose() * rd;
    return a.llt().solve(j.transpose() * y);
  }
};

class DenseOperator final : public JacobianOperator {
 public:
  explicit DenseOperator(const Eigen::MatrixXd& j) : j_(j) {}
  Status apply(const Eigen::VectorXd& v, Eigen::VectorXd* out) const override {
    *out = j_ * v;
    return {};
  }
  Status apply_transpose(const Eigen::MatrixXd& w, Eigen::MatrixXd* out) const override {
    *out = j_.transpose() * w;
    return {};
  }

 private:
  const Eigen::MatrixXd& j_;
};

ParameterFitSummary solve(const Problem& p, double product_flops, Eigen::VectorXd* q,
                          const Eigen::SparseMatrix<double>& coarse_basis = {}) {
  LmProblem lm;
  lm.residual = [&](const Eigen::VectorXd& v, Eigen::VectorXd* r) -> Status {
    *r = p.j * v - p.y;
    return {};
  };
  lm.jacobian_operator =
      [&](const Eigen::VectorXd&) -> Result<std::unique_ptr<JacobianOperator>> {
    return std::unique_ptr<JacobianOperator>(std::make_unique<DenseOperator>(p.j));
  };
  lm.matrix_free = true;
  lm.rows = p.j.rows();
  lm.block = 2;
  lm.product_flops = product_flops;
  lm.reg = p.reg;
  if (coarse_basis.size() > 0)
    lm.coarse = std::make_shared<const CoarseSpace>(coarse_basis, p.reg, 2);
  LmSettings settings;
  settings.max_iterations = 30;
  settings.function_tolerance = 1e-14;
  settings.cg_relative_tolerance = 1e-12;
  settings.cg_max_iterations = 2000;
  *q = Eigen::VectorXd::Zero(p.j.cols());
  ParameterFitSummary summary;
  EXPECT_TRUE(run_lm(lm, settings, q, &summary).ok());
  return summary;
}

TEST(LmMatrixFree, WholeRegulariserPreconditionerReachesTheMinimiserInFewCgIterations) {
  const Problem p;
  const Eigen::VectorXd exact = p.exact();
  Eigen::VectorXd whole, blocks;
  // Costly products (the joint fit's 24 solves each): M with RᵀR whole is worth factorising.
  const ParameterFitSummary sw = solve(p, 1e9, &whole);
  // Products cheaper than the factor: block-Jacobi.
  const ParameterFitSummary sb = solve(p, 1.0, &blocks);
  std::printf("CG iterations: RtR whole %ld (%d LM), block-Jacobi %ld (%d LM)\n",
              sw.cg_iterations, sw.iterations, sb.cg_iterations, sb.iterations);
  // The minimiser of a linear least-squares problem: both paths to 1e-7 of its size.
  EXPECT_LE((whole - exact).norm(), 1e-7 * exact.norm());
  EXPECT_LE((blocks - exact).norm(), 1e-7 * exact.norm());
  // The squared path Laplacian on 200 blocks has condition ~1e8: block-Jacobi leaves it to CG.
  EXPECT_LT(5 * sw.cg_iterations, sb.cg_iterations);
}

// Where RᵀR is not factorised (cheap products), block-Jacobi plus a coarse correction on smoothed
// aggregates of the path: the smooth modes that block-Jacobi leaves to CG are the coarse space's.
TEST(LmMatrixFree, CoarseCorrectionReachesTheMinimiserInFewerCgIterations) {
  const Problem p;
  const Eigen::VectorXd exact = p.exact();
  const Eigen::SparseMatrix<double>& l = p.laplacian;
  const Eigen::SparseMatrix<double> graph = neighbourhood(l, 3);
  EXPECT_EQ(graph.nonZeros(), 7 * p.blocks - 2 * (3 + 2 + 1));  // |i - j| <= 3
  const Eigen::SparseMatrix<double> basis = smoothed_aggregation_basis(graph, l);
  // A root and its 3 neighbours on either side: {0..3} (root 0), then {4..10} (root 7), {11..17},
  // ..., {193..199}: 1 + 196 / 7 aggregates.
  EXPECT_EQ(basis.cols(), 29);
  // The smoothed indicators still sum to 1 everywhere: constants lie in the coarse space.
  const Eigen::VectorXd sum = basis * Eigen::VectorXd::Ones(basis.cols());
  EXPECT_LE((sum - Eigen::VectorXd::Ones(p.blocks)).norm(), 1e-12 * std::sqrt(p.blocks));
  Eigen::VectorXd two_level, blocks;
  const ParameterFitSummary s2 = solve(p, 1.0, &two_level, basis);
  const ParameterFitSummary sb = solve(p, 1.0, &blocks);
  std::printf("CG iterations: two-level %ld (%d LM), block-Jacobi %ld (%d LM)\n", s2.cg_iterations,
              s2.iterations, sb.cg_iterations, sb.iterations);
  EXPECT_LE((two_level - exact).norm(), 1e-7 * exact.norm());
  EXPECT_LE((blocks - exact).norm(), 1e-7 * exact.norm());
  // Measured: 555 against 1,583 CG iterations (8 LM iterations each).
  EXPECT_LT(2 * s2.cg_iterations, sb.cg_iterations);
}

// CoarseSpace's scatter against Eigen's sparse triple product Pᵀ (X + RᵀR) P, P = C ⊗ I_b, for
// block sizes 1-3, a basis with overlapping supports and a regulariser wider than the basis (so
// the pattern has blocks from RᵀR alone); assembled twice with other X on the same pattern.
TEST(LmMatrixFree, CoarseSpaceAssemblesTheProjectedMatrix) {
  const Problem problem;
  const Eigen::SparseMatrix<double>& l = problem.laplacian;
  const Eigen::Index t = l.rows();
  const Eigen::SparseMatrix<double> basis = smoothed_aggregation_basis(neighbourhood(l, 2), l);
  ASSERT_GT(basis.cols(), 10);
  for (int b = 1; b <= 3; ++b) {
    // R: the squared path Laplacian on every channel, plus a prior on the last.
    std::vector<Eigen::Triplet<double>> trip;
    const Eigen::SparseMatrix<double> l2 = l * l;
    for (Eigen::Index k = 0; k < l2.outerSize(); ++k)
      for (Eigen::SparseMatrix<double>::InnerIterator it(l2, k); it; ++it)
        for (int c = 0; c < b; ++c)
          trip.emplace_back(static_cast<int>(it.row() * b + c), static_cast<int>(it.col() * b + c),
                            0.3 * it.value());
    for (Eigen::Index e = 0; e < t; ++e)
      trip.emplace_back(static_cast<int>(b * t + e), static_cast<int>(e * b + b - 1), 0.7);
    Eigen::SparseMatrix<double> r((b + 1) * t, b * t);
    r.setFromTriplets(trip.begin(), trip.end());
    const CoarseSpace space(basis, r, b);
    ASSERT_EQ(space.p().rows(), b * t);
    ASSERT_EQ(space.p().cols(), b * basis.cols());
    fem::SparseMatrix upper;
    for (int round = 0; round < 2; ++round) {
      Eigen::MatrixXd x(b * t, b);
      std::vector<Eigen::Triplet<double>> xt;
      for (Eigen::Index e = 0; e < t; ++e)
        for (int i = 0; i < b; ++i)
          for (int c = 0; c < b; ++c) {
            const double v = std::sin(1.3 * static_cast<double>(e * b * b + i * b + c) + round) +
                             (i == c ? 2.0 : 0.0);
            x(e * b + i, c) = v;
            xt.emplace_back(static_cast<int>(e * b + i), static_cast<int>(e * b + c), v);
          }
      Eigen::SparseMatrix<double> xs(b * t, b * t);
      xs.setFromTriplets(xt.begin(), xt.end());
      space.assemble(x, &upper);
      const Eigen::MatrixXd expected =
          Eigen::MatrixXd(Eigen::SparseMatrix<double>(
                              space.p().transpose() *
                              (xs + Eigen::SparseMatrix<double>(r.transpose() * r)) * space.p()))
              .triangularView<Eigen::Upper>();
      const Eigen::MatrixXd got = Eigen::MatrixXd(upper);
      EXPECT_LE((got - expected).norm(), 1e-12 * expected.norm()) << "block " << b;
      EXPECT_EQ(Eigen::MatrixXd(got.triangularView<Eigen::StrictlyLower>()).norm(), 0.0);
    }
  }
}

// umbrella_normal_product (fit_example's regulariser, applied from the Laplacian's neighbour
// lists) against RᵀR v with R assembled from its entries as fit_example assembles it, on the
// umbrella Laplacian of a tet mesh; and refused for a Laplacian with other weights.
TEST(LmMatrixFree, UmbrellaNormalProductIsRTransposeR) {
  // A strip of eight tets (k, k + 1, k + 2, k + 3) over nodes on a helix: tet k shares a vertex
  // with tets k - 3 .. k + 3, so the neighbour lists differ in length (3 at the ends, 6 inside) and
  // no two are the same.
  TetMesh mesh;
  constexpr int kTets = 8;
  mesh.nodes.resize(kTets + 3, 3);
  for (int i = 0; i < kTets + 3; ++i) mesh.nodes.row(i) << std::cos(2.1 * i), std::sin(2.1 * i), 0.3 * i;
  mesh.tets.resize(kTets, 4);
  for (int k = 0; k < kTets; ++k) mesh.tets.row(k) << k, k + 1, k + 2, k + 3;
  const Eigen::SparseMatrix<double> l = tet_umbrella_laplacian(mesh, TetAdjacency::kVertex);
  const Eigen::Index t = l.rows();
  ASSERT_EQ(l.coeff(0, 0), 3.0);
  ASSERT_EQ(l.coeff(4, 4), 6.0);
  const double gamma = 0.7, prior = 0.2;
  std::vector<Eigen::Triplet<double>> trip;
  for (Eigen::Index k = 0; k < l.outerSize(); ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(l, k); it; ++it)
      for (int c = 0; c < 2; ++c)
        trip.emplace_back(static_cast<int>(2 * it.row() + c), static_cast<int>(2 * it.col() + c),
                          std::sqrt(gamma) * it.value());
  for (Eigen::Index e = 0; e < t; ++e)
    trip.emplace_back(static_cast<int>(2 * t + e), static_cast<int>(2 * e + 1), std::sqrt(prior));
  Eigen::SparseMatrix<double> r(3 * t, 2 * t);
  r.setFromTriplets(trip.begin(), trip.end());
  const auto product = umbrella_normal_product(l, gamma, prior);
  ASSERT_TRUE(product);
  const Eigen::VectorXd v = Eigen::VectorXd::LinSpaced(2 * t, -1.0, 2.0).array().sin();
  Eigen::VectorXd out;
  product(v, &out);
  const Eigen::VectorXd expected = r.transpose() * (r * v);
  EXPECT_LE((out - expected).norm(), 1e-14 * expected.norm()) << out.transpose() << "\n"
                                                               << expected.transpose();
  // Without γ, only the prior.
  const auto prior_only = umbrella_normal_product(l, 0.0, prior);
  prior_only(v, &out);
  for (Eigen::Index e = 0; e < t; ++e) {
    EXPECT_EQ(out(2 * e), 0.0);
    EXPECT_DOUBLE_EQ(out(2 * e + 1), prior * v(2 * e + 1));
  }
  Eigen::SparseMatrix<double> weighted = l;
  weighted.coeffRef(2, 4) = -0.5;
  EXPECT_FALSE(umbrella_normal_product(weighted, gamma, prior));
}

}  // namespace
}  // namespace hc::material::detail
