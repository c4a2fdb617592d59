// Sparse Cholesky factorisation of symmetric positive definite matrices through CHOLMOD
// (SuiteSparse).
//
// The FEM solves K x = b many times with the same sparsity pattern and changing values
// (co-rotation, strain-dependent parameters, contact penalties), and the material fitter (thesis
// Appendix A) solves many right-hand sides with one factorisation. So the pattern is analysed once
// (fill-reducing ordering + symbolic factorisation), the numeric factorisation is repeated, and
// solves take one or many right-hand sides.
//
// Why not Eigen's CholmodSupport: we want hc::Status on failure (with the column where positive
// definiteness was lost), no copies of the matrix, and reused solve workspaces (cholmod_solve2) so
// that a solve allocates nothing in the steady state.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <memory>

#include "common/status.h"

namespace hc::fem {

// Column-major sparse matrix with int indices; the solver reads only its UPPER triangle (incl.
// diagonal).
using SparseMatrix = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;

class SparseCholesky {
 public:
  struct Options {
    // CHOLMOD's automatic choice between simplicial and supernodal factorisation (CHOLMOD_AUTO)
    // when false; force supernodal when true.
    bool force_supernodal = false;
    // Unknowns come in blocks of this many consecutive rows that share one sparsity pattern (an
    // FEM's coordinates per node): the fill-reducing ordering is then computed on the blocks'
    // graph, block_size² times smaller, and expanded. 1 = order the matrix itself.
    int block_size = 1;
    // AMD alone instead of the best of AMD, METIS and nested dissection: a fast analysis whose
    // fill is an upper bound of the best ordering's, to estimate what a factorisation would cost.
    bool amd_only = false;
  };

  struct Summary {
    int analyse_calls = 0;
    int factorize_calls = 0;
    double nnz_factor = 0;  // entries of L after the last analysis
    double flops = 0;       // CHOLMOD's flop count of the numeric factorisation
    double factorize_time_s = 0;  // wall time in numeric factorisations, summed over the calls
    bool supernodal = false;
  };

  SparseCholesky();
  explicit SparseCholesky(const Options& options);
  ~SparseCholesky();
  SparseCholesky(SparseCholesky&&) noexcept;
  SparseCholesky& operator=(SparseCholesky&&) noexcept;
  SparseCholesky(const SparseCholesky&) = delete;
  SparseCholesky& operator=(const SparseCholesky&) = delete;

  // Symbolic analysis of `upper`'s pattern (square, compressed, upper triangle incl. the full
  // diagonal). Values are ignored. Invalidates any previous factorisation. Fails on a non-square /
  // uncompressed matrix or when CHOLMOD runs out of memory.
  Status analyze(const SparseMatrix& upper);

  // Numeric factorisation of `upper`, which must have exactly the pattern given to analyze() (same
  // rows(), nonZeros()). Returns failed_precondition("... not positive definite (column k) ...")
  // when the matrix is not SPD; the object then has no valid factorisation until the next success.
  Status factorize(const SparseMatrix& upper);

  // analyze() + factorize().
  Status compute(const SparseMatrix& upper);

  // x = A^{-1} b. b has rows() entries. Precondition for success: factorized().
  Status solve(const Eigen::VectorXd& b, Eigen::VectorXd* x) const;
  // X = A^{-1} B for many right-hand sides at once (B is rows() by k, column-major).
  Status solve(const Eigen::MatrixXd& b, Eigen::MatrixXd* x) const;
  // x ≈ A^{-1} b through a single-precision copy of the factor, made at the first call after each
  // factorisation: half the memory a solve reads (the solves of a large factor are bound by it),
  // at a relative error of about 1e-7 times A's condition number. For preconditioners, whose
  // iterations correct that error; a simplicial factor is solved by solve().
  Status solve_single_precision(const Eigen::VectorXd& b, Eigen::VectorXd* x) const;
  Status solve_single_precision(const Eigen::MatrixXd& b, Eigen::MatrixXd* x) const;

  bool analyzed() const;
  bool factorized() const;
  Eigen::Index rows() const;
  const Summary& summary() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hc::fem
