#include "processing/fem/sparse_cholesky.h"

#include <cholmod.h>

#include <string>

#include "common/openmp.h"

namespace hc::fem {

struct SparseCholesky::Impl {
  Options options;
  Summary summary;
  cholmod_common common{};
  cholmod_factor* factor = nullptr;
  bool factorized = false;
  Eigen::Index n = 0;
  Eigen::Index nnz = 0;
  // Reused solve workspaces (cholmod_solve2); mutable because solve() is logically const.
  mutable cholmod_dense* x = nullptr;
  mutable cholmod_dense* y = nullptr;
  mutable cholmod_dense* e = nullptr;

  Impl() {
    cholmod_start(&common);
    // Errors come back as return values; don't let CHOLMOD print to stderr.
    common.print = 0;
    common.error_handler = nullptr;
    // LL^T also for simplicial factors: CHOLMOD's default simplicial LDL^T "succeeds" on indefinite
    // matrices, and we must report a matrix that is not positive definite.
    common.final_ll = 1;
    // The fill-reducing ordering is chosen once per pattern and reused for every factorisation, so
    // try AMD and both nested dissections and keep the one with the fewest flops. On the
    // 16x13x8-cell box of bench_fem_step NESDIS needs 402 MFlop against AMD's 533.
    common.nmethods = 3;
    common.method[0].ordering = CHOLMOD_AMD;
    common.method[1].ordering = CHOLMOD_METIS;
    common.method[2].ordering = CHOLMOD_NESDIS;
  }
  ~Impl() {
    free_workspace();
    if (factor != nullptr) cholmod_free_factor(&factor, &common);
    cholmod_finish(&common);
  }
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;

  void free_workspace() const {
    auto* c = const_cast<cholmod_common*>(&common);
    if (x != nullptr) cholmod_free_dense(&x, c);
    if (y != nullptr) cholmod_free_dense(&y, c);
    if (e != nullptr) cholmod_free_dense(&e, c);
  }

  // A non-owning CHOLMOD view of an Eigen upper-triangular CSC matrix (no copy).
  static cholmod_sparse view(const SparseMatrix& a) {
    cholmod_sparse s{};
    s.nrow = static_cast<size_t>(a.rows());
    s.ncol = static_cast<size_t>(a.cols());
    s.nzmax = static_cast<size_t>(a.nonZeros());
    s.p = const_cast<int*>(a.outerIndexPtr());
    s.i = const_cast<int*>(a.innerIndexPtr());
    s.x = const_cast<double*>(a.valuePtr());
    s.nz = nullptr;
    s.stype = 1;  // upper triangle stored
    s.itype = CHOLMOD_INT;
    s.xtype = CHOLMOD_REAL;
    s.dtype = CHOLMOD_DOUBLE;
    s.sorted = 1;
    s.packed = 1;
    return s;
  }
};

namespace {

Status check_matrix(const SparseMatrix& a) {
  if (a.rows() != a.cols()) {
    return invalid_argument("sparse Cholesky: matrix is " + std::to_string(a.rows()) + " x " +
                            std::to_string(a.cols()) + ", not square");
  }
  if (!a.isCompressed()) return invalid_argument("sparse Cholesky: matrix is not compressed");
  if (a.rows() == 0) return invalid_argument("sparse Cholesky: empty matrix");
  return {};
}

}  // namespace

SparseCholesky::SparseCholesky() : SparseCholesky(Options{}) {}
SparseCholesky::SparseCholesky(const Options& options) : impl_(std::make_unique<Impl>()) {
  impl_->options = options;
  impl_->common.supernodal = options.force_supernodal ? CHOLMOD_SUPERNODAL : CHOLMOD_AUTO;
}
SparseCholesky::~SparseCholesky() = default;
SparseCholesky::SparseCholesky(SparseCholesky&&) noexcept = default;
SparseCholesky& SparseCholesky::operator=(SparseCholesky&&) noexcept = default;

Status SparseCholesky::analyze(const SparseMatrix& upper) {
  HC_RETURN_IF_ERROR(check_matrix(upper));
  Impl& s = *impl_;
  if (s.factor != nullptr) cholmod_free_factor(&s.factor, &s.common);
  s.free_workspace();
  s.factorized = false;
  cholmod_sparse a = Impl::view(upper);
  const SerialOpenMpScope serial;
  s.factor = cholmod_analyze(&a, &s.common);
  if (s.factor == nullptr) {
    return internal_error("sparse Cholesky: symbolic analysis failed (CHOLMOD status " +
                          std::to_string(s.common.status) + ")");
  }
  s.n = upper.rows();
  s.nnz = upper.nonZeros();
  ++s.summary.analyse_calls;
  s.summary.nnz_factor = s.common.lnz;
  s.summary.supernodal = s.factor->is_super != 0;
  return {};
}

Status SparseCholesky::factorize(const SparseMatrix& upper) {
  Impl& s = *impl_;
  if (s.factor == nullptr)
    return failed_precondition("sparse Cholesky: factorize() before analyze()");
  if (upper.rows() != s.n || upper.cols() != s.n || upper.nonZeros() != s.nnz) {
    return invalid_argument("sparse Cholesky: matrix pattern differs from the analysed one");
  }
  HC_RETURN_IF_ERROR(check_matrix(upper));
  cholmod_sparse a = Impl::view(upper);
  s.factorized = false;
  const SerialOpenMpScope serial;  // see common/openmp.h
  const int ok = cholmod_factorize(&a, s.factor, &s.common);
  ++s.summary.factorize_calls;
  s.summary.flops = s.common.fl;
  if (!ok || s.common.status == CHOLMOD_NOT_POSDEF) {
    if (s.common.status == CHOLMOD_NOT_POSDEF) {
      return failed_precondition("sparse Cholesky: matrix is not positive definite (column " +
                                 std::to_string(s.factor->minor) + " of " + std::to_string(s.n) +
                                 ")");
    }
    return internal_error("sparse Cholesky: numeric factorisation failed (CHOLMOD status " +
                          std::to_string(s.common.status) + ")");
  }
  s.factorized = true;
  return {};
}

Status SparseCholesky::compute(const SparseMatrix& upper) {
  HC_RETURN_IF_ERROR(analyze(upper));
  return factorize(upper);
}

Status SparseCholesky::solve(const Eigen::MatrixXd& b, Eigen::MatrixXd* x) const {
  const Impl& s = *impl_;
  if (!s.factorized) return failed_precondition("sparse Cholesky: solve() without a factorisation");
  if (b.rows() != s.n) {
    return invalid_argument("sparse Cholesky: right-hand side has " + std::to_string(b.rows()) +
                            " rows, expected " + std::to_string(s.n));
  }
  if (b.cols() == 0) {
    x->resize(s.n, 0);
    return {};
  }
  cholmod_dense bd{};
  bd.nrow = static_cast<size_t>(b.rows());
  bd.ncol = static_cast<size_t>(b.cols());
  bd.nzmax = bd.nrow * bd.ncol;
  bd.d = bd.nrow;
  bd.x = const_cast<double*>(b.data());
  bd.xtype = CHOLMOD_REAL;
  bd.dtype = CHOLMOD_DOUBLE;
  auto* c = const_cast<cholmod_common*>(&s.common);
  if (!cholmod_solve2(CHOLMOD_A, s.factor, &bd, nullptr, &s.x, nullptr, &s.y, &s.e, c)) {
    return internal_error("sparse Cholesky: solve failed (CHOLMOD status " +
                          std::to_string(s.common.status) + ")");
  }
  x->resize(b.rows(), b.cols());
  const auto* src = static_cast<const double*>(s.x->x);
  std::copy(src, src + b.size(), x->data());
  return {};
}

Status SparseCholesky::solve(const Eigen::VectorXd& b, Eigen::VectorXd* x) const {
  Eigen::MatrixXd bm = b;  // one copy; keeps a single CHOLMOD entry point
  Eigen::MatrixXd xm;
  HC_RETURN_IF_ERROR(solve(bm, &xm));
  *x = xm.col(0);
  return {};
}

bool SparseCholesky::analyzed() const { return impl_->factor != nullptr; }
bool SparseCholesky::factorized() const { return impl_->factorized; }
Eigen::Index SparseCholesky::rows() const { return impl_->n; }
const SparseCholesky::Summary& SparseCholesky::summary() const { return impl_->summary; }

}  // namespace hc::fem
