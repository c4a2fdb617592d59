// Six-axis force-torque sensor bias (zero offset) and its drift, estimated from the unloaded
// stretches of a recorded wrench channel.
//
// The sensor reports raw counts; counts / counts_per_unit (WrenchCalibration) is the wrench before
// any bias is removed, w(t) = b + d (t - t0) + load(t) + noise. While the probe touches nothing,
// load = 0 and w is the bias b plus a slow drift d (the ATI Nano25 drifts with temperature; the
// simulator adds drift_n_per_s to Fz). We find the unloaded stretches robustly and fit b and d by
// least squares over them:
//  1. cut the series into windows of `window_s`; per window the median (per axis) and the noise
//     scale 1.4826 MAD (per axis);
//  2. windows whose noise scale exceeds `max_noise_ratio` x the median noise scale of all windows
//     are transitions (loading / unloading) and never count as unloaded;
//  3. the unloaded force level is the densest cluster of window medians: the window with the most
//     other windows within `contact_threshold_n` (force axes) seeds it;
//  4. a line b + d (t - t0) is fitted per axis through the cluster's window medians, windows within
//     `contact_threshold_n` (force) of the line join or leave, until the set stops changing;
//  4b. the line is refitted with a tight test (every force axis within tight_sigma robust
//     deviations of the window medians' scatter about the line), dropping small loads;
//  5. b, d and their standard errors come from ordinary least squares over every sample of the
//     unloaded windows (residual standard deviation = the sensor noise).
// Units: N for the force axes (0..2), N·m for the torque axes (3..5), s for time.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <vector>

#include "common/json.h"
#include "common/status.h"

namespace hc::calib {

using Vector6d = Eigen::Matrix<double, 6, 1>;

// One wrench reading before bias removal: Fx Fy Fz (N) Tx Ty Tz (N·m) at host time t_ns.
struct WrenchReading {
  std::int64_t t_ns = 0;
  Vector6d w = Vector6d::Zero();
};

struct FtBiasOptions {
  double window_s = 0.1;  // analysis window length
  // A window whose median force is farther than this from the unloaded level is loaded (N). The
  // thesis's F/T resolution is 1/24 N (Nano25, Sec. 5.6); contact steps in a capture are >= ~0.5 N.
  double contact_threshold_n = 0.25;
  // Second pass: a window stays unloaded when its median is within this many robust standard
  // deviations of the fitted bias line on every force axis (catches loads below the threshold).
  double tight_sigma = 5.0;
  // A window noisier than this x the median window noise is a transition (loading/unloading).
  double max_noise_ratio = 3.0;
  int min_window_samples = 10;   // windows with fewer samples are skipped
  int min_unloaded_windows = 3;  // fewer unloaded windows: kFailedPrecondition
  Status validate() const;
};

struct FtBiasResult {
  Vector6d bias = Vector6d::Zero();         // at the first sample's time t0
  Vector6d bias_std = Vector6d::Zero();     // standard error of `bias`
  Vector6d drift_per_s = Vector6d::Zero();  // N/s, N·m/s
  Vector6d drift_per_s_std = Vector6d::Zero();
  Vector6d mean_unloaded = Vector6d::Zero();  // plain mean over the unloaded samples
  Vector6d noise_std = Vector6d::Zero();      // residual standard deviation (sensor noise)
  // Drift over the whole session: drift_per_s x duration.
  Vector6d drift_total = Vector6d::Zero();
  std::int64_t t0_ns = 0;
  double duration_s = 0.0;
  std::size_t samples = 0;           // all samples
  std::size_t unloaded_samples = 0;  // used in the fit
  std::size_t windows = 0;
  std::size_t unloaded_windows = 0;
  std::size_t transition_windows = 0;
  // Unloaded stretches [start, end) in seconds since t0 (consecutive unloaded windows merged).
  std::vector<std::pair<double, double>> unloaded_intervals_s;
  double time_s = 0.0;  // wall time of the estimate

  // The bias at time t_ns (bias + drift x (t - t0)).
  Vector6d bias_at(std::int64_t t_ns) const;
  Json to_json() const;
};

// Estimates the bias. kInvalidArgument on bad options or unsorted / non-finite input;
// kFailedPrecondition when there are too few samples or unloaded windows (the message says how
// many were found).
Result<FtBiasResult> estimate_ft_bias(const std::vector<WrenchReading>& readings,
                                      const FtBiasOptions& options = {});

}  // namespace hc::calib
