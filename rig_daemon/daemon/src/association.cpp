#include "rig_daemon/daemon/association.h"

#include <algorithm>
#include <limits>

namespace hc::rig {
namespace {
// Recent samples kept for nearest-in-time matching: 2 s of a 7 kHz F/T stream.
constexpr std::size_t kMaxKeptSamples = 14000;
// Closed edges remembered (for late frames and complete()).
constexpr std::size_t kMaxClosed = 100000;
std::int64_t abs_ns(std::int64_t v) { return v < 0 ? -v : v; }
}  // namespace

Json AssociationStats::to_json() const {
  const auto ratio = [](std::uint64_t a, std::uint64_t b) {
    return b == 0 ? 1.0 : double(a) / double(b);
  };
  return Json{{"edges", edges},
              {"edges_complete", edges_complete},
              {"frames", frames},
              {"frames_associated", frames_associated},
              {"fsr_samples", fsr_samples},
              {"fsr_associated", fsr_associated},
              {"edges_with_ft", edges_with_ft},
              {"edges_with_fsr", edges_with_fsr},
              {"max_abs_ft_error_ns", max_abs_ft_error_ns},
              {"max_abs_fsr_error_ns", max_abs_fsr_error_ns},
              {"mean_abs_ft_error_ns", mean_abs_ft_error_ns},
              {"frame_association", ratio(frames_associated, frames)},
              {"edge_completeness", ratio(edges_complete, edges)}};
}

Associator::Associator(Options options) : options_(std::move(options)) {}

void Associator::add_edge(const devices::TriggerEdge& edge) {
  latest_ns_ = std::max(latest_ns_, edge.host_ns);
  if (!edge.rising) return;
  if (closed_.count(edge.index)) return;  // duplicate
  SyncRecord& r = open_[edge.index];
  if (!r.edge_seen) {
    r.trigger_index = edge.index;
    r.edge_seen = true;
    r.edge_host_ns = edge.host_ns;
    if (r.first_seen_ns == 0) r.first_seen_ns = edge.host_ns;
    ++stats_.edges;
  }
}

std::optional<std::uint64_t> Associator::add_frame(const std::string& camera,
                                                   const devices::Frame& frame) {
  ++stats_.frames;
  latest_ns_ = std::max(latest_ns_, frame.host_ns);
  std::optional<std::uint64_t> index = frame.trigger_index;
  if (!index) {
    // The latest edge at or before the frame, within the latency bound, that this camera has not
    // used yet.
    const std::uint64_t from = next_edge_for_camera_[camera];
    for (auto it = open_.rbegin(); it != open_.rend(); ++it) {
      const SyncRecord& r = it->second;
      if (!r.edge_seen || it->first < from) continue;
      if (r.edge_host_ns <= frame.host_ns &&
          frame.host_ns - r.edge_host_ns <= options_.max_frame_latency_ns) {
        index = it->first;
        break;
      }
    }
  }
  if (!index) return std::nullopt;
  if (auto c = closed_.find(*index); c != closed_.end()) {
    // Its record was already written (the frame came after the deadline): still associated.
    ++stats_.frames_associated;
    return index;
  }
  SyncRecord& r = open_[*index];
  if (!r.edge_seen && r.first_seen_ns == 0) {
    r.trigger_index = *index;
    r.first_seen_ns = frame.host_ns;
  }
  if (r.frames.count(camera)) return std::nullopt;  // a second frame for one edge: not this edge's
  r.frames[camera] = frame.frame_index;
  next_edge_for_camera_[camera] = *index + 1;
  ++stats_.frames_associated;
  return index;
}

void Associator::add_wrench(const devices::WrenchSample& s) {
  latest_ns_ = std::max(latest_ns_, s.host_ns);
  ft_.push_back(Sample{s.host_ns, s.sequence, s.force_n, 0});
  while (ft_.size() > kMaxKeptSamples) ft_.pop_front();
}

std::optional<std::uint64_t> Associator::add_fsr(const devices::FsrSample& s) {
  ++stats_.fsr_samples;
  latest_ns_ = std::max(latest_ns_, s.host_ns);
  if (!s.trigger_index) {
    fsr_.push_back(Sample{s.host_ns, s.sequence, {s.force_n, 0, 0}, s.raw});
    while (fsr_.size() > kMaxKeptSamples) fsr_.pop_front();
    return std::nullopt;
  }
  const std::uint64_t index = *s.trigger_index;
  if (closed_.count(index)) {
    ++stats_.fsr_associated;
    return index;
  }
  SyncRecord& r = open_[index];
  if (!r.edge_seen && r.first_seen_ns == 0) {
    r.trigger_index = index;
    r.first_seen_ns = s.host_ns;
  }
  if (!r.fsr_sequence) {
    r.fsr_sequence = s.sequence;
    r.fsr_raw = s.raw;
    r.fsr_force_n = s.force_n;
    r.fsr_error_ns = r.edge_seen ? s.host_ns - r.edge_host_ns : 0;
  }
  ++stats_.fsr_associated;
  return index;
}

void Associator::try_nearest(SyncRecord& r, bool ft) const {
  const std::deque<Sample>& q = ft ? ft_ : fsr_;
  if (q.empty() || !r.edge_seen) return;
  // First sample at or after the edge; the nearest is it or its predecessor. Without one after
  // the edge the nearest is not known yet (unless the caller forces it at the deadline).
  auto after = std::lower_bound(q.begin(), q.end(), r.edge_host_ns,
                                [](const Sample& a, std::int64_t t) { return a.host_ns < t; });
  if (after == q.end()) return;
  const Sample* best = &*after;
  if (after != q.begin()) {
    const Sample& before = *std::prev(after);
    if (r.edge_host_ns - before.host_ns < after->host_ns - r.edge_host_ns) best = &before;
  }
  const std::int64_t err = best->host_ns - r.edge_host_ns;
  if (abs_ns(err) > options_.max_sample_error_ns) return;
  if (ft) {
    r.ft_sequence = best->sequence;
    r.ft_error_ns = err;
    r.force_n = best->force_n;
  } else {
    r.fsr_sequence = best->sequence;
    r.fsr_error_ns = err;
    r.fsr_raw = best->raw;
    r.fsr_force_n = best->force_n[0];
  }
}

bool Associator::ready(const SyncRecord& r) const {
  if (!r.edge_seen) return false;
  for (const std::string& c : options_.cameras)
    if (!r.frames.count(c)) return false;
  if (options_.want_ft && !r.ft_sequence) return false;
  if (options_.want_fsr && !r.fsr_sequence) return false;
  return true;
}

void Associator::finish(SyncRecord& r) {
  r.complete = ready(r);
  for (const std::string& c : options_.cameras)
    if (!r.frames.count(c)) r.missing_cameras.push_back(c);
  if (r.complete) ++stats_.edges_complete;
  if (r.ft_sequence) {
    ++stats_.edges_with_ft;
    const std::int64_t e = abs_ns(r.ft_error_ns);
    stats_.max_abs_ft_error_ns = std::max(stats_.max_abs_ft_error_ns, e);
    ft_error_sum_ns_ += static_cast<double>(e);
    stats_.mean_abs_ft_error_ns = ft_error_sum_ns_ / static_cast<double>(stats_.edges_with_ft);
  }
  if (r.fsr_sequence) {
    ++stats_.edges_with_fsr;
    stats_.max_abs_fsr_error_ns = std::max(stats_.max_abs_fsr_error_ns, abs_ns(r.fsr_error_ns));
  }
  closed_[r.trigger_index] = r.complete;
  while (closed_.size() > kMaxClosed) closed_.erase(closed_.begin());
}

std::vector<SyncRecord> Associator::take_ready(std::int64_t clock_ns) {
  // Deadlines run on the items' own time line: a replay serves recorded host times while its
  // clock reads something else, and live items never carry a time later than the clock.
  const std::int64_t now_ns = std::min(clock_ns, latest_ns_);
  std::vector<SyncRecord> out;
  for (auto it = open_.begin(); it != open_.end();) {
    SyncRecord& r = it->second;
    if (r.edge_seen) {
      if (options_.want_ft && !r.ft_sequence) try_nearest(r, true);
      if (options_.want_fsr && !r.fsr_sequence) try_nearest(r, false);
    }
    const std::int64_t t0 = r.edge_seen ? r.edge_host_ns : r.first_seen_ns;
    const bool expired = now_ns - t0 > options_.deadline_ns;
    if (!ready(r) && !expired) {
      // Records close in edge order: a later edge waits for an earlier one.
      break;
    }
    if (!r.edge_seen && expired) {
      // Named by a frame or sample, but the edge itself never arrived: an edge was lost.
      r.edge_host_ns = r.first_seen_ns;
    }
    finish(r);
    out.push_back(std::move(r));
    it = open_.erase(it);
  }
  // Forget samples no open edge can need any more.
  // An open record whose edge has not arrived holds the lowest int64 as its time: saturate.
  const std::int64_t base = open_.empty() ? now_ns : open_.begin()->second.edge_host_ns;
  const std::int64_t keep_from =
      base < std::numeric_limits<std::int64_t>::min() + options_.max_sample_error_ns
          ? std::numeric_limits<std::int64_t>::min()
          : base - options_.max_sample_error_ns;
  while (!ft_.empty() && ft_.front().host_ns < keep_from && ft_.size() > 2) ft_.pop_front();
  while (!fsr_.empty() && fsr_.front().host_ns < keep_from && fsr_.size() > 2) fsr_.pop_front();
  return out;
}

std::vector<SyncRecord> Associator::take_all() {
  std::vector<SyncRecord> out;
  for (auto& [index, r] : open_) {
    if (r.edge_seen) {
      if (options_.want_ft && !r.ft_sequence) try_nearest(r, true);
      if (options_.want_fsr && !r.fsr_sequence) try_nearest(r, false);
    } else {
      r.edge_host_ns = r.first_seen_ns;
    }
    finish(r);
    out.push_back(std::move(r));
  }
  open_.clear();
  return out;
}

bool Associator::complete(std::uint64_t index) const {
  if (auto c = closed_.find(index); c != closed_.end()) return c->second;
  auto o = open_.find(index);
  return o != open_.end() && ready(o->second);
}

}  // namespace hc::rig
