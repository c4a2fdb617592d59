#include "lm.h"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <optional>
#include <random>
#include <vector>

#include "processing/fem/sparse_cholesky.h"

namespace hc::material::detail {

namespace {

// The step of one LM attempt and the model's predicted cost decrease.
struct Step {
  Eigen::VectorXd delta;
  double predicted = 0;
  int cg_iterations = 0;
  bool ok = false;
};

// Everything an iteration needs at the current point, for either path.
class Linearization {
 public:
  virtual ~Linearization() = default;
  // Solves (JᵀJ + RᵀR + μ D) δ = −g.
  virtual Status solve(double mu, Step* step) = 0;
  const Eigen::VectorXd& gradient() const { return g_; }
  const Eigen::VectorXd& scaling() const { return diag_; }

 protected:
  Eigen::VectorXd g_;     // Jᵀ r + Rᵀ (R q − b)
  Eigen::VectorXd diag_;  // Marquardt scaling D: diag(JᵀJ + RᵀR), floored
};

void floor_diagonal(Eigen::VectorXd* diag) {
  const double floor = 1e-12 * std::max(diag->maxCoeff(), 1e-300);
  *diag = diag->cwiseMax(floor);
}

class DenseLinearization final : public Linearization {
 public:
  DenseLinearization(Eigen::MatrixXd j, const Eigen::VectorXd& r, const Eigen::SparseMatrix<double>& rtr,
                     const Eigen::VectorXd& reg_gradient) {
    const Eigen::Index n = j.cols();
    g_ = j.transpose() * r;
    if (rtr.rows() > 0) g_ += reg_gradient;
    diag_ = j.colwise().squaredNorm().transpose();
    if (rtr.rows() > 0) diag_ += rtr.diagonal();
    floor_diagonal(&diag_);
    a_ = Eigen::MatrixXd::Zero(n, n);
    a_.selfadjointView<Eigen::Lower>().rankUpdate(j.transpose());
    a_.triangularView<Eigen::Upper>() = a_.transpose();
    if (rtr.rows() > 0) a_ += Eigen::MatrixXd(rtr);
  }
  Status solve(double mu, Step* step) override {
    Eigen::MatrixXd am = a_;
    am.diagonal() += mu * diag_;
    Eigen::LLT<Eigen::MatrixXd> llt(am);
    step->ok = llt.info() == Eigen::Success;
    if (!step->ok) return {};
    step->delta = llt.solve(-g_);
    step->predicted = -step->delta.dot(g_) + mu * step->delta.dot(diag_.cwiseProduct(step->delta));
    return {};
  }

 private:
  Eigen::MatrixXd a_;  // JᵀJ + RᵀR
};

// Matrix-free: preconditioned CG on the normal equations, J v and Jᵀ w by the operator. The
// preconditioner approximates JᵀJ + RᵀR + μ D by M = B + RᵀR + μ D, with B JᵀJ's diagonal blocks
// estimated from a Gaussian sketch: for W with k columns of N(0, 1/k), E[Jᵀ W Wᵀ J] = JᵀJ, so the
// blocks of (Jᵀ W)(Jᵀ W)ᵀ estimate those of JᵀJ from k adjoint products (one
// multi-right-hand-side solve). RᵀR is kept whole (M sparse, factorised by CHOLMOD) where that
// pays: the regulariser is a squared Laplacian, whose smooth modes block-Jacobi (RᵀR's diagonal
// blocks only) leaves to CG. The noise-study block's joint fit (1,536 tets x 24 examples) averaged
// 357 CG iterations per LM step against the cap of 400 with block-Jacobi, 10 with M.
//
// Whether M pays is decided once per LM run (its pattern does not change, so neither does its
// ordering and symbolic analysis, which cost more than a numeric factorisation): when the factor's
// flops, estimated as nnz(L)² / n, stay below kSavedProducts normal products (each a J v and a
// Jᵀ w). One example's fit (products of two small solves, a regulariser of wide vertex stencil:
// 1.6M factor entries on 3,072 parameters) gives a coarse space instead (LmProblem::coarse):
// block-Jacobi then handles the rough modes and an exact solve on the coarse space the smooth
// ones, an additive two-level preconditioner, B + RᵀR + μ D projected on the coarse space and
// factorised per LM trial.
constexpr double kSavedProducts = 50;
// How much fewer factor entries the best ordering is assumed to find than AMD, at most. The joint
// fit's M: 1.8x at 3,000 tets, 3.2x at 10,000 (AMD 8.77e7, nested dissection 2.75e7 on 39,984
// parameters). At 2 the 10,000-tet joint fit was refused M on AMD's count although the best
// ordering's was within the budget, and took 5,863 CG iterations (759 s) instead of 419 (122 s).
constexpr double kBestOrderingGain = 4;
struct Preconditioner {
  fem::SparseCholesky cholesky;   // analysed for M's pattern when whole_reg holds true
  std::optional<bool> whole_reg;  // empty: not decided yet
  // The coarse space (none: nullptr), its coarse matrix and that matrix's factor (analysed at its
  // first use).
  const CoarseSpace* coarse = nullptr;
  fem::SparseMatrix coarse_upper;
  fem::SparseCholesky coarse_cholesky;
};

class MatrixFreeLinearization final : public Linearization {
 public:
  static Result<std::unique_ptr<MatrixFreeLinearization>> create(
      std::unique_ptr<JacobianOperator> op, const Eigen::VectorXd& r,
      const Eigen::SparseMatrix<double>& reg, const Eigen::SparseMatrix<double>& rtr,
      const Eigen::MatrixXd& reg_blocks,
      const std::function<void(const Eigen::VectorXd&, Eigen::VectorXd*)>& reg_normal_product,
      const Eigen::VectorXd& reg_gradient, int block, const LmSettings& settings,
      double product_flops, Preconditioner* preconditioner, std::mt19937_64* rng, double g0_norm) {
    auto l = std::unique_ptr<MatrixFreeLinearization>(new MatrixFreeLinearization());
    l->op_ = std::move(op);
    l->reg_ = &reg;
    l->rtr_ = &rtr;
    l->normal_product_ = &reg_normal_product;
    l->block_ = block;
    l->preconditioner_ = preconditioner;
    l->settings_ = settings;
    Eigen::MatrixXd jtr;
    HC_RETURN_IF_ERROR(l->op_->apply_transpose(r, &jtr));
    l->g_ = jtr.col(0);
    if (reg.rows() > 0) l->g_ += reg_gradient;
    const Eigen::Index n = l->g_.size();
    const int k = std::max(1, settings.sketch_size);
    std::normal_distribution<double> normal(0.0, 1.0 / std::sqrt(static_cast<double>(k)));
    Eigen::MatrixXd w(r.size(), k);
    for (Eigen::Index c = 0; c < k; ++c)
      for (Eigen::Index i = 0; i < r.size(); ++i) w(i, c) = normal(*rng);
    Eigen::MatrixXd y;
    HC_RETURN_IF_ERROR(l->op_->apply_transpose(w, &y));
    const Eigen::Index blocks = n / block;
    l->jtj_blocks_.resize(n, block);
    for (Eigen::Index e = 0; e < blocks; ++e) {
      const auto ye = y.middleRows(e * block, block);
      l->jtj_blocks_.middleRows(e * block, block) = ye * ye.transpose();
    }
    if (preconditioner->coarse) l->b_blocks_ = l->jtj_blocks_;
    if (reg.rows() > 0) l->jtj_blocks_ += reg_blocks;
    l->diag_.resize(n);
    for (Eigen::Index i = 0; i < n; ++i) l->diag_(i) = l->jtj_blocks_(i, i % block);
    floor_diagonal(&l->diag_);
    // With a coarse space, RᵀR is not tried whole: for the per-example fits, whose products are
    // two small FEM solves, M's factor was refused at every size measured (1,800-10,000 tets),
    // and building M and its AMD count alone took 0.2 s per example at 10,000 tets (~13 % of the
    // per-example phase, BM_FitScaling/9996/0).
    if (preconditioner->coarse) preconditioner->whole_reg = false;
    const double budget = kSavedProducts * 2 * product_flops;
    const auto flops = [n](double entries) { return entries * entries / static_cast<double>(n); };
    if (!preconditioner->whole_reg && rtr.rows() > 0) {
      // nnz(M)² / n bounds the factor's flops from below (M's upper triangle: the blocks, and
      // RᵀR's entries outside them), counted before M is built: one example's fit at 3,000 tets
      // built M's 0.70M entries only to find them past the budget.
      double entries = static_cast<double>(blocks * block * (block + 1) / 2);
      for (Eigen::Index c = 0; c < rtr.outerSize(); ++c)
        for (Eigen::SparseMatrix<double>::InnerIterator it(rtr, c); it; ++it)
          if (it.row() < it.col() && it.row() / block != it.col() / block) entries += 1;
      if (flops(entries) > budget) preconditioner->whole_reg = false;
    }
    if (preconditioner->whole_reg.value_or(true) && rtr.rows() > 0) {
      // M's upper triangle: the blocks, and RᵀR's entries outside them.
      std::vector<Eigen::Triplet<double, int>> trip;
      for (Eigen::Index i = 0; i < n; ++i)
        for (Eigen::Index c = i % block; c < block; ++c)
          trip.emplace_back(static_cast<int>(i), static_cast<int>(i - i % block + c),
                            l->jtj_blocks_(i, c));
      for (Eigen::Index c = 0; c < rtr.outerSize(); ++c)
        for (Eigen::SparseMatrix<double>::InnerIterator it(rtr, c); it; ++it)
          if (it.row() < it.col() && it.row() / block != it.col() / block)
            trip.emplace_back(static_cast<int>(it.row()), static_cast<int>(it.col()), it.value());
      l->whole_.resize(n, n);
      l->whole_.setFromTriplets(trip.begin(), trip.end());
      l->whole_.makeCompressed();
      if (!preconditioner->whole_reg) {
        // Within the bound above, AMD's fill, an upper bound of the best ordering's (which is
        // seldom better by more than kBestOrderingGain in entries): only between the two is the
        // full analysis (AMD, METIS and nested dissection, 2 s on the 19,992 parameters of a
        // 10,000-tet example, once per example) run.
        fem::SparseCholesky amd(fem::SparseCholesky::Options{.amd_only = true});
        HC_RETURN_IF_ERROR(amd.analyze(l->whole_));
        bool whole = flops(amd.summary().nnz_factor / kBestOrderingGain) <= budget;
        if (whole) {
          HC_RETURN_IF_ERROR(preconditioner->cholesky.analyze(l->whole_));
          whole = flops(preconditioner->cholesky.summary().nnz_factor) <= budget;
        }
        preconditioner->whole_reg = whole;
      }
    }
    // Inexact Gauss–Newton: a loose CG tolerance while far from the minimum, tightening as the
    // gradient falls (Eisenstat–Walker's choice 2 in spirit: η = √(‖g‖/‖g₀‖), at most 0.1).
    const double ratio = g0_norm > 0 ? l->g_.norm() / g0_norm : 1.0;
    l->eta_ = std::clamp(std::sqrt(ratio), settings.cg_relative_tolerance, 0.1);
    return l;
  }

  Status solve(double mu, Step* step) override {
    const Eigen::Index n = g_.size();
    std::function<Eigen::VectorXd(const Eigen::VectorXd&)> precondition;
    bool factored = false;
    Eigen::VectorXd solved;
    if (preconditioner_->whole_reg.value_or(false)) {
      fem::SparseMatrix m = whole_;
      for (Eigen::Index i = 0; i < n; ++i) m.coeffRef(i, i) += mu * diag_(i);
      // M is SPD in exact arithmetic; should rounding break that, block-Jacobi takes over.
      factored = preconditioner_->cholesky.factorize(m).ok();
    }
    if (factored) {
      precondition = [&](const Eigen::VectorXd& v) -> Eigen::VectorXd {
        return preconditioner_->cholesky.solve(v, &solved).ok() ? solved : v;
      };
    } else if (preconditioner_->coarse && factor_coarse(mu).ok()) {
      // Additive two-level: block-Jacobi plus the coarse correction P (Pᵀ M P)⁻¹ Pᵀ.
      const auto smooth = block_jacobi(mu);
      const Eigen::SparseMatrix<double>& p = preconditioner_->coarse->p();
      precondition = [&, smooth](const Eigen::VectorXd& v) -> Eigen::VectorXd {
        Eigen::VectorXd z = smooth(v), y;
        if (preconditioner_->coarse_cholesky.solve(Eigen::VectorXd(p.transpose() * v), &y).ok())
          z += p * y;
        return z;
      };
    } else {
      precondition = block_jacobi(mu);
    }
    Eigen::VectorXd jv, jtjv;
    const auto normal = [&](const Eigen::VectorXd& v, Eigen::VectorXd* out) -> Status {
      HC_RETURN_IF_ERROR(op_->apply(v, &jv));
      Eigen::MatrixXd t;
      HC_RETURN_IF_ERROR(op_->apply_transpose(jv, &t));
      *out = t.col(0) + mu * diag_.cwiseProduct(v);
      if (reg_->rows() > 0) *out += regularizer_product(v);
      return {};
    };
    Eigen::VectorXd x = Eigen::VectorXd::Zero(n), res = -g_;
    Eigen::VectorXd z = precondition(res), p = z, ap;
    double rz = res.dot(z);
    const double stop = eta_ * g_.norm();
    int it = 0;
    for (; it < settings_.cg_max_iterations && res.norm() > stop; ++it) {
      HC_RETURN_IF_ERROR(normal(p, &ap));
      const double pap = p.dot(ap);
      if (!(pap > 0)) break;  // numerically singular direction: keep what we have
      const double alpha = rz / pap;
      x += alpha * p;
      res -= alpha * ap;
      z = precondition(res);
      const double rz_new = res.dot(z);
      p = z + (rz_new / rz) * p;
      rz = rz_new;
    }
    step->cg_iterations = it;
    step->ok = x.allFinite() && x.squaredNorm() > 0;
    if (!step->ok) return {};
    step->delta = x;
    // The model's decrease −(2 gᵀδ + δᵀ (JᵀJ + RᵀR) δ), exact also for an inexact CG solution.
    HC_RETURN_IF_ERROR(op_->apply(x, &jv));
    double quad = jv.squaredNorm();
    if (reg_->rows() > 0) quad += x.dot(regularizer_product(x));
    step->predicted = -(2 * g_.dot(x) + quad);
    return {};
  }

 private:
  MatrixFreeLinearization() = default;
  // The inverses of (B + RᵀR's diagonal blocks + μ D)'s blocks, applied.
  std::function<Eigen::VectorXd(const Eigen::VectorXd&)> block_jacobi(double mu) const {
    const Eigen::Index n = g_.size();
    const Eigen::Index blocks = n / block_;
    // The inverses stacked (n × block), applied without a temporary per block.
    auto inv = std::make_shared<Eigen::MatrixXd>(n, block_);
    for (Eigen::Index e = 0; e < blocks; ++e) {
      Eigen::MatrixXd m = jtj_blocks_.middleRows(e * block_, block_);
      for (int a = 0; a < block_; ++a) m(a, a) += mu * diag_(e * block_ + a);
      Eigen::LLT<Eigen::MatrixXd> llt(m);
      inv->middleRows(e * block_, block_) =
          llt.info() == Eigen::Success
              ? Eigen::MatrixXd(llt.solve(Eigen::MatrixXd::Identity(block_, block_)))
              : Eigen::MatrixXd(m.diagonal().cwiseMax(1e-300).cwiseInverse().asDiagonal());
    }
    const int block = block_;
    return [inv, blocks, block, n](const Eigen::VectorXd& v) {
      Eigen::VectorXd out(n);
      for (Eigen::Index e = 0; e < blocks; ++e)
        for (int a = 0; a < block; ++a)
          out(e * block + a) = inv->row(e * block + a).dot(v.segment(e * block, block));
      return out;
    };
  }

  // Factorises the coarse matrix Pᵀ M P = Pᵀ RᵀR P + Pᵀ (B + μ D) P, B the estimated diagonal
  // blocks of JᵀJ. Its pattern is the same at every call (the blocks are stored whole), as the
  // analysis needs.
  Status factor_coarse(double mu) const {
    Eigen::MatrixXd x = b_blocks_;
    for (Eigen::Index i = 0; i < x.rows(); ++i) x(i, i % block_) += mu * diag_(i);
    fem::SparseMatrix& upper = preconditioner_->coarse_upper;
    preconditioner_->coarse->assemble(x, &upper);
    fem::SparseCholesky& chol = preconditioner_->coarse_cholesky;
    if (!chol.analyzed()) HC_RETURN_IF_ERROR(chol.analyze(upper));
    return chol.factorize(upper);
  }

  // RᵀR v: by the problem's own product where it has one (the per-example fit's Laplacian,
  // fit.cpp); else Rᵀ (R v) where that at least halves the entries read (RᵀR has 4x R's): a vertex
  // stencil's RᵀR couples every element within two vertex rings (10,000 tets: its product was a
  // third of the per-example fits' time). Elsewhere RᵀR (2.4-3.9x R's entries in the tests and
  // the noise study), whose products the matrix-free and dense fits were checked to agree with.
  Eigen::VectorXd regularizer_product(const Eigen::VectorXd& v) const {
    if (*normal_product_) {
      Eigen::VectorXd out;
      (*normal_product_)(v, &out);
      return out;
    }
    if (4 * reg_->nonZeros() <= rtr_->nonZeros()) return reg_->transpose() * (*reg_ * v);
    return *rtr_ * v;
  }

  std::unique_ptr<JacobianOperator> op_;
  const Eigen::SparseMatrix<double>* reg_ = nullptr;  // R
  const Eigen::SparseMatrix<double>* rtr_ = nullptr;  // RᵀR (empty where not needed)
  const std::function<void(const Eigen::VectorXd&, Eigen::VectorXd*)>* normal_product_ = nullptr;
  int block_ = 1;
  Preconditioner* preconditioner_ = nullptr;
  LmSettings settings_;
  Eigen::MatrixXd jtj_blocks_;  // n × block: B plus RᵀR's diagonal blocks
  Eigen::MatrixXd b_blocks_;    // n × block: B alone (kept for the coarse space)
  fem::SparseMatrix whole_;     // M's upper triangle without μ D (when RᵀR is kept whole)
  double eta_ = 0.1;
};

// See umbrella_normal_product: L V as a sum over neighbours, with no values to read, and one pass
// for both parameters. Per entry of L, Rᵀ (R v) reads two of R's (value and index, 12 bytes each)
// twice; this reads one 4-byte index twice, a sixth of the memory traffic. At 9,996 tets R's
// products were a quarter of the per-example fits' time (perf).
class UmbrellaNormalProduct {
 public:
  // Empty when `laplacian` is not of that form.
  static std::optional<UmbrellaNormalProduct> create(const Eigen::SparseMatrix<double>& laplacian,
                                                     double gamma, double prior) {
    UmbrellaNormalProduct p;
    p.gamma_ = gamma;
    p.prior_ = prior;
    const Eigen::Index t = laplacian.cols();
    p.degree_.resize(static_cast<std::size_t>(t), 0.0);
    p.start_.reserve(static_cast<std::size_t>(t) + 1);
    p.start_.push_back(0);
    // L is symmetric: column e lists row e's neighbours.
    for (Eigen::Index e = 0; e < t; ++e) {
      for (Eigen::SparseMatrix<double>::InnerIterator it(laplacian, e); it; ++it) {
        if (it.row() == e) {
          p.degree_[static_cast<std::size_t>(e)] = it.value();
        } else if (it.value() == -1.0) {
          p.neighbours_.push_back(static_cast<int>(it.row()));
        } else {
          return std::nullopt;
        }
      }
      p.start_.push_back(static_cast<int>(p.neighbours_.size()));
    }
    return p;
  }

  void operator()(const Eigen::VectorXd& v, Eigen::VectorXd* out) const {
    out->setZero(v.size());
    if (gamma_ > 0) {
      Eigen::VectorXd lv(v.size());
      apply_laplacian(v, &lv);
      apply_laplacian(lv, out);
      *out *= gamma_;
    }
    if (prior_ > 0)
      for (Eigen::Index e = 1; e < v.size(); e += 2) (*out)(e) += prior_ * v(e);
  }

 private:
  // out = (L ⊗ I₂) v, v interleaved (two parameters per element).
  void apply_laplacian(const Eigen::VectorXd& v, Eigen::VectorXd* out) const {
    for (std::size_t e = 0; e < degree_.size(); ++e) {
      double a = degree_[e] * v(static_cast<Eigen::Index>(2 * e));
      double b = degree_[e] * v(static_cast<Eigen::Index>(2 * e + 1));
      for (int k = start_[e]; k < start_[e + 1]; ++k) {
        const auto f = static_cast<Eigen::Index>(neighbours_[static_cast<std::size_t>(k)]);
        a -= v(2 * f);
        b -= v(2 * f + 1);
      }
      (*out)(static_cast<Eigen::Index>(2 * e)) = a;
      (*out)(static_cast<Eigen::Index>(2 * e + 1)) = b;
    }
  }

  double gamma_ = 0, prior_ = 0;
  std::vector<double> degree_;
  std::vector<int> start_, neighbours_;
};

}  // namespace

std::function<void(const Eigen::VectorXd&, Eigen::VectorXd*)> umbrella_normal_product(
    const Eigen::SparseMatrix<double>& laplacian, double gamma, double prior) {
  auto product = UmbrellaNormalProduct::create(laplacian, gamma, prior);
  if (!product) return {};
  return [p = std::move(*product)](const Eigen::VectorXd& v, Eigen::VectorXd* out) { p(v, out); };
}

Eigen::SparseMatrix<double> neighbourhood(const Eigen::SparseMatrix<double>& a, int rings) {
  Eigen::SparseMatrix<double> step = a.cwiseAbs();
  for (Eigen::Index i = 0; i < step.rows(); ++i) step.coeffRef(i, i) = 1;
  Eigen::SparseMatrix<double> out = step;
  for (int r = 1; r < rings; ++r) out = out * step;
  for (Eigen::Index k = 0; k < out.outerSize(); ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(out, k); it; ++it) it.valueRef() = 1;
  return out;
}

CoarseSpace::CoarseSpace(const Eigen::SparseMatrix<double>& basis,
                         const Eigen::SparseMatrix<double>& reg, int block)
    : b_(block) {
  const int b = block;
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(static_cast<std::size_t>(basis.nonZeros() * b));
  for (Eigen::Index k = 0; k < basis.outerSize(); ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(basis, k); it; ++it)
      for (int a = 0; a < b; ++a)
        trip.emplace_back(static_cast<int>(it.row() * b + a), static_cast<int>(it.col() * b + a),
                          it.value());
  p_.resize(basis.rows() * b, basis.cols() * b);
  p_.setFromTriplets(trip.begin(), trip.end());
  const Eigen::SparseMatrix<double> rp = reg * p_;
  const Eigen::SparseMatrix<double> coarse_reg = rp.transpose() * rp;
  using RowMajor = Eigen::SparseMatrix<double, Eigen::RowMajor>;
  const RowMajor by_element = basis;
  const Eigen::Index m = basis.cols(), n = m * b;
  // Block column k at a time (a symbolic sparse product): its block rows j <= k are the
  // functions sharing an element with k and Pᵀ RᵀR P's blocks; column k b + c then holds rows
  // j b .. j b + b - 1 of each j < k and k b .. k b + c (upper triangle).
  std::vector<Eigen::Index> mark(static_cast<std::size_t>(m), -1);
  std::vector<int> local(static_cast<std::size_t>(m), 0), block_rows;
  std::vector<int> outer(static_cast<std::size_t>(n) + 1, 0), inner;
  std::vector<double> reg_values;
  const auto add_block_row = [&](Eigen::Index j, Eigen::Index k) {
    if (mark[static_cast<std::size_t>(j)] == k) return;
    mark[static_cast<std::size_t>(j)] = k;
    block_rows.push_back(static_cast<int>(j));
  };
  for (Eigen::Index k = 0; k < m; ++k) {
    block_rows.clear();
    for (Eigen::SparseMatrix<double>::InnerIterator e(basis, k); e; ++e)
      for (RowMajor::InnerIterator j(by_element, e.row()); j && j.col() <= k; ++j)
        add_block_row(j.col(), k);
    for (int c = 0; c < b; ++c)
      for (Eigen::SparseMatrix<double>::InnerIterator it(coarse_reg, k * b + c); it; ++it)
        if (it.row() / b <= k) add_block_row(it.row() / b, k);
    std::sort(block_rows.begin(), block_rows.end());
    for (std::size_t q = 0; q < block_rows.size(); ++q)
      local[static_cast<std::size_t>(block_rows[q])] = b * static_cast<int>(q);
    for (int c = 0; c < b; ++c) {
      for (const int j : block_rows)
        for (int a = 0; a < (j == k ? c + 1 : b); ++a) inner.push_back(j * b + a);
      outer[static_cast<std::size_t>(k * b + c) + 1] = static_cast<int>(inner.size());
    }
    reg_values.resize(inner.size(), 0.0);
    for (int c = 0; c < b; ++c)
      for (Eigen::SparseMatrix<double>::InnerIterator it(coarse_reg, k * b + c); it; ++it)
        if (it.row() <= k * b + c)
          reg_values[static_cast<std::size_t>(outer[static_cast<std::size_t>(k * b + c)] +
                                              local[static_cast<std::size_t>(it.row() / b)] +
                                              it.row() % b)] += it.value();
    for (Eigen::SparseMatrix<double>::InnerIterator e(basis, k); e; ++e)
      for (RowMajor::InnerIterator j(by_element, e.row()); j && j.col() <= k; ++j)
        terms_.push_back({static_cast<int>(e.row()), static_cast<int>(k),
                          local[static_cast<std::size_t>(j.col())], j.col() == k,
                          j.value() * e.value()});
  }
  upper_ = Eigen::Map<const fem::SparseMatrix>(n, n, static_cast<Eigen::Index>(inner.size()),
                                               outer.data(), inner.data(), reg_values.data());
  reg_values_ = Eigen::Map<const Eigen::VectorXd>(reg_values.data(),
                                                  static_cast<Eigen::Index>(reg_values.size()));
}

void CoarseSpace::assemble(const Eigen::MatrixXd& x, fem::SparseMatrix* upper) const {
  if (upper->nonZeros() != upper_.nonZeros()) *upper = upper_;
  Eigen::Map<Eigen::VectorXd>(upper->valuePtr(), upper->nonZeros()) = reg_values_;
  double* values = upper->valuePtr();
  const int* outer = upper->outerIndexPtr();
  for (const Term& t : terms_)
    for (int c = 0; c < b_; ++c) {
      double* column = values + outer[t.k * b_ + c] + t.offset;
      for (int a = 0; a < (t.diagonal ? c + 1 : b_); ++a)
        column[a] += t.weight * x(t.element * b_ + a, c);
    }
}

Eigen::SparseMatrix<double> smoothed_aggregation_basis(
    const Eigen::SparseMatrix<double>& graph, const Eigen::SparseMatrix<double>& laplacian) {
  const Eigen::Index n = graph.cols();
  std::vector<int> aggregate(static_cast<std::size_t>(n), -1);
  const auto each_neighbour = [&](Eigen::Index e, auto&& f) {
    for (Eigen::SparseMatrix<double>::InnerIterator it(graph, e); it; ++it)
      if (it.row() != e) f(static_cast<std::size_t>(it.row()));
  };
  int count = 0;
  // An element whose neighbours are all free is a root: it and they make an aggregate.
  for (Eigen::Index e = 0; e < n; ++e) {
    if (aggregate[static_cast<std::size_t>(e)] >= 0) continue;
    bool free = true;
    each_neighbour(e, [&](std::size_t f) { free = free && aggregate[f] < 0; });
    if (!free) continue;
    aggregate[static_cast<std::size_t>(e)] = count;
    each_neighbour(e, [&](std::size_t f) { aggregate[f] = count; });
    ++count;
  }
  // The rest join a neighbour's aggregate of the first pass, or (none near) make their own.
  std::vector<int> joined = aggregate;
  for (Eigen::Index e = 0; e < n; ++e) {
    int& mine = joined[static_cast<std::size_t>(e)];
    if (mine >= 0) continue;
    each_neighbour(e, [&](std::size_t f) {
      if (mine < 0) mine = aggregate[f];
    });
    if (mine < 0) mine = count++;
  }
  Eigen::SparseMatrix<double> indicator(n, count);
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(static_cast<std::size_t>(n));
  for (Eigen::Index e = 0; e < n; ++e)
    trip.emplace_back(static_cast<int>(e), joined[static_cast<std::size_t>(e)], 1.0);
  indicator.setFromTriplets(trip.begin(), trip.end());
  // ω = 1 (the textbook 4 / (3 ρ(D⁻¹ L)) is 2/3 for an umbrella Laplacian): measured better
  // (bench_material_fit BM_FitScaling/3000/0 with aggregates over L's own stencil: 144 against
  // 164 CG iterations per example).
  Eigen::SparseMatrix<double> smoother(n, n);
  smoother.setIdentity();
  smoother -= Eigen::SparseMatrix<double>(
      laplacian.diagonal().cwiseMax(1e-300).cwiseInverse().asDiagonal() * laplacian);
  return smoother * indicator;
}

LmSettings lm_settings(const ParameterFitOptions& options) {
  LmSettings s;
  s.max_iterations = options.max_iterations;
  s.function_tolerance = options.function_tolerance;
  s.parameter_tolerance = options.parameter_tolerance;
  s.cg_max_iterations = options.cg_max_iterations;
  s.cg_relative_tolerance = options.cg_relative_tolerance;
  s.sketch_size = options.sketch_size;
  return s;
}

bool prefer_dense(double m, double n, double factor_entries, double examples,
                  const ParameterFitOptions& options) {
  if (options.solver == FitSolver::kDense) return true;
  if (options.solver == FitSolver::kMatrixFree) return false;
  // Per LM iteration, in flops: dense forms J (min(m, n) solves per example), JᵀJ (m n²) and
  // factorises it (n³/3, ~1.5 attempts); matrix-free needs the sketch, the gradient and ~2 solves
  // per CG iteration (~60 observed) per example.
  const double solve = solve_flops(factor_entries);
  const double dense = examples * std::min(m / examples, n) * solve + m * n * n + 0.5 * n * n * n;
  const double free = examples * solve * (options.sketch_size + 2 + 2 * 60.0);
  const double dense_bytes = 8 * (m * n + 2 * n * n);
  return dense < free && dense_bytes <= options.max_dense_bytes;
}

void error_stats(const Eigen::VectorXd& r_m, double* rms, double* max) {
  const Eigen::Index nodes = r_m.size() / 3;
  double sum = 0, mx = 0;
  for (Eigen::Index i = 0; i < nodes; ++i) {
    const double d = r_m.segment<3>(3 * i).norm();
    sum += d * d;
    mx = std::max(mx, d);
  }
  *rms = nodes ? std::sqrt(sum / static_cast<double>(nodes)) : 0.0;
  *max = mx;
}

Status run_lm(const LmProblem& problem, const LmSettings& settings, Eigen::VectorXd* q,
              ParameterFitSummary* summary) {
  const bool has_reg = problem.reg.rows() > 0;
  const Eigen::SparseMatrix<double>& reg = problem.reg;
  const bool has_target = has_reg && problem.reg_target.size() == problem.reg.rows();
  const auto reg_residual = [&](const Eigen::VectorXd& v) -> Eigen::VectorXd {
    Eigen::VectorXd out = reg * v;
    if (has_target) out -= problem.reg_target;
    return out;
  };
  const auto reg_cost = [&](const Eigen::VectorXd& v) {
    return has_reg ? reg_residual(v).squaredNorm() : 0.0;
  };
  std::mt19937_64 rng(settings.seed);
  Preconditioner preconditioner;
  if (problem.matrix_free && has_reg && problem.coarse && problem.coarse->p().rows() == reg.cols())
    preconditioner.coarse = problem.coarse.get();
  // RᵀR's diagonal blocks (the matrix-free preconditioner's), the dot products of R's columns;
  // RᵀR itself only where something reads
  // it: the dense path, a product without the problem's own, and the choice of the whole-RᵀR
  // preconditioner, which a coarse space skips (forming a vertex-stencil RᵀR took 15 % of the
  // per-example fits at 10,000 tets).
  const int block = problem.block;
  Eigen::MatrixXd reg_blocks;
  Eigen::SparseMatrix<double> rtr;
  if (has_reg && problem.matrix_free) {
    reg_blocks.setZero(reg.cols(), block);
    for (Eigen::Index i = 0; i < reg.cols(); ++i)
      for (int c = 0; c < block; ++c) reg_blocks(i, c) = reg.col(i).dot(reg.col(i - i % block + c));
  }
  if (has_reg && (!problem.matrix_free || !problem.reg_normal_product || !preconditioner.coarse))
    rtr = reg.transpose() * reg;
  ProgressTask task(problem.progress, problem.progress_task,
                    static_cast<std::uint64_t>(settings.max_iterations));

  Eigen::VectorXd r;
  HC_RETURN_IF_ERROR(problem.residual(*q, &r));
  double cost = r.squaredNorm() + reg_cost(*q);
  summary->initial_cost = cost;
  double mu = 1e-3, nu = 2;
  bool at_current = true;
  double g0_norm = 0;
  summary->message = "max iterations";
  summary->cg_iterations = 0;
  int it = 0;
  bool done = false;
  for (; it < settings.max_iterations && !done; ++it) {
    if (!at_current) HC_RETURN_IF_ERROR(problem.residual(*q, &r));
    at_current = true;
    const Eigen::VectorXd reg_gradient =
        has_reg ? Eigen::VectorXd(reg.transpose() * reg_residual(*q)) : Eigen::VectorXd();
    std::unique_ptr<Linearization> lin;
    if (problem.matrix_free) {
      HC_ASSIGN_OR_RETURN(std::unique_ptr<JacobianOperator> op, problem.jacobian_operator(*q));
      HC_ASSIGN_OR_RETURN(
          lin, MatrixFreeLinearization::create(
                   std::move(op), r, reg, rtr, reg_blocks, problem.reg_normal_product, reg_gradient,
                   block, settings, problem.product_flops, &preconditioner, &rng, g0_norm));
    } else {
      Eigen::MatrixXd j;
      HC_RETURN_IF_ERROR(problem.jacobian(*q, &j));
      lin = std::make_unique<DenseLinearization>(std::move(j), r, rtr, reg_gradient);
    }
    if (it == 0) g0_norm = lin->gradient().norm();
    bool accepted = false;
    for (int attempt = 0; attempt < 30 && !accepted; ++attempt) {
      // A rejected trial left the FEM models at the trial point; the operator solves with the
      // factorisation at q.
      if (problem.matrix_free && !at_current) {
        HC_RETURN_IF_ERROR(problem.residual(*q, &r));
        at_current = true;
      }
      Step step;
      HC_RETURN_IF_ERROR(lin->solve(mu, &step));
      summary->cg_iterations += step.cg_iterations;
      if (!step.ok) {
        mu *= nu;
        nu *= 2;
        continue;
      }
      const Eigen::VectorXd trial = *q + step.delta;
      Eigen::VectorXd r_trial;
      const Status st = problem.residual(trial, &r_trial);
      at_current = false;
      const double cost_trial = st.ok() ? r_trial.squaredNorm() + reg_cost(trial) : INFINITY;
      const double rho = (cost - cost_trial) / std::max(step.predicted, 1e-300);
      if (st.ok() && cost_trial < cost) {
        const double decrease = (cost - cost_trial) / std::max(cost, 1e-300);
        const bool small_step = step.delta.norm() <= settings.parameter_tolerance *
                                                         (q->norm() + settings.parameter_tolerance);
        *q = trial;
        r = r_trial;
        cost = cost_trial;
        at_current = true;
        accepted = true;
        mu *= std::max(1.0 / 3.0, 1.0 - std::pow(2 * rho - 1, 3));
        nu = 2;
        if (decrease < settings.function_tolerance) {
          summary->message = "function tolerance";
          done = true;
        } else if (small_step) {
          summary->message = "parameter tolerance";
          done = true;
        }
      } else {
        mu *= nu;
        nu *= 2;
      }
    }
    task.advance();
    if (!accepted) {
      summary->message = "no decrease found (converged to machine precision)";
      break;
    }
  }
  summary->iterations = it;
  if (!at_current) HC_RETURN_IF_ERROR(problem.residual(*q, &r));
  summary->final_cost = cost;
  summary->usable = std::isfinite(cost);
  summary->matrix_free = problem.matrix_free;
  return {};
}

}  // namespace hc::material::detail
