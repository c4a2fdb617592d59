#include "processing/fem/sparse_cholesky.h"

#include <cholmod.h>
#include <chrono>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "common/huge_pages.h"
#include "common/openmp.h"
#include "processing/fem/blas_threads.h"

// Single-precision BLAS from OpenBLAS, which comes with SuiteSparse::CHOLMOD (see blas_threads.cpp
// for why these are declared here).
extern "C" {
void sgemv_(const char* trans, const int* m, const int* n, const float* alpha, const float* a,
            const int* lda, const float* x, const int* incx, const float* beta, float* y,
            const int* incy);
void strsv_(const char* uplo, const char* trans, const char* diag, const int* n, const float* a,
            const int* lda, float* x, const int* incx);
void sgemm_(const char* transa, const char* transb, const int* m, const int* n, const int* k,
            const float* alpha, const float* a, const int* lda, const float* b, const int* ldb,
            const float* beta, float* c, const int* ldc);
void strsm_(const char* side, const char* uplo, const char* transa, const char* diag, const int* m,
            const int* n, const float* alpha, const float* a, const int* lda, float* b,
            const int* ldb);
}

namespace hc::fem {
namespace {
// Factors with at least this many entries are factorised with OpenBLAS's threads (see factorize).
constexpr double kThreadedFactorEntries = 3e7;
}  // namespace

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
  // solve_single_precision(): the supernodal factor's values as floats (empty: not made since
  // the last factorisation), and its permuted right-hand side.
  mutable std::vector<float> lx;
  mutable std::vector<float> work;
  mutable std::vector<float> gathered;

  Impl() {
    // CHOLMOD allocates through SuiteSparse's process-wide hooks: its large blocks (the factor,
    // written anew by every factorisation) get huge pages (common/huge_pages.h). Default Hertz
    // scene, `hardcopy simulate`: 68k page faults -> 25k, 3.01 -> 2.60 s (mean of 4 alternating
    // runs each). The hooks are set before this process's first cholmod_start; memory they give
    // is released by free(), so earlier and later blocks mix safely.
    static std::once_flag hooks;
    std::call_once(hooks, [] {
      SuiteSparse_config.malloc_func = malloc_huge;
      SuiteSparse_config.calloc_func = calloc_huge;
      SuiteSparse_config.realloc_func = realloc_huge;
    });
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
  // f() with CHOLMOD set to use one ordering method.
  template <typename F>
  cholmod_factor* with_one_method(int ordering, F&& f) {
    const int methods = common.nmethods;
    const auto first = common.method[0];
    common.nmethods = 1;
    common.method[0].ordering = ordering;
    cholmod_factor* result = f();
    common.nmethods = methods;
    common.method[0] = first;
    return result;
  }

  // The fill-reducing ordering of `upper`'s blocks of b rows, expanded to the rows: CHOLMOD's
  // nested dissection of the blocks' graph. Trying AMD and METIS too, as for other matrices,
  // costs twice as much: on the default Hertz scene's 6,834 nodes (20,502 rows) the three took
  // 96 ms, NESDIS alone 49 ms, and NESDIS gave the least fill (10.8M entries; METIS 10.9M, AMD
  // 15.3M).
  Result<std::vector<int>> block_ordering(const SparseMatrix& upper, int b) {
    const Eigen::Index nb = upper.rows() / b;
    // The blocks' pattern, column by column (upper triangle: a block column's rows are sorted
    // blocks, each once).
    SparseMatrix blocks(nb, nb);
    std::vector<int> seen(static_cast<std::size_t>(nb), -1), rows;
    std::vector<Eigen::Triplet<double, int>> entries;
    for (Eigen::Index jb = 0; jb < nb; ++jb) {
      rows.clear();
      for (int k = 0; k < b; ++k) {
        for (SparseMatrix::InnerIterator it(upper, jb * b + k); it; ++it) {
          const int ib = static_cast<int>(it.row() / b);
          if (seen[static_cast<std::size_t>(ib)] == jb) continue;
          seen[static_cast<std::size_t>(ib)] = static_cast<int>(jb);
          rows.push_back(ib);
        }
      }
      for (int ib : rows) entries.emplace_back(ib, static_cast<int>(jb), 1.0);
    }
    blocks.setFromTriplets(entries.begin(), entries.end());
    cholmod_sparse bv = view(blocks);
    cholmod_factor* f =
        with_one_method(CHOLMOD_NESDIS, [&] { return cholmod_analyze(&bv, &common); });
    if (f == nullptr) {
      return internal_error("sparse Cholesky: ordering the blocks failed (CHOLMOD status " +
                            std::to_string(common.status) + ")");
    }
    const int* block_perm = static_cast<const int*>(f->Perm);
    std::vector<int> perm(static_cast<std::size_t>(upper.rows()));
    for (Eigen::Index i = 0; i < nb; ++i)
      for (int k = 0; k < b; ++k) perm[static_cast<std::size_t>(i * b + k)] = block_perm[i] * b + k;
    cholmod_free_factor(&f, &common);
    return perm;
  }

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
  if (options.amd_only) impl_->common.nmethods = 1;  // method[0] is AMD
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
  s.lx.clear();
  cholmod_sparse a = Impl::view(upper);
  const SerialOpenMpScope serial;
  const int b = s.options.block_size;
  if (b > 1 && upper.rows() % b == 0 && upper.rows() > b) {
    HC_ASSIGN_OR_RETURN(std::vector<int> perm, s.block_ordering(upper, b));
    s.factor = s.with_one_method(
        CHOLMOD_GIVEN, [&] { return cholmod_analyze_p(&a, perm.data(), nullptr, 0, &s.common); });
  } else {
    s.factor = cholmod_analyze(&a, &s.common);
  }
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
  s.lx.clear();
  const SerialOpenMpScope serial;  // see common/openmp.h
  // OpenBLAS's threads pay for themselves only on large factors (a 100k-tet step: 2.6 -> 1.9-2.2
  // s with two; 10k tets: no gain), and where other processes keep the cores busy every threaded
  // BLAS call waits for a worker to be scheduled (blas_threads.h).
  std::optional<SingleThreadedBlasScope> single;
  if (s.summary.nnz_factor < kThreadedFactorEntries) single.emplace();
  const auto t0 = std::chrono::steady_clock::now();
  const int ok = cholmod_factorize(&a, s.factor, &s.common);
  s.summary.factorize_time_s +=
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
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
  const SingleThreadedBlasScope single;  // as in solve_single_precision
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

Status SparseCholesky::solve_single_precision(const Eigen::MatrixXd& b, Eigen::MatrixXd* x) const {
  const Impl& s = *impl_;
  if (!s.factorized)
    return failed_precondition("sparse Cholesky: solve_single_precision() without a factorisation");
  const cholmod_factor* f = s.factor;
  if (!f->is_super || !f->is_ll) return solve(b, x);
  // Many small BLAS calls: with OpenBLAS's threads each waits for a worker (blas_threads.h).
  const SingleThreadedBlasScope single;
  if (b.rows() != s.n) {
    return invalid_argument("sparse Cholesky: right-hand side has " + std::to_string(b.rows()) +
                            " rows, expected " + std::to_string(s.n));
  }
  const auto nsuper = static_cast<Eigen::Index>(f->nsuper);
  const int* super = static_cast<const int*>(f->super);
  const int* pi = static_cast<const int*>(f->pi);
  const int* px = static_cast<const int*>(f->px);
  const int* rows = static_cast<const int*>(f->s);
  const int* perm = static_cast<const int*>(f->Perm);
  if (s.lx.empty()) {
    const auto* lx = static_cast<const double*>(f->x);
    const auto size = static_cast<std::size_t>(px[nsuper]);
    if (s.lx.capacity() < size) {
      s.lx.reserve(size);
      advise_huge_pages(s.lx.data(), size * sizeof(float));
    }
    s.lx.assign(lx, lx + size);
  }
  // L Lᵀ = P A Pᵀ: Y = P B, L Z = Y, Lᵀ W = Z, X = Pᵀ W, in place in Y. Supernode k holds columns
  // super[k] .. super[k + 1] of L as a dense column-major block: its rows are rows[pi[k] ..], the
  // first of them its own columns (a lower-triangular block), the rest below. Blocks of at least
  // kBlasEntries go to OpenBLAS (single-threaded: see the scope above); smaller ones stay in
  // Eigen (no call overhead). Measured with OpenBLAS's two threads, before the solves were made
  // single-threaded (the default Hertz scene's `simulate` took the same time either way when the
  // machine was idle): default Hertz scene (10.8M factor entries), 80 solves:
  // CHOLMOD's double solve 0.86 s, this 0.56 s (with the threshold at 2^16: 0.78 s). On grid
  // Laplacians with 3 rows per node (the unit test's), per solve: 1.4M entries 1.29 -> 0.90 ms,
  // 6.5M 5.4 -> 3.4 ms, 27M 31.5 -> 17.6 ms.
  constexpr long kBlasEntries = 1 << 8;
  using MatrixF = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic>;
  using Strided = Eigen::Map<MatrixF, 0, Eigen::OuterStride<>>;
  const int n = static_cast<int>(s.n), k = static_cast<int>(b.cols()), one = 1;
  const float unit = 1, minus = -1, zero = 0;
  std::vector<float>& y = s.work;
  y.resize(static_cast<std::size_t>(n) * static_cast<std::size_t>(k));
  for (int c = 0; c < k; ++c)
    for (int i = 0; i < n; ++i)
      y[static_cast<std::size_t>(c) * n + i] = static_cast<float>(b(perm[i], c));
  std::vector<float>& t = s.gathered;
  const auto gathered = [&](int below) {
    t.resize(static_cast<std::size_t>(below) * static_cast<std::size_t>(k));
    return Eigen::Map<MatrixF>(t.data(), below, k);
  };
  struct Supernode {
    int ncol, nrow, below;
    const float* l;   // its block, nrow × ncol
    float* own;       // its columns' rows of Y
    const int* rows;  // the rows below its own
    bool large;
  };
  const auto supernode = [&](Eigen::Index sn) {
    const int k1 = super[sn], ncol = super[sn + 1] - k1, nrow = pi[sn + 1] - pi[sn];
    return Supernode{ncol,
                     nrow,
                     nrow - ncol,
                     s.lx.data() + px[sn],
                     y.data() + k1,
                     rows + pi[sn] + ncol,
                     static_cast<long>(nrow) * ncol >= kBlasEntries};
  };
  for (Eigen::Index sn = 0; sn < nsuper; ++sn) {
    const auto [ncol, nrow, below, l, y_own, r, large] = supernode(sn);
    const Eigen::Map<const MatrixF> block(l, nrow, ncol);
    Strided own(y_own, ncol, k, Eigen::OuterStride<>(n));
    if (!large) {
      block.topRows(ncol).triangularView<Eigen::Lower>().solveInPlace(own);
    } else if (k == 1) {
      strsv_("L", "N", "N", &ncol, l, &nrow, own.data(), &one);
    } else {
      strsm_("L", "L", "N", "N", &ncol, &k, &unit, l, &nrow, own.data(), &n);
    }
    if (below == 0) continue;
    Eigen::Map<MatrixF> tb = gathered(below);
    if (!large) {
      tb.noalias() = block.bottomRows(below) * own;
    } else if (k == 1) {
      sgemv_("N", &below, &ncol, &unit, l + ncol, &nrow, own.data(), &one, &zero, tb.data(), &one);
    } else {
      sgemm_("N", "N", &below, &k, &ncol, &unit, l + ncol, &nrow, own.data(), &n, &zero, tb.data(),
             &below);
    }
    for (int c = 0; c < k; ++c) {
      float* yc = y.data() + static_cast<std::size_t>(c) * n;
      for (int i = 0; i < below; ++i) yc[r[i]] -= tb(i, c);
    }
  }
  for (Eigen::Index sn = nsuper - 1; sn >= 0; --sn) {
    const auto [ncol, nrow, below, l, y_own, r, large] = supernode(sn);
    const Eigen::Map<const MatrixF> block(l, nrow, ncol);
    Strided own(y_own, ncol, k, Eigen::OuterStride<>(n));
    if (below > 0) {
      Eigen::Map<MatrixF> tb = gathered(below);
      for (int c = 0; c < k; ++c) {
        const float* yc = y.data() + static_cast<std::size_t>(c) * n;
        for (int i = 0; i < below; ++i) tb(i, c) = yc[r[i]];
      }
      if (!large) {
        own.noalias() -= block.bottomRows(below).transpose() * tb;
      } else if (k == 1) {
        sgemv_("T", &below, &ncol, &minus, l + ncol, &nrow, tb.data(), &one, &unit, own.data(),
               &one);
      } else {
        sgemm_("T", "N", &ncol, &k, &below, &minus, l + ncol, &nrow, tb.data(), &below, &unit,
               own.data(), &n);
      }
    }
    if (!large) {
      block.topRows(ncol).triangularView<Eigen::Lower>().transpose().solveInPlace(own);
    } else if (k == 1) {
      strsv_("L", "T", "N", &ncol, l, &nrow, own.data(), &one);
    } else {
      strsm_("L", "L", "T", "N", &ncol, &k, &unit, l, &nrow, own.data(), &n);
    }
  }
  x->resize(n, k);
  for (int c = 0; c < k; ++c)
    for (int i = 0; i < n; ++i) (*x)(perm[i], c) = y[static_cast<std::size_t>(c) * n + i];
  return {};
}

Status SparseCholesky::solve_single_precision(const Eigen::VectorXd& b, Eigen::VectorXd* x) const {
  Eigen::MatrixXd xm;
  HC_RETURN_IF_ERROR(solve_single_precision(Eigen::MatrixXd(b), &xm));
  *x = xm.col(0);
  return {};
}

bool SparseCholesky::analyzed() const { return impl_->factor != nullptr; }
bool SparseCholesky::factorized() const { return impl_->factorized; }
Eigen::Index SparseCholesky::rows() const { return impl_->n; }
const SparseCholesky::Summary& SparseCholesky::summary() const { return impl_->summary; }

}  // namespace hc::fem
