// CHOLMOD wrapper vs Eigen's dense LLT on small SPD systems; failure modes.
#include "processing/fem/sparse_cholesky.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <vector>

namespace hc::fem {
namespace {

// Upper triangle of a random sparse SPD matrix: 1-D Laplacian-like band plus random couplings and a
// dominant diagonal (strict diagonal dominance guarantees positive definiteness).
SparseMatrix random_spd(int n, unsigned seed, Eigen::MatrixXd* dense) {
  std::srand(seed);
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n, n);
  for (int i = 0; i < n; ++i) {
    if (i + 1 < n) a(i, i + 1) = a(i + 1, i) = -1.0;
    const int j = std::rand() % n;
    if (j != i) a(i, j) = a(j, i) = 0.5 * (std::rand() % 100) / 100.0 - 0.25;
  }
  for (int i = 0; i < n; ++i) a(i, i) = a.row(i).cwiseAbs().sum() + 1.0;
  *dense = a;
  std::vector<Eigen::Triplet<double>> t;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i <= j; ++i)
      if (a(i, j) != 0 || i == j) t.emplace_back(i, j, a(i, j));
  SparseMatrix s(n, n);
  s.setFromTriplets(t.begin(), t.end());
  s.makeCompressed();
  return s;
}

TEST(SparseCholesky, MatchesDenseLltOneAndManyRightHandSides) {
  Eigen::MatrixXd dense;
  const SparseMatrix a = random_spd(60, 7, &dense);
  SparseCholesky chol;
  ASSERT_TRUE(chol.compute(a).ok());
  const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(60, -1.0, 2.0);
  Eigen::VectorXd x;
  ASSERT_TRUE(chol.solve(b, &x).ok());
  const Eigen::VectorXd x_ref = dense.llt().solve(b);  // Eigen dense Cholesky as the peer solver
  EXPECT_LT((x - x_ref).norm(), 1e-12 * x_ref.norm());
  Eigen::MatrixXd bm = Eigen::MatrixXd::Random(60, 5);
  Eigen::MatrixXd xm;
  ASSERT_TRUE(chol.solve(bm, &xm).ok());
  EXPECT_LT((xm - dense.llt().solve(bm)).norm(), 1e-12 * xm.norm());
}

// The upper triangle of a side³ grid Laplacian with 3 rows per node sharing its pattern, as an
// FEM's coordinates do, plus `shift` on the diagonal.
SparseMatrix grid_laplacian(int side, double shift = 1.0) {
  const int rows = 3 * side * side * side;
  const auto node = [side](int x, int y, int z) { return (z * side + y) * side + x; };
  std::vector<Eigen::Triplet<double>> t;
  Eigen::VectorXd diagonal = Eigen::VectorXd::Constant(rows, shift);
  for (int z = 0; z < side; ++z)
    for (int y = 0; y < side; ++y)
      for (int x = 0; x < side; ++x) {
        const int i = node(x, y, z);
        const int nbrs[3][3] = {{x + 1, y, z}, {x, y + 1, z}, {x, y, z + 1}};
        for (const auto& q : nbrs) {
          if (q[0] >= side || q[1] >= side || q[2] >= side) continue;
          const int j = node(q[0], q[1], q[2]);
          for (int c = 0; c < 3; ++c)
            for (int d = 0; d < 3; ++d) {
              t.emplace_back(std::min(3 * i + c, 3 * j + d), std::max(3 * i + c, 3 * j + d), -0.1);
              diagonal(3 * i + c) += 0.1;
              diagonal(3 * j + d) += 0.1;
            }
        }
      }
  for (int i = 0; i < rows; ++i) t.emplace_back(i, i, diagonal(i));  // diagonally dominant
  SparseMatrix upper(rows, rows);
  upper.setFromTriplets(t.begin(), t.end());
  upper.makeCompressed();
  return upper;
}

// Orderings computed on the graph of 3-row blocks (block_size) or by AMD alone (amd_only) are
// other permutations of the same factorisation: the same solution as Eigen's own sparse LDLT. The
// matrix: a 3-D grid Laplacian with 3 rows per node sharing its pattern, as an FEM's coordinates
// do. The default tries AMD, METIS and nested dissection and keeps the fewest flops
// (sparse_cholesky.cpp); on this 16³ grid a nested dissection wins, so AMD alone costs more
// (measured 1.61e9 against 1.27e9 flops; the block ordering 0.84e9).
TEST(SparseCholesky, BlockAndAmdOrderingsSolveTheSameSystem) {
  constexpr int kRows = 3 * 16 * 16 * 16;
  const SparseMatrix upper = grid_laplacian(16);
  const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(kRows, -1.0, 2.0);
  const Eigen::SparseMatrix<double> full = upper.selfadjointView<Eigen::Upper>();
  const Eigen::VectorXd expected = Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>(full).solve(b);
  double default_flops = 0;
  for (const SparseCholesky::Options& o :
       {SparseCholesky::Options{}, SparseCholesky::Options{.block_size = 3},
        SparseCholesky::Options{.amd_only = true}}) {
    SparseCholesky chol(o);
    ASSERT_TRUE(chol.compute(upper).ok());
    Eigen::VectorXd x;
    ASSERT_TRUE(chol.solve(b, &x).ok());
    EXPECT_LT((x - expected).cwiseAbs().maxCoeff(), 1e-12);
    if (default_flops == 0) default_flops = chol.summary().flops;
    if (o.amd_only) {
      EXPECT_GT(chol.summary().flops, default_flops);
    }
  }
}

// The single-precision solve against CHOLMOD's double one on a supernodal factor (the 14³ grid:
// supernodes from one column to dense blocks of thousands of entries, so both the Eigen and the
// OpenBLAS paths run), for one and many right-hand sides, and after a refactorisation with other
// values (the float copy must follow). Its error is float rounding: above 1e-9 (so it is the float
// path) and below 1e-5 (float's 6e-8 times this matrix's modest condition number).
TEST(SparseCholesky, SinglePrecisionSolveMatchesTheDoubleOne) {
  for (const double shift : {1.0, 0.01}) {
    const SparseMatrix a = grid_laplacian(14, shift);
    SparseCholesky chol(SparseCholesky::Options{.force_supernodal = true, .block_size = 3});
    ASSERT_TRUE(chol.compute(a).ok());
    ASSERT_TRUE(chol.summary().supernodal);
    Eigen::MatrixXd b = Eigen::MatrixXd::Random(a.rows(), 4);
    Eigen::MatrixXd exact, single;
    ASSERT_TRUE(chol.solve(b, &exact).ok());
    ASSERT_TRUE(chol.solve_single_precision(b, &single).ok());
    for (Eigen::Index c = 0; c < b.cols(); ++c) {
      const double err = (single.col(c) - exact.col(c)).norm() / exact.col(c).norm();
      EXPECT_LT(err, 1e-5) << "shift " << shift << " column " << c;
      EXPECT_GT(err, 1e-9) << "shift " << shift << " column " << c;
      Eigen::VectorXd one;
      ASSERT_TRUE(chol.solve_single_precision(Eigen::VectorXd(b.col(c)), &one).ok());
      EXPECT_LT((one - exact.col(c)).norm(), 1e-5 * exact.col(c).norm());
    }
  }
  // Refactorised with the diagonal doubled: the answer of the new values, not the copy's.
  SparseMatrix a = grid_laplacian(14);
  SparseCholesky chol(SparseCholesky::Options{.force_supernodal = true});
  ASSERT_TRUE(chol.compute(a).ok());
  const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(a.rows(), -1.0, 2.0);
  Eigen::VectorXd x;
  ASSERT_TRUE(chol.solve_single_precision(b, &x).ok());
  for (Eigen::Index c = 0; c < a.cols(); ++c) a.coeffRef(c, c) *= 2;
  ASSERT_TRUE(chol.factorize(a).ok());
  Eigen::VectorXd exact, single;
  ASSERT_TRUE(chol.solve(b, &exact).ok());
  ASSERT_TRUE(chol.solve_single_precision(b, &single).ok());
  EXPECT_LT((single - exact).norm(), 1e-5 * exact.norm());
  EXPECT_GT((x - exact).norm(), 1e-2 * exact.norm());
  // A simplicial factor is solved by the double solve, and a misfit right-hand side refused.
  Eigen::MatrixXd dense;
  SparseCholesky simplicial;
  ASSERT_TRUE(simplicial.compute(random_spd(60, 7, &dense)).ok());
  ASSERT_FALSE(simplicial.summary().supernodal);
  const Eigen::VectorXd b60 = Eigen::VectorXd::LinSpaced(60, -1.0, 2.0);
  ASSERT_TRUE(simplicial.solve(b60, &exact).ok());
  ASSERT_TRUE(simplicial.solve_single_precision(b60, &single).ok());
  EXPECT_EQ(single, exact);
  EXPECT_EQ(chol.solve_single_precision(b60, &single).code(), StatusCode::kInvalidArgument);
  const Status unfactorised = SparseCholesky().solve_single_precision(b60, &single);
  EXPECT_EQ(unfactorised.code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(unfactorised.message().find("solve_single_precision"), std::string::npos);
}

TEST(SparseCholesky, NumericRefactorisationReusesTheAnalysis) {
  Eigen::MatrixXd dense;
  SparseMatrix a = random_spd(40, 3, &dense);
  SparseCholesky chol;
  ASSERT_TRUE(chol.analyze(a).ok());
  for (int k = 1; k <= 3; ++k) {
    SparseMatrix ak = a;
    for (int c = 0; c < ak.cols(); ++c) ak.coeffRef(c, c) += k;  // same pattern, new values
    Eigen::MatrixXd dk = dense;
    dk.diagonal().array() += k;
    ASSERT_TRUE(chol.factorize(ak).ok());
    Eigen::VectorXd x;
    const Eigen::VectorXd b = Eigen::VectorXd::Ones(40);
    ASSERT_TRUE(chol.solve(b, &x).ok());
    EXPECT_LT((x - dk.llt().solve(b)).norm(), 1e-12 * x.norm());
  }
  EXPECT_EQ(chol.summary().analyse_calls, 1);
  EXPECT_EQ(chol.summary().factorize_calls, 3);
}

TEST(SparseCholesky, NotPositiveDefiniteIsAnError) {
  Eigen::MatrixXd dense;
  SparseMatrix a = random_spd(20, 5, &dense);
  a.coeffRef(10, 10) = -50.0;
  SparseCholesky chol;
  const Status st = chol.compute(a);
  EXPECT_EQ(st.code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(st.message().find("not positive definite"), std::string::npos) << st.message();
  EXPECT_FALSE(chol.factorized());
  Eigen::VectorXd x;
  EXPECT_FALSE(chol.solve(Eigen::VectorXd::Ones(20), &x).ok());
}

TEST(SparseCholesky, MisuseIsReported) {
  Eigen::MatrixXd dense;
  const SparseMatrix a = random_spd(10, 1, &dense);
  SparseCholesky chol;
  EXPECT_EQ(chol.factorize(a).code(), StatusCode::kFailedPrecondition);  // before analyze
  ASSERT_TRUE(chol.compute(a).ok());
  Eigen::VectorXd x;
  EXPECT_EQ(chol.solve(Eigen::VectorXd::Ones(7), &x).code(), StatusCode::kInvalidArgument);
  const SparseMatrix other = random_spd(12, 1, &dense);
  EXPECT_EQ(chol.factorize(other).code(), StatusCode::kInvalidArgument);
  SparseMatrix rect(3, 4);
  EXPECT_EQ(chol.analyze(rect).code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace hc::fem
