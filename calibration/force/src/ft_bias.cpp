#include "calibration/force/ft_bias.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>

namespace hc::calib {
namespace {

// 1 / Phi^-1(3/4): MAD to standard deviation for Gaussian noise.
constexpr double kMadToSigma = 1.4826;

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const std::size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  const double hi = v[mid];
  if (v.size() % 2 == 1) return hi;
  const double lo = *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid));
  return 0.5 * (lo + hi);
}

struct Window {
  std::size_t begin = 0, end = 0;  // sample range
  double t_s = 0.0;                // mid time since t0
  Vector6d med = Vector6d::Zero();
  Vector6d sigma = Vector6d::Zero();
  bool transition = false;
  bool unloaded = false;
};

// Least-squares line y = a + b (t - tm) over the unloaded windows' medians (per axis).
void fit_line(const std::vector<Window>& w, Vector6d& a_at0, Vector6d& b) {
  double st = 0.0;
  int n = 0;
  for (const Window& x : w)
    if (x.unloaded) st += x.t_s, ++n;
  if (n == 0) return;
  const double tm = st / n;
  Vector6d sy = Vector6d::Zero(), sty = Vector6d::Zero();
  double stt = 0.0;
  for (const Window& x : w) {
    if (!x.unloaded) continue;
    sy += x.med;
    sty += (x.t_s - tm) * x.med;
    stt += (x.t_s - tm) * (x.t_s - tm);
  }
  const Vector6d mean = sy / n;
  b = stt > 0.0 ? Vector6d(sty / stt) : Vector6d::Zero();
  a_at0 = mean - b * tm;
}

// Sample i's time since the first sample (t0).
double t_of(const std::vector<WrenchReading>& readings, std::size_t i) {
  return static_cast<double>(readings[i].t_ns - readings.front().t_ns) * 1e-9;
}

Status check_readings(const std::vector<WrenchReading>& readings, const FtBiasOptions& options) {
  const std::size_t n = readings.size();
  for (std::size_t i = 0; i < n; ++i) {
    if (!readings[i].w.allFinite())
      return invalid_argument(fmt::format("wrench sample {} is not finite", i));
    if (i > 0 && readings[i].t_ns < readings[i - 1].t_ns)
      return invalid_argument(fmt::format("wrench sample {} goes back in time", i));
  }
  if (n < static_cast<std::size_t>(options.min_window_samples * options.min_unloaded_windows))
    return failed_precondition(
        fmt::format("{} wrench samples: need at least {} ({} windows of {})", n,
                    options.min_window_samples * options.min_unloaded_windows,
                    options.min_unloaded_windows, options.min_window_samples));
  return {};
}

// 1. Windows with per-axis median and MAD noise scale.
std::vector<Window> make_windows(const std::vector<WrenchReading>& readings,
                                 const FtBiasOptions& options) {
  const std::size_t n = readings.size();
  std::vector<Window> windows;
  std::vector<double> buf;
  for (std::size_t i = 0; i < n;) {
    const double t_end = t_of(readings, i) + options.window_s;
    std::size_t j = i;
    while (j < n && t_of(readings, j) < t_end) ++j;
    if (j - i >= static_cast<std::size_t>(options.min_window_samples)) {
      Window w;
      w.begin = i;
      w.end = j;
      w.t_s = 0.5 * (t_of(readings, i) + t_of(readings, j - 1));
      for (int a = 0; a < 6; ++a) {
        buf.clear();
        for (std::size_t k = i; k < j; ++k) buf.push_back(readings[k].w[a]);
        w.med[a] = median(buf);
        for (double& v : buf) v = std::abs(v - w.med[a]);
        w.sigma[a] = kMadToSigma * median(buf);
      }
      windows.push_back(w);
    }
    i = j;
  }
  return windows;
}

// The typical noise scale per axis: the median over the windows.
Vector6d typical_noise(const std::vector<Window>& windows) {
  Vector6d typical;
  std::vector<double> buf;
  for (int a = 0; a < 6; ++a) {
    buf.clear();
    for (const Window& w : windows) buf.push_back(w.sigma[a]);
    typical[a] = median(buf);
  }
  return typical;
}

// 2. Transitions: noise scale far above the typical one on any force axis. Returns their number.
std::size_t mark_transitions(const FtBiasOptions& options, const Vector6d& typical,
                             std::vector<Window>& windows) {
  std::size_t transitions = 0;
  for (Window& w : windows) {
    for (int a = 0; a < 3; ++a)
      // A floor of 1e-9 N keeps noise-free (synthetic) data from marking every window.
      if (w.sigma[a] > options.max_noise_ratio * std::max(typical[a], 1e-9)) w.transition = true;
    if (w.transition) ++transitions;
  }
  return transitions;
}

// 3. Seed: the calm window with the most calm neighbours (force distance within threshold); marks
// those unloaded and returns the seed.
Result<std::size_t> seed_unloaded(const FtBiasOptions& options, std::vector<Window>& windows) {
  const double thr = options.contact_threshold_n;
  std::size_t best = windows.size(), best_count = 0;
  for (std::size_t k = 0; k < windows.size(); ++k) {
    if (windows[k].transition) continue;
    std::size_t c = 0;
    for (const Window& o : windows)
      if (!o.transition && (o.med.head<3>() - windows[k].med.head<3>()).norm() <= thr) ++c;
    if (c > best_count) best = k, best_count = c;
  }
  if (best == windows.size())
    return failed_precondition("every window is a loading transition: no unloaded stretch");
  for (Window& w : windows)
    w.unloaded = !w.transition && (w.med.head<3>() - windows[best].med.head<3>()).norm() <= thr;
  return best;
}

// 4. Line through the cluster; re-select windows near the line until stable.
void follow_line(const FtBiasOptions& options, std::vector<Window>& windows, Vector6d& a0,
                 Vector6d& b) {
  const double thr = options.contact_threshold_n;
  for (int iter = 0; iter < 20; ++iter) {
    fit_line(windows, a0, b);
    bool changed = false;
    for (Window& w : windows) {
      const Vector6d line = a0 + b * w.t_s;
      const bool u = !w.transition && (w.med.head<3>() - line.head<3>()).norm() <= thr;
      changed = changed || u != w.unloaded;
      w.unloaded = u;
    }
    if (!changed) break;
  }
}

// 4b. Tight re-selection: loads below contact_threshold_n (the first steps of a press) are
// still far outside the scatter of unloaded window medians about the line (the median of a
// 100-sample window of 1/24 N noise scatters by ~5 mN). A window stays unloaded when every force
// axis is within tight_sigma robust deviations (1.4826 MAD of the residuals, floored at the
// standard error of a window median) of the line.
void tighten_to_line(const FtBiasOptions& options, const Vector6d& typical,
                     std::vector<Window>& windows, Vector6d& a0, Vector6d& b) {
  std::vector<double> buf;
  double window_size = 0.0;
  for (const Window& w : windows) window_size += static_cast<double>(w.end - w.begin);
  window_size /= static_cast<double>(windows.size());
  for (int iter = 0; iter < 20; ++iter) {
    fit_line(windows, a0, b);
    Eigen::Vector3d scale;
    for (int a = 0; a < 3; ++a) {
      buf.clear();
      for (const Window& w : windows)
        if (w.unloaded) buf.push_back(w.med[a] - (a0[a] + b[a] * w.t_s));
      const double mid = median(buf);
      for (double& v : buf) v = std::abs(v - mid);
      // 1.2533 = sqrt(pi / 2): standard error of a median relative to that of a mean.
      scale[a] = std::max(kMadToSigma * median(buf), 1.2533 * typical[a] / std::sqrt(window_size));
      scale[a] = std::max(scale[a], 1e-12);
    }
    bool changed = false;
    for (Window& w : windows) {
      bool u = !w.transition;
      for (int a = 0; a < 3 && u; ++a)
        u = std::abs(w.med[a] - (a0[a] + b[a] * w.t_s)) <= options.tight_sigma * scale[a];
      changed = changed || u != w.unloaded;
      w.unloaded = u;
    }
    if (!changed) break;
  }
}

// Guard band: a window next to a loaded or transition window may hold the first or last
// milliseconds of a press that its median hides; keep only windows whose neighbours are unloaded
// too (unless that leaves too few).
void keep_core_windows(const FtBiasOptions& options, std::vector<Window>& windows) {
  std::vector<bool> core(windows.size(), false);
  std::size_t n_core = 0;
  for (std::size_t k = 0; k < windows.size(); ++k) {
    core[k] = windows[k].unloaded && (k == 0 || windows[k - 1].unloaded) &&
              (k + 1 == windows.size() || windows[k + 1].unloaded);
    n_core += core[k] ? 1 : 0;
  }
  if (n_core >= static_cast<std::size_t>(options.min_unloaded_windows))
    for (std::size_t k = 0; k < windows.size(); ++k) windows[k].unloaded = core[k];
}

// 5. OLS over every sample of the unloaded windows: bias, drift, noise and their errors.
void fit_unloaded_samples(const std::vector<WrenchReading>& readings,
                          const std::vector<Window>& windows, FtBiasResult& out) {
  double st = 0.0;
  std::size_t m = 0;
  for (const Window& w : windows)
    if (w.unloaded)
      for (std::size_t k = w.begin; k < w.end; ++k) st += t_of(readings, k), ++m;
  const double tm = st / static_cast<double>(m);
  Vector6d sy = Vector6d::Zero(), sty = Vector6d::Zero();
  double stt = 0.0;
  for (const Window& w : windows)
    if (w.unloaded)
      for (std::size_t k = w.begin; k < w.end; ++k) {
        const double dt = t_of(readings, k) - tm;
        sy += readings[k].w;
        sty += dt * readings[k].w;
        stt += dt * dt;
      }
  const Vector6d mean = sy / static_cast<double>(m);
  const Vector6d slope = stt > 0.0 ? Vector6d(sty / stt) : Vector6d::Zero();
  Vector6d ss = Vector6d::Zero();
  for (const Window& w : windows)
    if (w.unloaded)
      for (std::size_t k = w.begin; k < w.end; ++k) {
        const Vector6d r = readings[k].w - mean - slope * (t_of(readings, k) - tm);
        ss += r.cwiseProduct(r);
      }
  const double dof = std::max<double>(1.0, static_cast<double>(m) - 2.0);
  const Vector6d sigma = (ss / dof).cwiseSqrt();
  out.unloaded_samples = m;
  out.mean_unloaded = mean;
  out.noise_std = sigma;
  out.drift_per_s = slope;
  out.drift_per_s_std = stt > 0.0 ? Vector6d(sigma / std::sqrt(stt)) : Vector6d::Zero();
  out.bias = mean - slope * tm;  // at t0 (t = 0)
  for (int a = 0; a < 6; ++a)
    out.bias_std[a] = std::sqrt(sigma[a] * sigma[a] / static_cast<double>(m) +
                                tm * tm * out.drift_per_s_std[a] * out.drift_per_s_std[a]);
  out.drift_total = slope * out.duration_s;
}

// Merge consecutive unloaded windows into intervals.
void add_unloaded_intervals(const std::vector<WrenchReading>& readings,
                            const std::vector<Window>& windows, FtBiasResult& out) {
  for (std::size_t k = 0; k < windows.size(); ++k) {
    if (!windows[k].unloaded) continue;
    const double a = t_of(readings, windows[k].begin), e = t_of(readings, windows[k].end - 1);
    if (!out.unloaded_intervals_s.empty() && k > 0 && windows[k - 1].unloaded)
      out.unloaded_intervals_s.back().second = e;
    else
      out.unloaded_intervals_s.emplace_back(a, e);
  }
}

}  // namespace

Status FtBiasOptions::validate() const {
  if (!(window_s > 0.0) || !std::isfinite(window_s))
    return invalid_argument("window_s must be > 0");
  if (!(contact_threshold_n > 0.0) || !std::isfinite(contact_threshold_n))
    return invalid_argument("contact_threshold_n must be > 0");
  if (!(max_noise_ratio > 1.0)) return invalid_argument("max_noise_ratio must be > 1");
  if (!(tight_sigma > 1.0)) return invalid_argument("tight_sigma must be > 1");
  if (min_window_samples < 3) return invalid_argument("min_window_samples must be >= 3");
  if (min_unloaded_windows < 2) return invalid_argument("min_unloaded_windows must be >= 2");
  return {};
}

Vector6d FtBiasResult::bias_at(std::int64_t t_ns) const {
  return bias + drift_per_s * (static_cast<double>(t_ns - t0_ns) * 1e-9);
}

Json FtBiasResult::to_json() const {
  Json intervals = Json::array();
  for (const auto& [a, b] : unloaded_intervals_s) intervals.push_back(Json::array({a, b}));
  return Json{{"bias", eigen_to_json(bias)},
              {"bias_std", eigen_to_json(bias_std)},
              {"drift_per_s", eigen_to_json(drift_per_s)},
              {"drift_per_s_std", eigen_to_json(drift_per_s_std)},
              {"drift_total", eigen_to_json(drift_total)},
              {"mean_unloaded", eigen_to_json(mean_unloaded)},
              {"noise_std", eigen_to_json(noise_std)},
              {"units", "Fx Fy Fz in N, Tx Ty Tz in N·m; bias at t0 (first sample)"},
              {"t0_ns", t0_ns},
              {"duration_s", duration_s},
              {"samples", samples},
              {"unloaded_samples", unloaded_samples},
              {"windows", windows},
              {"unloaded_windows", unloaded_windows},
              {"transition_windows", transition_windows},
              {"unloaded_intervals_s", intervals},
              {"time_s", time_s}};
}

Result<FtBiasResult> estimate_ft_bias(const std::vector<WrenchReading>& readings,
                                      const FtBiasOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  HC_RETURN_IF_ERROR(options.validate());
  HC_RETURN_IF_ERROR(check_readings(readings, options));

  FtBiasResult out;
  out.t0_ns = readings.front().t_ns;
  out.samples = readings.size();
  out.duration_s = static_cast<double>(readings.back().t_ns - out.t0_ns) * 1e-9;

  std::vector<Window> windows = make_windows(readings, options);
  out.windows = windows.size();
  if (windows.size() < static_cast<std::size_t>(options.min_unloaded_windows))
    return failed_precondition(fmt::format("only {} windows of {} s with >= {} samples",
                                           windows.size(), options.window_s,
                                           options.min_window_samples));
  const Vector6d typical = typical_noise(windows);
  out.transition_windows = mark_transitions(options, typical, windows);
  HC_ASSIGN_OR_RETURN(const std::size_t best, seed_unloaded(options, windows));
  Vector6d a0 = windows[best].med, b = Vector6d::Zero();
  follow_line(options, windows, a0, b);
  tighten_to_line(options, typical, windows, a0, b);
  keep_core_windows(options, windows);
  for (const Window& w : windows) out.unloaded_windows += w.unloaded ? 1 : 0;
  if (out.unloaded_windows < static_cast<std::size_t>(options.min_unloaded_windows))
    return failed_precondition(fmt::format("only {} unloaded windows (need {})",
                                           out.unloaded_windows, options.min_unloaded_windows));

  fit_unloaded_samples(readings, windows, out);
  add_unloaded_intervals(readings, windows, out);
  out.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace hc::calib
