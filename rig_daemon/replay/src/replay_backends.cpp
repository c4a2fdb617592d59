// The "replay" backends: every device kind served from a recorded session (replay.h).
#include <algorithm>
#include <deque>
#include <limits>
#include <string>
#include <string_view>

#include "rig_daemon/devices/registry.h"
#include "rig_daemon/recording/foxglove_image.h"
#include "rig_daemon/replay/replay.h"
#include "rig_daemon/session/codec.h"

namespace hc::devices {

namespace {

constexpr std::size_t kMaxBatch = 4096;
constexpr std::int64_t kForever = std::numeric_limits<std::int64_t>::max();
constexpr std::int64_t kPrefetchNs = 1'000'000'000;  // time series read ahead per slice

std::string_view text(const ReplaySession::Message& m) {
  return {reinterpret_cast<const char*>(m.data.data()), m.data.size()};
}

Result<Frame> decode_frame(const ReplaySession::Message& m) {
  HC_ASSIGN_OR_RETURN(recording::RawImage img, recording::decode_raw_image(m.data));
  std::optional<PixelFormat> format = pixel_format_from_string(img.encoding);
  if (!format || *format == PixelFormat::kMjpeg)
    return unsupported("replay: image encoding '" + img.encoding + "' is not a camera format");
  Frame f;
  f.format = *format;
  f.width = img.width;
  f.height = img.height;
  f.stride_bytes = img.step;
  f.pixels = std::move(img.data);
  f.frame_id = m.sequence;
  f.host_ns = m.log_time_ns;
  // The recorder stores the device stamp as publish_time (the host time when there is none).
  if (m.publish_time_ns != m.log_time_ns) f.device_stamp_ns = m.publish_time_ns;
  if (!f.valid()) return invalid_argument("replay: image buffer smaller than its size says");
  return f;
}

template <typename Item>
Result<Item> decode(const ReplaySession::Message& m);
template <>
Result<TriggerEdge> decode(const ReplaySession::Message& m) {
  return session::trigger_edge_from_json(text(m));
}
template <>
Result<FsrSample> decode(const ReplaySession::Message& m) {
  return session::fsr_sample_from_json(text(m));
}
template <>
Result<WrenchSample> decode(const ReplaySession::Message& m) {
  return session::wrench_sample_from_json(text(m));
}
template <>
Result<Frame> decode(const ReplaySession::Message& m) {
  return decode_frame(m);
}

// The counter whose gaps mean lost items, and its wrap (0 = none).
std::uint64_t counter(const TriggerEdge& e) { return e.index; }
std::uint64_t counter(const FsrSample& s) { return s.sequence; }
std::uint64_t counter(const WrenchSample& s) { return s.sequence; }
std::uint64_t counter(const Frame& f) { return f.frame_id; }
std::uint64_t counter_wrap(const Frame&) { return 1u << 16; }
template <typename Item>
std::uint64_t counter_wrap(const Item&) {
  return 0;
}

// The session a replay device serves (from its factory), and the stream in it.
struct ReplayBinding {
  std::shared_ptr<ReplaySession> session;
  const ReplaySession::Stream* stream = nullptr;

  Status bind(const DeviceContext& ctx, ConfigNode node, DeviceKind kind) {
    std::string source = ctx.name;
    node.optional("source", source);
    HC_RETURN_IF_ERROR(node.status());
    stream = session->find(source, kind);
    if (!stream)
      return not_found("replay: the session has no " + std::string(to_string(kind)) +
                       " stream of device '" + source + "'");
    return {};
  }
  // The bound stream's mean message rate over the session.
  double rate_hz() const {
    const double span_s = (session->end_ns() - session->start_ns()) * 1e-9;
    return span_s > 0.0 ? stream->messages / span_s : 0.0;
  }
};

// Items of one stream in log-time order, read in slices as the replay clock reaches them.
template <typename Item>
class ReplayCursor {
 public:
  // prefetch_ns: recorded time read ahead per slice, so that a chunk is decompressed about once
  // per slice rather than once per read() (1 s for time series; 0 for frames, which are big).
  void reset(const ReplayBinding* b, std::int64_t prefetch_ns) {
    binding_ = b;
    prefetch_ns_ = prefetch_ns;
    next_ns_ = std::numeric_limits<std::int64_t>::min();
    skip_ = 0;
    pending_.clear();
    exhausted_ = false;
    last_counter_.reset();
  }
  // Loads at least one more item if there is one (up to `limit` recorded time, or the next one).
  Status fill(std::int64_t recorded_now) {
    if (!pending_.empty() || exhausted_) return {};
    const std::int64_t from = std::max<std::int64_t>(0, next_ns_);
    std::size_t seen_at_next = 0;
    std::size_t taken = 0;
    std::size_t limit = kMaxBatch * 16;  // items one read may take
    Status decode_status;
    const std::int64_t to =
        std::max(recorded_now + 1, from + std::max<std::int64_t>(1, prefetch_ns_));
    auto visit = [&](const ReplaySession::Message& m) {
      if (m.log_time_ns < next_ns_) return true;  // taken in an earlier slice
      if (m.log_time_ns == next_ns_ && seen_at_next < skip_) {
        ++seen_at_next;
        return true;
      }
      Result<Item> item = decode<Item>(m);
      if (!item.ok()) {
        decode_status = item.status().with_context(binding_->stream->topic);
        return false;
      }
      item->host_ns = m.log_time_ns;
      pending_.push_back(std::move(item).value());
      if (m.log_time_ns == next_ns_) {
        ++skip_;
      } else {
        next_ns_ = m.log_time_ns;
        skip_ = 1;
      }
      return ++taken < limit;
    };
    HC_RETURN_IF_ERROR(binding_->session->read(*binding_->stream, from, to, visit));
    HC_RETURN_IF_ERROR(decode_status);
    if (pending_.empty() && to != kForever) {
      // Nothing due yet: look one item ahead so the reader knows how long to wait.
      seen_at_next = 0;
      taken = 0;
      limit = 1;
      HC_RETURN_IF_ERROR(binding_->session->read(*binding_->stream, from, kForever, visit));
      HC_RETURN_IF_ERROR(decode_status);
      if (pending_.empty()) exhausted_ = true;
    }
    return {};
  }
  bool empty() const { return pending_.empty(); }
  bool exhausted() const { return exhausted_ && pending_.empty(); }
  const Item& front() const { return pending_.front(); }
  // Pops the front item; returns how many items its counter says were skipped before it.
  std::uint64_t pop(Item& out) {
    out = std::move(pending_.front());
    pending_.pop_front();
    const std::uint64_t c = counter(out);
    const std::uint64_t wrap = counter_wrap(out);
    std::uint64_t lost = 0;
    if (last_counter_) {
      std::uint64_t step = c - *last_counter_;
      if (wrap) step = (c + wrap - *last_counter_) % wrap;
      if (step > 1 && (wrap || c > *last_counter_)) lost = step - 1;
    }
    last_counter_ = c;
    return lost;
  }

 private:
  const ReplayBinding* binding_ = nullptr;
  std::int64_t prefetch_ns_ = 0;
  std::int64_t next_ns_ = 0;
  std::size_t skip_ = 0;  // items at log time next_ns_ already taken
  std::deque<Item> pending_;
  bool exhausted_ = false;
  std::optional<std::uint64_t> last_counter_;
};

// The read loop of every replayed stream: items become available at their due clock time.
template <typename Item, typename Counters>
Result<std::size_t> replay_read(Clock& clock, ReplayBinding& b, ReplayCursor<Item>& cursor,
                                std::vector<Item>& out, Duration timeout, Counters&& count_lost) {
  const std::int64_t deadline = clock.now_ns() + std::max<std::int64_t>(0, timeout.count());
  const std::size_t before = out.size();
  while (true) {
    const std::int64_t now = clock.now_ns();
    const std::int64_t recorded_now = b.session->recorded_ns_at(now);
    while (out.size() - before < kMaxBatch) {
      HC_RETURN_IF_ERROR(cursor.fill(recorded_now));
      if (cursor.empty() || b.session->due_clock_ns(cursor.front().host_ns) > now) break;
      Item item;
      count_lost(cursor.pop(item));
      out.push_back(std::move(item));
    }
    if (out.size() > before) return out.size() - before;
    if (now >= deadline) return std::size_t{0};
    std::int64_t wake = deadline;
    if (!cursor.empty()) wake = std::min(wake, b.session->due_clock_ns(cursor.front().host_ns));
    clock.sleep_until_ns(std::max(wake, now + 1));
  }
}

Status bind_and_anchor(ReplayBinding& b, const Clock& clock) {
  if (!b.session) return failed_precondition("replay: not configured");
  b.session->anchor(clock);
  return {};
}

// ------------------------------------------------------------------------------------------------
class ReplayCamera final : public Camera {
 public:
  ReplayCamera(const DeviceContext& ctx, std::shared_ptr<ReplaySession> session)
      : Camera(ctx), binding_{std::move(session), nullptr} {}
  CameraInfo camera_info() const override { return info_; }

 protected:
  Status on_configure(ConfigNode node) override {
    HC_RETURN_IF_ERROR(binding_.bind(context(), node, kKind));
    // The stream's size and format, from its first frame.
    Status s = binding_.session->read(*binding_.stream, 0, kForever, [&](const auto& m) {
      Result<Frame> f = decode_frame(m);
      if (f.ok()) {
        info_.width = f->width;
        info_.height = f->height;
        info_.format = f->format;
      }
      return false;
    });
    info_.trigger_mode = TriggerMode::kHardware;
    return s;
  }
  Status on_activate() override {
    HC_RETURN_IF_ERROR(bind_and_anchor(binding_, clock()));
    cursor_.reset(&binding_, 0);
    index_ = 0;
    return {};
  }
  Status on_deactivate() override { return {}; }
  Result<std::size_t> on_read(std::vector<Frame>& out, Duration timeout) override {
    const std::size_t before = out.size();
    Result<std::size_t> n =
        replay_read(clock(), binding_, cursor_, out, timeout, [&](std::uint64_t lost) {
          count_lost(lost);
          index_ += lost;
        });
    for (std::size_t i = before; i < out.size(); ++i) out[i].frame_index = index_++;
    return n;
  }
  Status on_software_trigger() override { return {}; }  // frames come as recorded
  void describe(DeviceInfo& info) const override {
    info.model = "replay of " + binding_.stream->device + " (" + binding_.stream->backend + ")";
  }

 private:
  ReplayBinding binding_;
  ReplayCursor<Frame> cursor_;
  CameraInfo info_;
  std::uint64_t index_ = 0;
};

class ReplayTrigger final : public Trigger {
 public:
  ReplayTrigger(const DeviceContext& ctx, std::shared_ptr<ReplaySession> session)
      : Trigger(ctx), binding_{std::move(session), nullptr} {}
  bool running() const override { return false; }  // the recorded edges come regardless
  std::vector<std::uint32_t> lines() const override { return lines_; }

 protected:
  Status on_configure(ConfigNode node) override {
    HC_RETURN_IF_ERROR(binding_.bind(context(), node, kKind));
    lines_.clear();
    Status s = binding_.session->read(*binding_.stream, 0, kForever, [&](const auto& m) {
      Result<TriggerEdge> e = session::trigger_edge_from_json(text(m));
      if (!e.ok()) return true;
      if (std::find(lines_.begin(), lines_.end(), e->line) != lines_.end()) return false;
      lines_.push_back(e->line);
      return lines_.size() < 64;
    });
    return s;
  }
  Status on_activate() override {
    HC_RETURN_IF_ERROR(bind_and_anchor(binding_, clock()));
    cursor_.reset(&binding_, kPrefetchNs);
    return {};
  }
  Status on_deactivate() override { return {}; }
  Status on_start(const PulseTrain&) override { return {}; }
  Status on_stop() override { return {}; }
  Status on_fire() override { return {}; }
  Result<std::size_t> on_read(std::vector<TriggerEdge>& out, Duration timeout) override {
    return replay_read(clock(), binding_, cursor_, out, timeout, [&](std::uint64_t lost) {
      count_lost(lost * std::max<std::size_t>(1, lines_.size()));
    });
  }

 private:
  ReplayBinding binding_;
  ReplayCursor<TriggerEdge> cursor_;
  std::vector<std::uint32_t> lines_;
};

class ReplayFsr final : public Fsr {
 public:
  ReplayFsr(const DeviceContext& ctx, std::shared_ptr<ReplaySession> session)
      : Fsr(ctx), binding_{std::move(session), nullptr} {}
  FsrCalibration calibration() const override { return cal_; }
  double sample_rate_hz() const override { return rate_hz_; }

 protected:
  Status on_configure(ConfigNode node) override {
    read_calibration(node, &cal_);
    HC_RETURN_IF_ERROR(binding_.bind(context(), node, kKind));
    rate_hz_ = binding_.rate_hz();
    return {};
  }
  Status on_activate() override {
    HC_RETURN_IF_ERROR(bind_and_anchor(binding_, clock()));
    cursor_.reset(&binding_, kPrefetchNs);
    return {};
  }
  Status on_deactivate() override { return {}; }
  Result<std::size_t> on_read(std::vector<FsrSample>& out, Duration timeout) override {
    return replay_read(clock(), binding_, cursor_, out, timeout,
                       [&](std::uint64_t n) { count_lost(n); });
  }

 private:
  ReplayBinding binding_;
  ReplayCursor<FsrSample> cursor_;
  FsrCalibration cal_;
  double rate_hz_ = 0.0;
};

class ReplayForceTorque final : public ForceTorque {
 public:
  ReplayForceTorque(const DeviceContext& ctx, std::shared_ptr<ReplaySession> session)
      : ForceTorque(ctx), binding_{std::move(session), nullptr} {}
  WrenchCalibration calibration() const override { return cal_; }
  double sample_rate_hz() const override { return rate_hz_; }

 protected:
  Status on_configure(ConfigNode node) override {
    node.optional("counts_per_n", cal_.counts_per_n, Bounds::positive());
    node.optional("counts_per_nm", cal_.counts_per_nm, Bounds::positive());
    HC_RETURN_IF_ERROR(binding_.bind(context(), node, kKind));
    rate_hz_ = binding_.rate_hz();
    return {};
  }
  Status on_activate() override {
    HC_RETURN_IF_ERROR(bind_and_anchor(binding_, clock()));
    cursor_.reset(&binding_, kPrefetchNs);
    return {};
  }
  Status on_deactivate() override { return {}; }
  Result<std::size_t> on_read(std::vector<WrenchSample>& out, Duration timeout) override {
    return replay_read(clock(), binding_, cursor_, out, timeout,
                       [&](std::uint64_t n) { count_lost(n); });
  }
  // The recorded SI values already have the recorded bias; replay keeps them as they are.
  Status on_bias() override { return {}; }
  Status on_clear_bias() override { return {}; }

 private:
  ReplayBinding binding_;
  ReplayCursor<WrenchSample> cursor_;
  WrenchCalibration cal_;
  double rate_hz_ = 0.0;
};

class ReplayArm final : public Arm {
 public:
  ReplayArm(const DeviceContext& ctx, std::shared_ptr<ReplaySession> session)
      : Arm(ctx), binding_{std::move(session), nullptr} {}
  ArmLimits limits() const override { return limits_; }

 protected:
  Status on_configure(ConfigNode node) override {
    HC_RETURN_IF_ERROR(binding_.bind(context(), node, kKind));
    states_.clear();
    Status decode_status;
    Status s = binding_.session->read(*binding_.stream, 0, kForever, [&](const auto& m) {
      Result<ArmState> st = session::arm_state_from_json(text(m));
      if (!st.ok()) {
        decode_status = st.status().with_context(binding_.stream->topic);
        return false;
      }
      st->host_ns = m.log_time_ns;
      states_.push_back(std::move(st).value());
      return true;
    });
    HC_RETURN_IF_ERROR(s);
    HC_RETURN_IF_ERROR(decode_status);
    if (states_.empty())
      return not_found("replay: the arm stream of '" + binding_.stream->device + "' is empty");
    // The recorded arm stayed inside its limits; report a box around what it did.
    limits_.min = limits_.max = states_.front().pose;
    for (const ArmState& st : states_) {
      limits_.min.x_m = std::min(limits_.min.x_m, st.pose.x_m);
      limits_.min.y_m = std::min(limits_.min.y_m, st.pose.y_m);
      limits_.min.z_m = std::min(limits_.min.z_m, st.pose.z_m);
      limits_.min.yaw_rad = std::min(limits_.min.yaw_rad, st.pose.yaw_rad);
      limits_.max.x_m = std::max(limits_.max.x_m, st.pose.x_m);
      limits_.max.y_m = std::max(limits_.max.y_m, st.pose.y_m);
      limits_.max.z_m = std::max(limits_.max.z_m, st.pose.z_m);
      limits_.max.yaw_rad = std::max(limits_.max.yaw_rad, st.pose.yaw_rad);
    }
    return {};
  }
  Status on_activate() override { return bind_and_anchor(binding_, clock()); }
  Status on_deactivate() override { return {}; }
  Status on_write(const ArmCommand&) override {
    return unsupported("arm '" + name() + "' is a replay: it cannot be commanded");
  }
  Result<ArmState> on_read() override {
    // The latest recorded state due by now (the first one before that).
    const std::int64_t recorded_now = binding_.session->recorded_ns_at(clock().now_ns());
    auto it = std::upper_bound(states_.begin(), states_.end(), recorded_now,
                               [](std::int64_t t, const ArmState& s) { return t < s.host_ns; });
    return it == states_.begin() ? states_.front() : *std::prev(it);
  }
  Status on_stop() override { return {}; }

 private:
  ReplayBinding binding_;
  std::vector<ArmState> states_;
  ArmLimits limits_;
};

template <typename D, typename Impl>
DeviceFactory<D> replay_factory(std::shared_ptr<ReplaySession> session) {
  return [session](const DeviceContext& ctx) -> Result<std::unique_ptr<D>> {
    return std::unique_ptr<D>(std::make_unique<Impl>(ctx, session));
  };
}

}  // namespace

Status register_replay_backends(BackendRegistry& registry, std::shared_ptr<ReplaySession> session) {
  if (!session) return invalid_argument("replay backends need a session");
  HC_RETURN_IF_ERROR(registry.add<Camera>("replay", replay_factory<Camera, ReplayCamera>(session),
                                          "frames of a recorded session"));
  HC_RETURN_IF_ERROR(registry.add<Trigger>("replay",
                                           replay_factory<Trigger, ReplayTrigger>(session),
                                           "trigger edges of a recorded session"));
  HC_RETURN_IF_ERROR(registry.add<Fsr>("replay", replay_factory<Fsr, ReplayFsr>(session),
                                       "FSR samples of a recorded session"));
  HC_RETURN_IF_ERROR(
      registry.add<ForceTorque>("replay", replay_factory<ForceTorque, ReplayForceTorque>(session),
                                "wrenches of a recorded session"));
  HC_RETURN_IF_ERROR(registry.add<Arm>("replay", replay_factory<Arm, ReplayArm>(session),
                                       "arm states of a recorded session"));
  return {};
}

}  // namespace hc::devices
