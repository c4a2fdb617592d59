// What the live page shows that the status snapshot does not: the recent force samples, the arm's
// last state, a thumbnail of each camera's latest frame, and the control cycle's timing. The
// session thread feeds it with a few cheap calls per control cycle (a short lock each, no
// allocation once warmed up, thumbnails only when the page asked for one); the HTTP server's
// publisher thread reads it. Nothing here can block the control loop for longer than a copy of a
// few hundred bytes.
#pragma once

#include <atomic>
#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "common/json.h"
#include "rig_daemon/devices/types.h"

namespace hc::rig {

// Control-cycle timing: how late each cycle woke and how long it worked, in log-spaced buckets
// (about 4 % wide from 1 µs to 10 s), so quantiles are cheap and memory is constant.
class CycleTimer {
 public:
  void add(std::int64_t period_ns, std::int64_t busy_ns);
  // {"cycles", "period_ns": {p50, p99, max, mean}, "busy_ns": {p50, p99, max, mean}}.
  Json to_json() const;
  void reset();

  static constexpr int kBuckets = 420;

 private:
  struct Histogram {
    std::uint64_t counts[kBuckets] = {};
    std::uint64_t n = 0;
    double sum = 0;
    std::int64_t max = 0;
    void add(std::int64_t v);
    double quantile(double q) const;
  };
  Histogram period_, busy_;
};

class LiveFeed {
 public:
  struct ForcePoint {
    std::int64_t host_ns = 0;
    float force_n = 0;  // magnitude
    float fz_n = 0;
  };
  struct Thumbnail {
    std::uint64_t sequence = 0;  // increases with every new thumbnail of this camera
    std::uint32_t width = 0, height = 0;
    std::vector<std::uint8_t> gray;  // width x height, 8-bit
    std::int64_t host_ns = 0;
    std::uint64_t frame_index = 0;
    std::uint32_t source_width = 0, source_height = 0;
  };

  static constexpr std::size_t kForceCapacity = 16384;
  static constexpr std::uint32_t kThumbnailWidth = 192;

  // ---- session thread ----
  void add_wrenches(const std::vector<devices::WrenchSample>& samples);
  void set_arm(const devices::ArmState& state);
  // Keeps a downscaled copy when a thumbnail of this camera was asked for since the last one.
  void offer_frame(const std::string& camera, const devices::Frame& frame);
  void add_cycle(std::int64_t period_ns, std::int64_t busy_ns);
  // A new session starts (cycle timing restarts; force history and thumbnails stay).
  void session_started();

  // ---- readers (any thread) ----
  // Force samples newer than `after_ns`, at most `max_points` (evenly thinned), oldest first.
  std::vector<ForcePoint> forces_since(std::int64_t after_ns, std::size_t max_points) const;
  std::optional<devices::ArmState> arm() const;
  // Asks every camera for a thumbnail of its next frame.
  void request_thumbnails();
  std::optional<Thumbnail> thumbnail(const std::string& camera) const;
  std::map<std::string, std::uint64_t> thumbnail_sequences() const;
  Json cycle_json() const;

 private:
  mutable std::mutex force_mutex_;
  std::vector<ForcePoint> ring_ = std::vector<ForcePoint>(kForceCapacity);
  std::size_t ring_head_ = 0;  // next write
  std::size_t ring_size_ = 0;

  mutable std::mutex arm_mutex_;
  std::optional<devices::ArmState> arm_;

  std::atomic<std::uint64_t> thumbnail_request_{0};
  mutable std::mutex thumb_mutex_;
  std::map<std::string, std::uint64_t> served_request_;  // camera -> request generation served
  std::map<std::string, Thumbnail> thumbnails_;

  mutable std::mutex cycle_mutex_;
  CycleTimer cycles_;
};

}  // namespace hc::rig
