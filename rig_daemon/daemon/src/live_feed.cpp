#include "rig_daemon/daemon/live_feed.h"

#include <algorithm>
#include <cmath>

namespace hc::rig {
namespace {

constexpr double kBucketRatio = 1.04;  // ~4 % wide buckets
constexpr int kFirstBucketExponent = 170;  // 1.04^170 ≈ 790 ns: everything below lands in bucket 0

int bucket_of(std::int64_t v) {
  if (v <= 1) return 0;
  const int b = static_cast<int>(std::floor(std::log(static_cast<double>(v)) / std::log(kBucketRatio))) -
                kFirstBucketExponent;
  return std::clamp(b, 0, CycleTimer::kBuckets - 1);
}

double bucket_middle(int b) {
  return std::pow(kBucketRatio, b + kFirstBucketExponent + 0.5);
}

// The luminance of pixel (x, y) for the uncompressed formats (0 for others).
std::uint8_t luminance(const devices::Frame& f, std::uint32_t x, std::uint32_t y) {
  const std::uint8_t* row = f.pixels.data() + static_cast<std::size_t>(y) * f.stride_bytes;
  switch (f.format) {
    case devices::PixelFormat::kMono8:
      return row[x];
    case devices::PixelFormat::kMono16:
      return row[2 * x + 1];  // little-endian: the high byte
    case devices::PixelFormat::kRgb8:
    case devices::PixelFormat::kBgr8: {
      const std::uint8_t* p = row + 3 * x;
      // Rec. 601 luma; the weights of R and B are close enough that their order does not matter
      // for a thumbnail.
      return static_cast<std::uint8_t>((77 * p[0] + 150 * p[1] + 29 * p[2]) >> 8);
    }
    case devices::PixelFormat::kYuyv:
      return row[2 * x];
    case devices::PixelFormat::kMjpeg:
      return 0;
  }
  return 0;
}

}  // namespace

void CycleTimer::Histogram::add(std::int64_t v) {
  ++counts[bucket_of(v)];
  ++n;
  sum += static_cast<double>(v);
  max = std::max(max, v);
}

double CycleTimer::Histogram::quantile(double q) const {
  if (n == 0) return 0;
  const auto want = static_cast<std::uint64_t>(std::ceil(q * static_cast<double>(n)));
  std::uint64_t seen = 0;
  for (int b = 0; b < kBuckets; ++b) {
    seen += counts[b];
    if (seen >= want) return std::min(bucket_middle(b), static_cast<double>(max));
  }
  return static_cast<double>(max);
}

void CycleTimer::add(std::int64_t period_ns, std::int64_t busy_ns) {
  period_.add(period_ns);
  busy_.add(busy_ns);
}

void CycleTimer::reset() {
  period_ = Histogram{};
  busy_ = Histogram{};
}

Json CycleTimer::to_json() const {
  const auto stats = [](const Histogram& h) {
    return Json{{"p50", h.quantile(0.5)},
                {"p99", h.quantile(0.99)},
                {"max", h.max},
                {"mean", h.n > 0 ? h.sum / static_cast<double>(h.n) : 0.0}};
  };
  return Json{{"cycles", period_.n}, {"period_ns", stats(period_)}, {"busy_ns", stats(busy_)}};
}

void LiveFeed::add_wrenches(const std::vector<devices::WrenchSample>& samples) {
  if (samples.empty()) return;
  std::lock_guard lock(force_mutex_);
  for (const devices::WrenchSample& s : samples) {
    const double f = std::sqrt(s.force_n[0] * s.force_n[0] + s.force_n[1] * s.force_n[1] +
                               s.force_n[2] * s.force_n[2]);
    ring_[ring_head_] = {s.host_ns, static_cast<float>(f), static_cast<float>(s.force_n[2])};
    ring_head_ = (ring_head_ + 1) % kForceCapacity;
    ring_size_ = std::min(ring_size_ + 1, kForceCapacity);
  }
}

void LiveFeed::set_arm(const devices::ArmState& state) {
  std::lock_guard lock(arm_mutex_);
  arm_ = state;
}

void LiveFeed::offer_frame(const std::string& camera, const devices::Frame& frame) {
  const std::uint64_t request = thumbnail_request_.load(std::memory_order_relaxed);
  if (request == 0 || !frame.valid() || frame.format == devices::PixelFormat::kMjpeg) return;
  {
    std::lock_guard lock(thumb_mutex_);
    if (served_request_[camera] >= request) return;
    served_request_[camera] = request;
  }
  // Point sampling (not block averaging): a 1600x1200 frame costs ~25k reads, well inside a
  // control cycle, where averaging would read all 1.9M pixels.
  const std::uint32_t step = std::max<std::uint32_t>(1, (frame.width + kThumbnailWidth - 1) / kThumbnailWidth);
  Thumbnail t;
  t.width = frame.width / step;
  t.height = frame.height / step;
  if (t.width == 0 || t.height == 0) return;
  t.gray.resize(static_cast<std::size_t>(t.width) * t.height);
  for (std::uint32_t y = 0; y < t.height; ++y)
    for (std::uint32_t x = 0; x < t.width; ++x)
      t.gray[static_cast<std::size_t>(y) * t.width + x] = luminance(frame, x * step, y * step);
  t.host_ns = frame.host_ns;
  t.frame_index = frame.frame_index;
  t.source_width = frame.width;
  t.source_height = frame.height;
  std::lock_guard lock(thumb_mutex_);
  Thumbnail& slot = thumbnails_[camera];
  t.sequence = slot.sequence + 1;
  slot = std::move(t);
}

void LiveFeed::add_cycle(std::int64_t period_ns, std::int64_t busy_ns) {
  std::lock_guard lock(cycle_mutex_);
  cycles_.add(period_ns, busy_ns);
}

void LiveFeed::session_started() {
  std::lock_guard lock(cycle_mutex_);
  cycles_.reset();
}

std::vector<LiveFeed::ForcePoint> LiveFeed::forces_since(std::int64_t after_ns,
                                                         std::size_t max_points) const {
  std::vector<ForcePoint> out;
  {
    std::lock_guard lock(force_mutex_);
    // Walk back from the newest to the first sample not newer than after_ns.
    std::size_t n = 0;
    while (n < ring_size_) {
      const ForcePoint& p = ring_[(ring_head_ + kForceCapacity - 1 - n) % kForceCapacity];
      if (p.host_ns <= after_ns) break;
      ++n;
    }
    out.reserve(n);
    for (std::size_t k = n; k > 0; --k)
      out.push_back(ring_[(ring_head_ + kForceCapacity - k) % kForceCapacity]);
  }
  if (max_points > 0 && out.size() > max_points) {
    // Keep max_points evenly spread, always including the newest.
    std::vector<ForcePoint> thin;
    thin.reserve(max_points);
    for (std::size_t k = 0; k < max_points; ++k)
      thin.push_back(out[(k + 1) * out.size() / max_points - 1]);
    out = std::move(thin);
  }
  return out;
}

std::optional<devices::ArmState> LiveFeed::arm() const {
  std::lock_guard lock(arm_mutex_);
  return arm_;
}

void LiveFeed::request_thumbnails() { thumbnail_request_.fetch_add(1); }

std::optional<LiveFeed::Thumbnail> LiveFeed::thumbnail(const std::string& camera) const {
  std::lock_guard lock(thumb_mutex_);
  const auto it = thumbnails_.find(camera);
  if (it == thumbnails_.end()) return std::nullopt;
  return it->second;
}

std::map<std::string, std::uint64_t> LiveFeed::thumbnail_sequences() const {
  std::map<std::string, std::uint64_t> out;
  std::lock_guard lock(thumb_mutex_);
  for (const auto& [name, t] : thumbnails_) out[name] = t.sequence;
  return out;
}

Json LiveFeed::cycle_json() const {
  std::lock_guard lock(cycle_mutex_);
  return cycles_.to_json();
}

}  // namespace hc::rig
