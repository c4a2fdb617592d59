#include "calibration/force/fsr_fit.h"

#include <ceres/ceres.h>
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

namespace hc::calib {
namespace {

// Keeps (x - threshold) away from 0 so that pow() and its derivative stay finite.
constexpr double kMinNormalised = 1e-9;

// F_model(raw) - F_ref for the power law; p = {threshold, scale_n, exponent}.
struct PowerLawResidual {
  PowerLawResidual(double x, double f) : x_(x), f_(f) {}
  template <typename T>
  bool operator()(const T* p, T* r) const {
    using std::pow;
    T u = (T(x_) - p[0]) / (T(1.0) - p[0]);
    if (u < T(kMinNormalised)) u = T(kMinNormalised);
    r[0] = p[1] * pow(u, p[2]) - T(f_);
    return true;
  }
  double x_, f_;
};

// F_model(raw) - F_ref for the monotone piecewise-linear curve; p = {f0, d1, ..., dK-1} with the
// increments d >= 0 (bounds), so the knot forces f0 + d1 + ... + dk never decrease.
struct PiecewiseResidual {
  PiecewiseResidual(const std::vector<double>* knots, double raw, double f)
      : knots_(knots), raw_(raw), f_(f) {}
  template <typename T>
  bool operator()(T const* const* params, T* r) const {
    const T* p = params[0];
    const std::vector<double>& k = *knots_;
    const std::size_t n = k.size();
    // Segment [k[s], k[s+1]] containing raw (end segments extrapolate).
    std::size_t s = 0;
    while (s + 2 < n && raw_ > k[s + 1]) ++s;
    T f_s = p[0];
    for (std::size_t i = 1; i <= s; ++i) f_s += p[i];
    const double w = (raw_ - k[s]) / (k[s + 1] - k[s]);
    r[0] = f_s + T(w) * p[s + 1] - T(f_);
    return true;
  }
  const std::vector<double>* knots_;
  double raw_, f_;
};

FsrFitQuality quality_of(const std::vector<FsrPair>& pairs, int k,
                         const std::function<double(double)>& model) {
  FsrFitQuality q;
  q.parameters = k;
  double mean = 0.0;
  for (const FsrPair& p : pairs) mean += p.force_n;
  mean /= static_cast<double>(pairs.size());
  double rss = 0.0, tss = 0.0;
  for (const FsrPair& p : pairs) {
    const double e = model(p.raw) - p.force_n;
    rss += e * e;
    tss += (p.force_n - mean) * (p.force_n - mean);
    q.max_abs_n = std::max(q.max_abs_n, std::abs(e));
  }
  const double n = static_cast<double>(pairs.size());
  q.rms_n = std::sqrt(rss / n);
  q.r2 = tss > 0.0 ? 1.0 - rss / tss : 0.0;
  q.bic = n * std::log(std::max(rss / n, 1e-300)) + k * std::log(n);
  return q;
}

// Initial power law: for thresholds on a grid below the smallest loaded reading, a straight line
// through log F = log s + e log u; keep the one with the least force-space RSS.
FsrPowerLaw initial_power_law(const std::vector<FsrPair>& pairs, double full_scale) {
  double x_min = std::numeric_limits<double>::infinity();
  for (const FsrPair& p : pairs) x_min = std::min(x_min, p.raw / full_scale);
  FsrPowerLaw best;
  best.full_scale = full_scale;
  double best_rss = std::numeric_limits<double>::infinity();
  constexpr int kGrid = 60;
  for (int g = 0; g < kGrid; ++g) {
    const double th = std::max(0.0, x_min) * (static_cast<double>(g) / kGrid);
    if (th >= 1.0) break;
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    int m = 0;
    for (const FsrPair& p : pairs) {
      const double u = (p.raw / full_scale - th) / (1.0 - th);
      if (!(u > 0.0) || !(p.force_n > 0.0)) continue;
      const double lx = std::log(u), ly = std::log(p.force_n);
      sx += lx, sy += ly, sxx += lx * lx, sxy += lx * ly, ++m;
    }
    if (m < 3) continue;
    const double den = m * sxx - sx * sx;
    if (!(std::abs(den) > 0.0)) continue;
    const double e = (m * sxy - sx * sy) / den;
    const double ls = (sy - e * sx) / m;
    if (!(e > 0.0) || !std::isfinite(ls)) continue;
    FsrPowerLaw c{full_scale, th, std::exp(ls), e};
    double rss = 0.0;
    for (const FsrPair& p : pairs) {
      const double r = c.to_newtons(p.raw) - p.force_n;
      rss += r * r;
    }
    if (rss < best_rss) best_rss = rss, best = c;
  }
  return best;
}

}  // namespace

double FsrPowerLaw::to_newtons(double raw) const {
  if (!(full_scale > 0.0) || !(threshold < 1.0)) return 0.0;
  const double x = raw / full_scale;
  if (!(x > threshold)) return 0.0;
  return scale_n * std::pow((x - threshold) / (1.0 - threshold), exponent);
}

double FsrPiecewiseLinear::to_newtons(double r) const {
  const std::size_t n = raw.size();
  if (n < 2 || force_n.size() != n) return 0.0;
  std::size_t s = 0;
  while (s + 2 < n && r > raw[s + 1]) ++s;
  const double w = (r - raw[s]) / (raw[s + 1] - raw[s]);
  return std::max(0.0, force_n[s] + w * (force_n[s + 1] - force_n[s]));
}

std::string_view to_string(FsrModel model) {
  return model == FsrModel::kPowerLaw ? "power_law" : "piecewise_linear";
}

Json FsrFitQuality::to_json() const {
  return Json{{"rms_n", rms_n},
              {"max_abs_n", max_abs_n},
              {"r2", r2},
              {"bic", bic},
              {"parameters", parameters},
              {"iterations", iterations},
              {"converged", converged}};
}

double FsrCurve::to_newtons(double raw) const {
  return model == FsrModel::kPowerLaw ? power_law.to_newtons(raw) : piecewise.to_newtons(raw);
}

Status FsrFitOptions::validate() const {
  if (!(full_scale > 0.0) || !std::isfinite(full_scale))
    return invalid_argument("full_scale must be > 0");
  if (!(min_force_n >= 0.0) || !std::isfinite(min_force_n))
    return invalid_argument("min_force_n must be >= 0");
  if (knots < 2) return invalid_argument("knots must be >= 2");
  if (max_iterations < 1) return invalid_argument("max_iterations must be >= 1");
  if (min_pairs < 4) return invalid_argument("min_pairs must be >= 4");
  return {};
}

Result<FsrCurve> fit_fsr(const std::vector<FsrPair>& pairs, const FsrFitOptions& options,
                         FsrFitSummary* summary) {
  const auto start = std::chrono::steady_clock::now();
  HC_RETURN_IF_ERROR(options.validate());
  std::vector<FsrPair> loaded;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const FsrPair& p = pairs[i];
    if (!std::isfinite(p.raw) || !std::isfinite(p.force_n))
      return invalid_argument(fmt::format("pair {}: raw or force is not finite", i));
    if (p.force_n >= options.min_force_n) loaded.push_back(p);
  }
  if (loaded.size() < static_cast<std::size_t>(options.min_pairs))
    return failed_precondition(fmt::format(
        "{} of {} pairs have a reference force >= {} N; need at least {} to fit the FSR",
        loaded.size(), pairs.size(), options.min_force_n, options.min_pairs));
  const auto [lo, hi] =
      std::minmax_element(loaded.begin(), loaded.end(),
                          [](const FsrPair& a, const FsrPair& b) { return a.raw < b.raw; });
  if (!(hi->raw > lo->raw))
    return failed_precondition(fmt::format(
        "the FSR reads {} for every loaded pair: its response cannot be fitted", lo->raw));

  FsrCurve curve;
  curve.pairs = loaded.size();
  const double fs = options.full_scale;
  const double x_min = lo->raw / fs;

  // ---- Power law ----
  FsrPowerLaw init = initial_power_law(loaded, fs);
  double p[3] = {init.threshold, init.scale_n, init.exponent};
  ceres::Problem problem;
  for (const FsrPair& q : loaded)
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<PowerLawResidual, 1, 3>(
                                 new PowerLawResidual(q.raw / fs, q.force_n)),
                             nullptr, p);
  // threshold below every loaded reading (they all read force > 0), scale and exponent positive.
  problem.SetParameterLowerBound(p, 0, 0.0);
  problem.SetParameterUpperBound(p, 0, std::max(0.0, x_min - 1e-6));
  problem.SetParameterLowerBound(p, 1, 1e-9);
  problem.SetParameterLowerBound(p, 2, 1e-3);
  problem.SetParameterUpperBound(p, 2, 50.0);
  ceres::Solver::Options so;
  so.max_num_iterations = options.max_iterations;
  so.linear_solver_type = ceres::DENSE_QR;
  so.function_tolerance = 1e-12;
  so.parameter_tolerance = 1e-12;
  so.gradient_tolerance = 1e-14;
  ceres::Solver::Summary ss;
  ceres::Solve(so, &problem, &ss);
  if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
    return failed_precondition("the power-law fit diverged: " + ss.BriefReport());
  curve.power_law = {fs, p[0], p[1], p[2]};
  curve.power_law_quality =
      quality_of(loaded, 3, [&](double r) { return curve.power_law.to_newtons(r); });
  curve.power_law_quality.iterations = static_cast<int>(ss.iterations.size());
  curve.power_law_quality.converged = ss.termination_type == ceres::CONVERGENCE;
  {
    ceres::Covariance::Options co;
    co.algorithm_type = ceres::DENSE_SVD;
    ceres::Covariance cov(co);
    std::vector<std::pair<const double*, const double*>> blocks{{p, p}};
    if (cov.Compute(blocks, &problem)) {
      double c[9];
      cov.GetCovarianceBlock(p, p, c);
      const double dof = std::max(1.0, static_cast<double>(loaded.size()) - 3.0);
      const double s2 = 2.0 * ss.final_cost / dof;
      curve.threshold_std = std::sqrt(std::max(0.0, c[0] * s2));
      curve.scale_n_std = std::sqrt(std::max(0.0, c[4] * s2));
      curve.exponent_std = std::sqrt(std::max(0.0, c[8] * s2));
    }
  }

  // ---- Monotone piecewise linear ----
  curve.model = FsrModel::kPowerLaw;
  if (options.fit_piecewise) {
    std::vector<double> raws;
    for (const FsrPair& q : loaded) raws.push_back(q.raw);
    std::sort(raws.begin(), raws.end());
    std::vector<double> knots;
    for (int k = 0; k < options.knots; ++k) {
      const double v = raws[static_cast<std::size_t>(
          std::llround(static_cast<double>(k) / (options.knots - 1) * (raws.size() - 1)))];
      if (knots.empty() || v > knots.back()) knots.push_back(v);
    }
    if (knots.size() >= 2) {
      const std::size_t k = knots.size();
      std::vector<double> q(k, 0.0);
      // Start from the power law at the knots.
      q[0] = curve.power_law.to_newtons(knots[0]);
      for (std::size_t i = 1; i < k; ++i)
        q[i] = std::max(
            0.0, curve.power_law.to_newtons(knots[i]) - curve.power_law.to_newtons(knots[i - 1]));
      ceres::Problem pw;
      for (const FsrPair& pr : loaded) {
        auto* cf = new ceres::DynamicAutoDiffCostFunction<PiecewiseResidual, 8>(
            new PiecewiseResidual(&knots, pr.raw, pr.force_n));
        cf->AddParameterBlock(static_cast<int>(k));
        cf->SetNumResiduals(1);
        pw.AddResidualBlock(cf, nullptr, q.data());
      }
      for (std::size_t i = 1; i < k; ++i)
        pw.SetParameterLowerBound(q.data(), static_cast<int>(i), 0);
      ceres::Solver::Summary ps;
      ceres::Solve(so, &pw, &ps);
      curve.piecewise.raw = knots;
      curve.piecewise.force_n.resize(k);
      double acc = 0.0;
      for (std::size_t i = 0; i < k; ++i) {
        acc += q[i];
        curve.piecewise.force_n[i] = acc;
      }
      curve.piecewise_quality = quality_of(loaded, static_cast<int>(k),
                                           [&](double r) { return curve.piecewise.to_newtons(r); });
      curve.piecewise_quality.iterations = static_cast<int>(ps.iterations.size());
      curve.piecewise_quality.converged = ps.termination_type == ceres::CONVERGENCE;
      if (curve.piecewise_quality.bic < curve.power_law_quality.bic)
        curve.model = FsrModel::kPiecewiseLinear;
    }
  }
  if (summary) {
    summary->input_pairs = pairs.size();
    summary->loaded_pairs = loaded.size();
    summary->time_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  return curve;
}

}  // namespace hc::calib
