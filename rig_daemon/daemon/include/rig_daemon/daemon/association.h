// Associates every camera frame and force sample with the trigger edge that caused it.
//
// * Frames: by Frame::trigger_index when the backend knows it (hardware-triggered simulated
//   cameras, firmware-latched samples); otherwise the latest rising edge at or before the frame's
//   host time, within max_frame_latency, not yet taken by that camera (a hardware-triggered camera
//   delivers one frame per edge, in order).
// * FSR samples: by trigger_index when set (triggered sampling), else the nearest sample in time.
// * Force-torque samples (a continuous stream): the sample nearest in host time to the edge.
//   The difference is the association error (reported; < 1 ms is the rig's bar, the Harp
//   devices' shared-clock sync is ±42 µs).
//
// The scheduler feeds edges, frames and samples as they arrive and collects SyncRecords once an
// edge has everything it waits for (or its deadline passed: then the record says what is missing).
#pragma once

#include <array>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "common/json.h"
#include "rig_daemon/devices/types.h"
#include "rig_daemon/session/session_records.h"

namespace hc::rig {

// session::SyncRecord (what /session/sync records) and the associator's own book-keeping.
struct SyncRecord : session::SyncRecord {
  bool edge_seen = false;          // the edge itself was read (a frame may name it first)
  std::int64_t first_seen_ns = 0;  // host time of the first thing that named this edge
};

struct AssociationStats {
  std::uint64_t edges = 0;
  std::uint64_t edges_complete = 0;
  std::uint64_t frames = 0;
  std::uint64_t frames_associated = 0;
  std::uint64_t fsr_samples = 0;
  std::uint64_t fsr_associated = 0;  // triggered FSR samples matched to an edge
  std::uint64_t edges_with_ft = 0;
  std::uint64_t edges_with_fsr = 0;
  std::int64_t max_abs_ft_error_ns = 0;
  std::int64_t max_abs_fsr_error_ns = 0;
  double mean_abs_ft_error_ns = 0.0;
  Json to_json() const;
};

class Associator {
 public:
  struct Options {
    std::vector<std::string> cameras;  // every edge waits for one frame from each
    bool want_ft = false;              // every edge waits for its nearest F/T sample
    bool want_fsr = false;             // every edge waits for an FSR sample
    std::int64_t max_frame_latency_ns = 500'000'000;
    std::int64_t max_sample_error_ns = 5'000'000;  // nearest sample farther than this: none
    std::int64_t deadline_ns = 1'000'000'000;      // an edge is closed this long after it fired
  };
  explicit Associator(Options options);

  void add_edge(const devices::TriggerEdge& edge);  // falling edges are ignored
  // The edge the frame belongs to (nullopt: none; counted).
  std::optional<std::uint64_t> add_frame(const std::string& camera, const devices::Frame& frame);
  void add_wrench(const devices::WrenchSample& sample);
  std::optional<std::uint64_t> add_fsr(const devices::FsrSample& sample);

  // Records of edges that are complete, or past their deadline, in edge order. Deadlines count
  // on the items' time line: min(clock_ns, latest host_ns added).
  std::vector<SyncRecord> take_ready(std::int64_t clock_ns);
  // Every open record (end of session), complete or not.
  std::vector<SyncRecord> take_all();
  // True when no edge is waiting.
  bool idle() const { return open_.empty(); }
  // True when edge `index` has been closed as complete or is complete now.
  bool complete(std::uint64_t index) const;
  const AssociationStats& stats() const { return stats_; }

 private:
  struct Sample {
    std::int64_t host_ns;
    std::uint64_t sequence;
    std::array<double, 3> force_n;
    std::uint32_t raw;
  };
  void try_nearest(SyncRecord& r, bool ft) const;
  bool ready(const SyncRecord& r) const;
  void finish(SyncRecord& r);

  Options options_;
  std::map<std::uint64_t, SyncRecord> open_;
  std::map<std::uint64_t, bool> closed_;  // index -> complete (recent ones)
  std::map<std::string, std::uint64_t> next_edge_for_camera_;
  std::deque<Sample> ft_;   // recent F/T samples (bounded)
  std::deque<Sample> fsr_;  // recent untriggered FSR samples (bounded)
  AssociationStats stats_;
  double ft_error_sum_ns_ = 0.0;
  std::int64_t latest_ns_ = INT64_MIN;  // the latest host_ns of anything added
};

}  // namespace hc::rig
