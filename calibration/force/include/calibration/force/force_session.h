// Reading the force streams of a recorded session (rig_daemon/session/topics.h) for the
// force calibrations: the F/T sensor's raw wrench (counts / counts-per-unit, before any bias the
// device removed), the FSR's raw readings, the recorded device calibrations, and the simulator's
// true contact force when the session has one.
//
// Channels are found by their metadata "kind" ("force_torque", "fsr"), or by device name when one
// is given. Pairing FSR readings with the F/T reference is by host time: the F/T wrench is
// interpolated linearly at each FSR reading's host time between the two F/T samples around it
// (both streams are stamped on the same host monotonic clock; the F/T runs at ~1 kHz, so the
// interpolation error is far below the sensor noise). Trigger association (/session/sync) would
// pair them too, but rigd's plans record either the FSR (hand-held) or the F/T (automated) with
// the trigger, never both, so time is the pairing every session supports.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "calibration/force/fsr_fit.h"
#include "calibration/force/ft_bias.h"
#include "common/status.h"

namespace hc::calib {

struct FsrReading {
  std::int64_t t_ns = 0;
  double raw = 0.0;
  std::optional<std::uint64_t> trigger_index;
};

struct TruthForce {
  std::int64_t t_ns = 0;
  double force_n = 0.0;
};

struct ForceSession {
  std::string ft_device;   // empty: no F/T channel
  std::string fsr_device;  // empty: no FSR channel
  double counts_per_n = 1'000'000.0;
  double counts_per_nm = 1'000'000.0;
  std::vector<WrenchReading> wrench;  // sorted by time
  std::vector<FsrReading> fsr;        // sorted by time
  // The FSR calibration the session recorded (metadata "calibration"), when present.
  std::optional<FsrPowerLaw> recorded_fsr;
  std::vector<TruthForce> truth;  // /sim/ground_truth, sorted by time (simulated rigs only)
};

struct ForceSessionOptions {
  std::string ft_device;   // "" = the first force_torque channel
  std::string fsr_device;  // "" = the first fsr channel
  bool want_ft = true;
  bool want_fsr = false;
  bool want_truth = true;
};

// Reads the session. kNotFound / kIoError for the file, kInvalidArgument for a file that is not
// MCAP, a wanted channel that is missing or empty, or a message that does not decode (the message
// names the topic and sequence).
Result<ForceSession> read_force_session(const std::filesystem::path& path,
                                        const ForceSessionOptions& options);

// FSR readings paired with the F/T reference force |F - bias(t)| (norm of the bias-corrected force
// vector, so the sensor's mounting orientation does not matter). Readings with no F/T sample
// within max_gap_ns on both sides are skipped.
std::vector<FsrPair> pair_fsr_with_ft(const ForceSession& session, const FtBiasResult& bias,
                                      std::int64_t max_gap_ns = 2'000'000);

// The true force interpolated at t_ns (nullopt outside the truth samples or with a gap > 2 ms
// around t_ns).
std::optional<double> truth_force_at(const ForceSession& session, std::int64_t t_ns);

}  // namespace hc::calib
