// F/T bias and FSR response-curve calibration: synthetic data with known truth, sessions recorded
// from the simulated rig with known device parameters, malformed input.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "calibration/force/force_session.h"
#include "calibration/force/fsr_fit.h"
#include "calibration/force/fsr_io.h"
#include "calibration/force/ft_bias.h"
#include "common/file_io.h"
#include "force_session_support.h"
#include "test_data.h"

namespace hc::calib {
namespace {

using hc::testing::ScratchDir;

// Synthetic wrench: bias b + drift d t + load(t) + N(0, sigma) per axis; load on Fz (and a
// little on Fx) during presses that ramp up and down with noise-free plateaus in between.
struct SyntheticWrench {
  Vector6d bias;
  Vector6d drift;
  double sigma_n = 1.0 / 24.0;  // Nano25 resolution (thesis 5.6)
  double sigma_nm = 1.0 / 1320.0;
  std::vector<WrenchReading> readings;
};

SyntheticWrench make_wrench(std::uint64_t seed) {
  SyntheticWrench s;
  s.bias << 0.8, -0.35, 2.1, 0.012, -0.004, 0.0007;
  s.drift << 0.0, 0.001, 0.003, 0.0, 0.0, 1e-5;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  const double rate = 1000.0;
  const double duration = 40.0;
  for (int k = 0; k < static_cast<int>(duration * rate); ++k) {
    const double t = k / rate;
    // Presses: 5..12 s, 18..26 s, 31..35 s (rises to 30 N, holds, falls); unloaded otherwise.
    double load = 0.0;
    for (const auto& [a, e] : {std::pair{5.0, 12.0}, {18.0, 26.0}, {31.0, 35.0}}) {
      if (t < a || t > e) continue;
      const double u = std::min({(t - a) / 1.0, (e - t) / 1.0, 1.0});
      load = 30.0 * u;
    }
    WrenchReading r;
    r.t_ns = 3'000'000'000 + static_cast<std::int64_t>(std::llround(t * 1e9));
    for (int i = 0; i < 6; ++i)
      r.w[i] = s.bias[i] + s.drift[i] * t + (i < 3 ? s.sigma_n : s.sigma_nm) * g(rng);
    r.w[2] += load;
    r.w[0] += 0.1 * load;
    r.w[4] += 0.002 * load;
    s.readings.push_back(r);
  }
  return s;
}

TEST(FtBias, RecoversBiasAndDriftOfSyntheticSession) {
  const SyntheticWrench s = make_wrench(5);
  Result<FtBiasResult> r = estimate_ft_bias(s.readings);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  // Unloaded: 0..5, 12..18, 26..31, 35..40 s = 22 s of 40 (less the transition windows).
  EXPECT_GT(r->unloaded_samples, 20000u);
  EXPECT_LE(r->unloaded_samples, 22100u);
  for (int i = 0; i < 6; ++i) {
    const double sigma = i < 3 ? s.sigma_n : s.sigma_nm;
    // Truth within 4 standard errors, and the standard error as OLS predicts for ~21000 samples
    // spread over 40 s (sigma / sqrt(n) ~ 2.9e-4 N at t-bar, larger at t0).
    EXPECT_NEAR(r->bias[i], s.bias[i], 4.0 * r->bias_std[i]) << "axis " << i;
    EXPECT_NEAR(r->drift_per_s[i], s.drift[i], 4.0 * r->drift_per_s_std[i]) << "axis " << i;
    EXPECT_NEAR(r->noise_std[i], sigma, 0.03 * sigma) << "axis " << i;
    EXPECT_LT(r->bias_std[i], 3.0 * sigma / std::sqrt(20000.0)) << "axis " << i;
  }
  // Fz: 3 mN/s over 40 s = 0.12 N of drift over the session.
  EXPECT_NEAR(r->drift_total[2], 0.12, 0.01);
  // Four unloaded stretches.
  EXPECT_EQ(r->unloaded_intervals_s.size(), 4u);
}

TEST(FtBias, RefusesSessionsWithoutUnloadedStretch) {
  std::vector<WrenchReading> ramp;
  for (int k = 0; k < 5000; ++k) {  // load rising steadily: never a plateau near one level
    WrenchReading r;
    r.t_ns = std::int64_t{k} * 1'000'000;
    r.w[2] = 0.02 * k;
    ramp.push_back(r);
  }
  Result<FtBiasResult> r = estimate_ft_bias(ramp);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kFailedPrecondition) << r.status().to_string();

  EXPECT_EQ(estimate_ft_bias({}).status().code(), StatusCode::kFailedPrecondition);
  std::vector<WrenchReading> bad(100);
  for (int k = 0; k < 100; ++k) bad[static_cast<std::size_t>(k)].t_ns = std::int64_t{k} * 1'000'000;
  bad[50].w[1] = std::nan("");
  EXPECT_EQ(estimate_ft_bias(bad).status().code(), StatusCode::kInvalidArgument);
  bad[50].w[1] = 0.0;
  bad[60].t_ns = 0;  // back in time
  EXPECT_EQ(estimate_ft_bias(bad).status().code(), StatusCode::kInvalidArgument);
  FtBiasOptions o;
  o.window_s = 0.0;
  EXPECT_EQ(estimate_ft_bias(bad, o).status().code(), StatusCode::kInvalidArgument);
}

// Pairs from a known power law: raw noise (ADC counts) plus reference-force noise (N).
std::vector<FsrPair> power_law_pairs(const FsrPowerLaw& truth, int n, double raw_noise,
                                     double force_noise, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 35.0);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<FsrPair> out;
  for (int k = 0; k < n; ++k) {
    const double f = u(rng);
    const double x = truth.threshold +
                     (1.0 - truth.threshold) * std::pow(f / truth.scale_n, 1.0 / truth.exponent);
    out.push_back(
        {std::round(x * truth.full_scale + raw_noise * g(rng)), f + force_noise * g(rng)});
  }
  return out;
}

TEST(FsrFit, RecoversPowerLawParameters) {
  // The simulated FSR's default calibration (devices::FsrCalibration).
  const FsrPowerLaw truth{4095.0, 0.02, 60.0, 1.6};
  const std::vector<FsrPair> pairs = power_law_pairs(truth, 800, 2.0, 1.0 / 24.0, 3);
  FsrFitSummary summary;
  Result<FsrCurve> c = fit_fsr(pairs, {}, &summary);
  ASSERT_TRUE(c.ok()) << c.status().to_string();
  EXPECT_EQ(c->model, FsrModel::kPowerLaw);
  EXPECT_TRUE(c->power_law_quality.converged);
  // Tolerances: 4 reported standard deviations, and absolute bounds a user would accept.
  EXPECT_NEAR(c->power_law.threshold, truth.threshold, 4.0 * c->threshold_std);
  EXPECT_NEAR(c->power_law.scale_n, truth.scale_n, 4.0 * c->scale_n_std);
  EXPECT_NEAR(c->power_law.exponent, truth.exponent, 4.0 * c->exponent_std);
  EXPECT_NEAR(c->power_law.threshold, truth.threshold, 5e-4);
  EXPECT_NEAR(c->power_law.scale_n, truth.scale_n, 0.01 * truth.scale_n);
  EXPECT_NEAR(c->power_law.exponent, truth.exponent, 0.01);
  // Residual: force noise 1/24 N plus 2 counts of raw noise through dF/draw (<= ~0.03 N/count
  // at 35 N): RMS between 0.04 and 0.08 N.
  EXPECT_GT(c->power_law_quality.rms_n, 0.04);
  EXPECT_LT(c->power_law_quality.rms_n, 0.08);
  EXPECT_GT(c->power_law_quality.r2, 0.9999);
  EXPECT_GT(summary.loaded_pairs, 750u);
}

TEST(FsrFit, SelectsPiecewiseLinearForANonPowerLawSensor) {
  // A divider that saturates: F = 40 tanh(3 (x - 0.1)) past x = 0.1 (not a power law).
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(0.12, 0.9);
  std::normal_distribution<double> g(0.0, 0.03);
  std::vector<FsrPair> pairs;
  for (int k = 0; k < 600; ++k) {
    const double x = u(rng);
    pairs.push_back({std::round(x * 4095.0), 40.0 * std::tanh(3.0 * (x - 0.1)) + g(rng)});
  }
  FsrFitOptions o;
  o.knots = 12;
  Result<FsrCurve> c = fit_fsr(pairs, o);
  ASSERT_TRUE(c.ok()) << c.status().to_string();
  EXPECT_EQ(c->model, FsrModel::kPiecewiseLinear);
  EXPECT_LT(c->piecewise_quality.rms_n, c->power_law_quality.rms_n);
  // 12 knots on a tanh: chord error max |f''| h^2 / 8 with h ~ 0.07 -> ~0.2 N at worst.
  EXPECT_LT(c->piecewise_quality.rms_n, 0.2);
  for (std::size_t i = 1; i < c->piecewise.force_n.size(); ++i)
    EXPECT_GE(c->piecewise.force_n[i], c->piecewise.force_n[i - 1]);
}

TEST(FsrFit, RefusesTooFewOrConstantPairs) {
  std::vector<FsrPair> few(5, {1000.0, 5.0});
  EXPECT_EQ(fit_fsr(few).status().code(), StatusCode::kFailedPrecondition);
  std::vector<FsrPair> flat(50, {1000.0, 5.0});
  Result<FsrCurve> r = fit_fsr(flat);
  EXPECT_EQ(r.status().code(), StatusCode::kFailedPrecondition);
  std::vector<FsrPair> nan(50, {1000.0, std::nan("")});
  EXPECT_EQ(fit_fsr(nan).status().code(), StatusCode::kInvalidArgument);
}

TEST(FsrIo, RoundTripAndMalformedInput) {
  const FsrPowerLaw truth{4095.0, 0.02, 60.0, 1.6};
  Result<FsrCurve> c = fit_fsr(power_law_pairs(truth, 300, 2.0, 0.04, 4));
  ASSERT_TRUE(c.ok());
  c->device = "fsr";
  ScratchDir dir;
  ASSERT_TRUE(write_fsr_calibration(dir / "fsr.json", *c).ok());
  Result<FsrCurve> back = read_fsr_calibration(dir / "fsr.json");
  ASSERT_TRUE(back.ok()) << back.status().to_string();
  EXPECT_EQ(back->device, "fsr");
  EXPECT_EQ(back->model, c->model);
  EXPECT_EQ(back->pairs, c->pairs);
  for (double raw : {50.0, 100.0, 900.0, 2500.0, 4000.0})
    EXPECT_DOUBLE_EQ(back->to_newtons(raw), c->to_newtons(raw));

  const std::string good = dump_json(fsr_curve_to_json(*c));
  struct Case {
    std::string text, expect;
  };
  const std::vector<Case> bad = {
      {"", "fsr.json"},
      {"[]", "expected a JSON object"},
      {R"({"format":"other","version":1,"model":"power_law"})", "format"},
      {R"({"format":"hardcopy.fsr_calibration","version":2,"model":"power_law"})", "version"},
      {R"({"format":"hardcopy.fsr_calibration","version":1,"model":"cubic"})", "model"},
      {R"({"format":"hardcopy.fsr_calibration","version":1,"model":"power_law"})",
       "power_law: missing"},
      {R"({"format":"hardcopy.fsr_calibration","version":1,"model":"power_law","power_law":)"
       R"({"full_scale":4095,"threshold":1.5,"scale_n":60,"exponent":1.6}})",
       "threshold"},
      {R"({"format":"hardcopy.fsr_calibration","version":1,"model":"power_law","power_law":)"
       R"({"full_scale":4095,"threshold":0.1,"scale_n":"60","exponent":1.6}})",
       "scale_n: expected a number"},
      {R"({"format":"hardcopy.fsr_calibration","version":1,"model":"piecewise_linear",)"
       R"("piecewise_linear":{"raw":[1,2,2],"force_n":[0,1,2]}})",
       "raw[2]"},
      {R"({"format":"hardcopy.fsr_calibration","version":1,"model":"piecewise_linear",)"
       R"("piecewise_linear":{"raw":[1,2,3],"force_n":[0,2,1]}})",
       "force_n[2]"},
      {R"({"format":"hardcopy.fsr_calibration","version":1,"model":"piecewise_linear",)"
       R"("piecewise_linear":{"raw":[1,2,3],"force_n":[0,2]}})",
       "2 values for 3 knots"},
      {good.substr(0, good.size() / 2), "fsr.json"},
  };
  for (const Case& k : bad) {
    Result<FsrCurve> r = parse_fsr_calibration(k.text, "fsr.json");
    ASSERT_FALSE(r.ok()) << k.text;
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument) << k.text;
    EXPECT_NE(r.status().message().find(k.expect), std::string::npos)
        << r.status().message() << " (wanted '" << k.expect << "')";
  }
  EXPECT_EQ(read_fsr_calibration(dir / "missing.json").status().code(), StatusCode::kNotFound);
}

// ---- Sessions recorded from the simulated rig ----

class SimForceSession : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new ScratchDir();
    spec_ = new testing::SimForceSpec();
    const Status s = testing::record_sim_force_session(*dir_ / "force.mcap", *spec_);
    ASSERT_TRUE(s.ok()) << s.to_string();
  }
  static void TearDownTestSuite() {
    delete dir_;
    delete spec_;
  }
  static ScratchDir* dir_;
  static testing::SimForceSpec* spec_;
};
ScratchDir* SimForceSession::dir_ = nullptr;
testing::SimForceSpec* SimForceSession::spec_ = nullptr;

TEST_F(SimForceSession, FtBiasMatchesTheSimulatorsOffsetAndDrift) {
  ForceSessionOptions o;
  Result<ForceSession> s = read_force_session(*dir_ / "force.mcap", o);
  ASSERT_TRUE(s.ok()) << s.status().to_string();
  EXPECT_EQ(s->ft_device, "ft");
  Result<FtBiasResult> b = estimate_ft_bias(s->wrench);
  ASSERT_TRUE(b.ok()) << b.status().to_string();
  // The simulated F/T (sim_force_torque.cpp): Fz = force + offset_n + drift_n_per_s (t - t_activate)
  // + N(0, 1/24 N); other axes N(0, noise) with zero bias; counts rounded at 1e6 counts/N.
  // spec: offset 0.4 N, drift 0.002 N/s; the first sample is 1 ms after activation.
  EXPECT_NEAR(b->bias[2], 0.4, std::max(4.0 * b->bias_std[2], 2e-3));
  EXPECT_NEAR(b->drift_per_s[2], 0.002, std::max(4.0 * b->drift_per_s_std[2], 2e-4));
  for (int i : {0, 1, 3, 4, 5}) EXPECT_NEAR(b->bias[i], 0.0, 4.0 * b->bias_std[i]) << i;
  EXPECT_NEAR(b->noise_std[2], 1.0 / 24.0, 0.004);
  // Unloaded: 1 s at each end, 2 s in all (the presses cover the rest).
  EXPECT_GT(b->unloaded_samples, 1700u);
  EXPECT_LT(b->unloaded_samples, 2600u);
}

TEST_F(SimForceSession, FsrFitRecoversTheSimulatedCalibration) {
  ForceSessionOptions o;
  o.want_fsr = true;
  Result<ForceSession> s = read_force_session(*dir_ / "force.mcap", o);
  ASSERT_TRUE(s.ok()) << s.status().to_string();
  ASSERT_TRUE(s->recorded_fsr.has_value());
  Result<FtBiasResult> b = estimate_ft_bias(s->wrench);
  ASSERT_TRUE(b.ok());
  const std::vector<FsrPair> pairs = pair_fsr_with_ft(*s, *b);
  EXPECT_GT(pairs.size(), 0.95 * static_cast<double>(s->fsr.size()));
  FsrFitOptions fo;
  fo.full_scale = s->recorded_fsr->full_scale;
  Result<FsrCurve> c = fit_fsr(pairs, fo);
  ASSERT_TRUE(c.ok()) << c.status().to_string();
  // The spec's FSR: threshold 0.03, scale 50 N, exponent 1.4, raw noise 2 counts.
  EXPECT_EQ(c->model, FsrModel::kPowerLaw);
  EXPECT_NEAR(c->power_law.threshold, 0.03, std::max(4.0 * c->threshold_std, 1e-3));
  EXPECT_NEAR(c->power_law.scale_n, 50.0, std::max(4.0 * c->scale_n_std, 0.5));
  EXPECT_NEAR(c->power_law.exponent, 1.4, std::max(4.0 * c->exponent_std, 0.02));
  EXPECT_LT(c->power_law_quality.rms_n, 0.12);
  EXPECT_GT(c->power_law_quality.r2, 0.999);
  // Against the simulator's true force at the FSR readings: the fitted curve within 0.15 N RMS.
  double ss = 0.0;
  int n = 0;
  for (const FsrReading& r : s->fsr) {
    const std::optional<double> t = truth_force_at(*s, r.t_ns);
    if (!t || *t < 0.5) continue;
    ss += (c->to_newtons(r.raw) - *t) * (c->to_newtons(r.raw) - *t);
    ++n;
  }
  ASSERT_GT(n, 100);
  EXPECT_LT(std::sqrt(ss / n), 0.15);
}

TEST_F(SimForceSession, MissingChannelsAndMalformedFilesAreInvalidInput) {
  ScratchDir dir;
  testing::SimForceSpec spec;
  spec.record_fsr = false;
  spec.steps = 3;
  ASSERT_TRUE(testing::record_sim_force_session(dir / "ft_only.mcap", spec).ok());
  ForceSessionOptions o;
  o.want_fsr = true;
  Result<ForceSession> s = read_force_session(dir / "ft_only.mcap", o);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.status().message().find("no fsr channel"), std::string::npos);
  o.want_fsr = false;
  o.ft_device = "ft7";
  EXPECT_EQ(read_force_session(dir / "ft_only.mcap", o).status().code(),
            StatusCode::kInvalidArgument);

  ASSERT_TRUE(write_file_atomic(dir / "junk.mcap", "not an mcap file at all").ok());
  EXPECT_EQ(read_force_session(dir / "junk.mcap", {}).status().code(),
            StatusCode::kInvalidArgument);
  // Truncated copy of the recorded session (no footer).
  Result<std::string> bytes = read_file(*dir_ / "force.mcap");
  ASSERT_TRUE(bytes.ok());
  ASSERT_TRUE(write_file_atomic(dir / "cut.mcap", bytes->substr(0, bytes->size() / 2)).ok());
  Result<ForceSession> cut = read_force_session(dir / "cut.mcap", {});
  ASSERT_FALSE(cut.ok());
  EXPECT_NE(cut.status().code(), StatusCode::kOk);
  EXPECT_EQ(read_force_session(dir / "none.mcap", {}).status().code(), StatusCode::kNotFound);
}

}  // namespace
}  // namespace hc::calib
