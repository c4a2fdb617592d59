// The FSR response curve: raw reading -> N, fitted against a reference force (the six-axis F/T
// sensor) on pairs of simultaneous readings.
//
// Two models:
//  * power law (the FSR's conductance follows a power law of the force past a break force,
//    Interlink FSR 400 datasheet; read through a voltage divider; the model of
//    devices::FsrCalibration and of the simulated FSR):
//      x = raw / full_scale;  F = 0 for x <= threshold, else scale_n ((x - threshold) /
//      (1 - threshold))^exponent
//    three parameters (threshold, scale_n, exponent); full_scale is given (the ADC's range).
//  * monotone piecewise linear: force values at `knots` raw readings (placed at quantiles of the
//    loaded readings), non-decreasing, linear in between and extrapolated by the end segments. For
//    real sensors whose response (hysteresis, creep, a divider that saturates) does not follow the
//    power law.
// Both are fitted by least squares on the force residual F_model(raw) - F_ref with Ceres over the
// loaded pairs (F_ref >= min_force_n); the model with the lower BIC (n ln(RSS/n) + k ln n) is
// selected, so the more flexible curve wins only when it explains clearly more.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "common/json.h"
#include "common/status.h"

namespace hc::calib {

// One FSR reading with the reference force at the same instant.
struct FsrPair {
  double raw = 0.0;      // ADC counts
  double force_n = 0.0;  // reference force (N, compressive positive)
};

struct FsrPowerLaw {
  double full_scale = 4095.0;
  double threshold = 0.02;
  double scale_n = 60.0;
  double exponent = 1.6;
  double to_newtons(double raw) const;
};

struct FsrPiecewiseLinear {
  std::vector<double> raw;      // strictly increasing
  std::vector<double> force_n;  // non-decreasing, same size (>= 2)
  double to_newtons(double raw) const;
};

enum class FsrModel { kPowerLaw, kPiecewiseLinear };
std::string_view to_string(FsrModel model);

// The quality of one fitted model over the fitting pairs.
struct FsrFitQuality {
  double rms_n = 0.0;  // RMS of F_model - F_ref
  double max_abs_n = 0.0;
  double r2 = 0.0;  // 1 - RSS / TSS
  double bic = 0.0;
  int parameters = 0;
  int iterations = 0;
  bool converged = false;
  Json to_json() const;
};

// The calibration a fit produces (and the FSR JSON file holds; see fsr_io.h).
struct FsrCurve {
  std::string device;  // FSR device name, informational
  FsrModel model = FsrModel::kPowerLaw;
  FsrPowerLaw power_law;
  // Standard deviations of threshold, scale_n, exponent (covariance scaled by the residual
  // variance); zero when not computed.
  double threshold_std = 0.0, scale_n_std = 0.0, exponent_std = 0.0;
  FsrPiecewiseLinear piecewise;  // empty when not fitted
  FsrFitQuality power_law_quality, piecewise_quality;
  std::size_t pairs = 0;  // pairs used (loaded)

  // Force through the selected model.
  double to_newtons(double raw) const;
};

struct FsrFitOptions {
  double full_scale = 4095.0;  // raw at the top of the range (12-bit ADC; Phidget: 1000)
  double min_force_n = 0.5;    // pairs below are unloaded and not fitted
  int knots = 8;               // piecewise-linear knots (>= 2)
  bool fit_piecewise = true;
  int max_iterations = 200;
  int min_pairs = 10;
  Status validate() const;
};

struct FsrFitSummary {
  std::size_t input_pairs = 0;
  std::size_t loaded_pairs = 0;
  double time_s = 0.0;
};

// Fits both models and selects one. kInvalidArgument on bad options or non-finite pairs;
// kFailedPrecondition with fewer than min_pairs loaded pairs, loaded raw values that do not vary,
// or a power-law fit that does not converge to finite parameters.
Result<FsrCurve> fit_fsr(const std::vector<FsrPair>& pairs, const FsrFitOptions& options = {},
                         FsrFitSummary* summary = nullptr);

}  // namespace hc::calib
