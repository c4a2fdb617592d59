// The "sim" backends: every device kind on the shared simulated world (sim_world.h).
#include <algorithm>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <limits>
#include <memory>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include "rig_daemon/devices/pinhole.h"
#include "rig_daemon/devices/registry.h"
#include "rig_daemon/devices/sim_scene.h"
#include "rig_daemon/devices/sim_world.h"

namespace hc::devices {

namespace {

using sim::Fault;
using sim::World;

constexpr std::size_t kMaxBatch = 4096;  // items per read(), bounds memory when a reader lags

std::int64_t seconds_to_ns(double s) { return static_cast<std::int64_t>(std::llround(s * 1e9)); }

// Reads/writes fail while a disconnect fault covers `t`.
Status check_connected(const World& world, const std::string& name, std::int64_t t) {
  if (auto f = world.fault(name, Fault::Kind::kDisconnect, t))
    return Status(StatusCode::kUnavailable, "simulated device '" + name + "' disconnected");
  return {};
}

// What every simulated device shares: the world, seeded generators, a device clock offset and the
// fault checks of one item at time t.
class SimParts {
 public:
  SimParts(const DeviceContext& ctx, std::shared_ptr<World> world)
      : world_(std::move(world)),
        name_(ctx.name),
        noise_(world_->device_seed(ctx.name)),
        faults_(world_->device_seed(ctx.name + "/faults")) {
    // A device clock that started at a random moment before the host's (ns).
    device_offset_ns_ =
        static_cast<std::int64_t>(world_->device_seed(ctx.name + "/clock") % 1'000'000'000'000ULL);
  }

  World& world() const { return *world_; }
  double gauss() { return normal_(noise_); }
  std::int64_t device_stamp(std::int64_t t) const { return t + device_offset_ns_; }

  // Whether the item due at t is lost to a stall or dropout (consumes one fault draw either way,
  // so that dropouts do not shift the noise sequence).
  bool lost(std::int64_t t) {
    const double u = uniform_(faults_);
    if (world_->fault(name_, Fault::Kind::kStall, t)) return true;
    if (auto f = world_->fault(name_, Fault::Kind::kDropout, t)) return u < f->probability;
    return false;
  }
  std::int64_t delay_ns(std::int64_t t) const {
    auto f = world_->fault(name_, Fault::Kind::kDelay, t);
    return f ? seconds_to_ns(std::max(0.0, f->magnitude)) : 0;
  }
  double spike_n(std::int64_t t) const {
    auto f = world_->fault(name_, Fault::Kind::kSpike, t);
    return f ? f->magnitude : 0.0;
  }
  Status connected(std::int64_t t) const { return check_connected(*world_, name_, t); }

 private:
  std::shared_ptr<World> world_;
  std::string name_;
  std::mt19937_64 noise_;
  std::mt19937_64 faults_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  std::uniform_real_distribution<double> uniform_{0.0, 1.0};
  std::int64_t device_offset_ns_ = 0;
};

Result<std::shared_ptr<World>> need_world(const DeviceContext& ctx) {
  if (!ctx.world)
    return failed_precondition("backend 'sim' needs the simulated world (DeviceContext::world)");
  return ctx.world;
}

// The loop every periodic or event-driven stream shares. `next_due()` is the time the next item
// becomes available (nullopt: none scheduled yet); `emit(out)` produces (or loses) that item and
// returns false if it was lost.
template <typename Self, typename Item>
Result<std::size_t> stream_read(Self& self, SimParts& parts, std::vector<Item>& out,
                                Duration timeout) {
  Clock& clock = parts.world().clock();
  const std::int64_t deadline = clock.now_ns() + std::max<std::int64_t>(0, timeout.count());
  const std::size_t before = out.size();
  while (true) {
    const std::int64_t now = clock.now_ns();
    HC_RETURN_IF_ERROR(parts.connected(now));
    std::optional<std::int64_t> due;
    while (out.size() - before < kMaxBatch && (due = self.next_due()) && *due <= now)
      self.emit(out);
    if (out.size() > before) return out.size() - before;
    if (now >= deadline) return std::size_t{0};
    // Wait for the next item (or a little, when none is scheduled: a trigger may start).
    const std::int64_t wake = due ? std::min(*due, deadline) : std::min(now + 1'000'000, deadline);
    clock.sleep_until_ns(std::max(wake, now + 1));
  }
}

// ------------------------------------------------------------------------------------------------
class SimForceTorque final : public ForceTorque {
 public:
  SimForceTorque(const DeviceContext& ctx, std::shared_ptr<World> world)
      : ForceTorque(ctx), parts_(ctx, std::move(world)) {}

  WrenchCalibration calibration() const override { return cal_; }
  double sample_rate_hz() const override { return rate_hz_; }

  std::optional<std::int64_t> next_due() const {
    const std::int64_t t = t0_ + seconds_to_ns(static_cast<double>(k_) / rate_hz_);
    return t + parts_.delay_ns(t);
  }
  void emit(std::vector<WrenchSample>& out) {
    const std::int64_t t = t0_ + seconds_to_ns(static_cast<double>(k_) / rate_hz_);
    const std::uint64_t k = k_++;
    // Draw the noise first so that a lost sample does not shift later samples' noise.
    std::array<double, 6> noise{};
    for (double& n : noise) n = parts_.gauss();
    if (parts_.lost(t)) {
      count_lost(1);
      return;
    }
    const double force = parts_.world().true_force_n(t) + parts_.spike_n(t);
    const double drift = drift_n_per_s_ * static_cast<double>(t - t0_) * 1e-9 + offset_n_;
    std::array<double, 6> value{
        noise_n_ * noise[0],  noise_n_ * noise[1],  force + drift + noise_n_ * noise[2],
        noise_nm_ * noise[3], noise_nm_ * noise[4], noise_nm_ * noise[5]};
    WrenchSample s;
    for (int i = 0; i < 6; ++i) {
      const double cpu = i < 3 ? cal_.counts_per_n : cal_.counts_per_nm;
      const double c = std::clamp(std::round(value[i] * cpu),
                                  static_cast<double>(std::numeric_limits<std::int32_t>::min()),
                                  static_cast<double>(std::numeric_limits<std::int32_t>::max()));
      s.counts[i] = static_cast<std::int32_t>(c);
      last_counts_[i] = s.counts[i];
      const double si = (static_cast<double>(s.counts[i]) - bias_[i]) / cpu;
      if (i < 3)
        s.force_n[i] = si;
      else
        s.torque_nm[i - 3] = si;
    }
    s.rdt_sequence = static_cast<std::uint32_t>(k);
    s.ft_sequence = static_cast<std::uint32_t>(k + ft_offset_);
    s.sequence = k - 1;
    const std::int64_t delay = parts_.delay_ns(t);
    s.host_ns = t + delay;
    s.device_stamp_ns = parts_.device_stamp(t);
    if (delay > late_ns_) count_late(1);
    out.push_back(s);
  }

 protected:
  Status on_configure(ConfigNode node) override {
    node.optional("rate_hz", rate_hz_, Bounds{0.0, 7000.0, true, false});
    node.optional("noise_n", noise_n_, Bounds::non_negative());
    node.optional("noise_nm", noise_nm_, Bounds::non_negative());
    node.optional("drift_n_per_s", drift_n_per_s_);
    node.optional("offset_n", offset_n_);
    node.optional("counts_per_n", cal_.counts_per_n, Bounds::positive());
    node.optional("counts_per_nm", cal_.counts_per_nm, Bounds::positive());
    double late_s = 0.005;
    node.optional("late_after_s", late_s, Bounds::positive());
    late_ns_ = seconds_to_ns(late_s);
    return node.status();
  }
  Status on_activate() override {
    const std::int64_t now = parts_.world().clock().now_ns();
    HC_RETURN_IF_ERROR(parts_.connected(now));
    t0_ = now;
    k_ = 1;
    ft_offset_ = parts_.world().device_seed(name() + "/ft") % 100000;
    return {};
  }
  Status on_deactivate() override { return {}; }
  Status on_reset() override { return parts_.connected(parts_.world().clock().now_ns()); }
  Result<std::size_t> on_read(std::vector<WrenchSample>& out, Duration timeout) override {
    return stream_read(*this, parts_, out, timeout);
  }
  Status on_bias() override {
    for (int i = 0; i < 6; ++i) bias_[i] = static_cast<double>(last_counts_[i]);
    return {};
  }
  Status on_clear_bias() override {
    bias_.fill(0.0);
    return {};
  }
  void describe(DeviceInfo& info) const override {
    info.model = "simulated ATI Net F/T";
    info.details = {{"rate_hz", std::to_string(rate_hz_)},
                    {"noise_n", std::to_string(noise_n_)},
                    {"drift_n_per_s", std::to_string(drift_n_per_s_)}};
  }

 private:
  SimParts parts_;
  WrenchCalibration cal_;
  double rate_hz_ = 1000.0;
  double noise_n_ = 1.0 / 24.0;  // Nano25 resolution (thesis 5.6: 1/24 N)
  double noise_nm_ = 1.0 / 1320.0;
  double drift_n_per_s_ = 0.002;
  double offset_n_ = 0.0;
  std::int64_t late_ns_ = 5'000'000;
  std::int64_t t0_ = 0;
  std::uint64_t k_ = 1;
  std::uint64_t ft_offset_ = 0;
  std::array<std::int32_t, 6> last_counts_{};
  std::array<double, 6> bias_{};
};

// ------------------------------------------------------------------------------------------------
class SimFsr final : public Fsr {
 public:
  SimFsr(const DeviceContext& ctx, std::shared_ptr<World> world)
      : Fsr(ctx), parts_(ctx, std::move(world)) {}

  FsrCalibration calibration() const override { return cal_; }
  double sample_rate_hz() const override { return triggered_ ? 0.0 : rate_hz_; }

  // Time of item k_ (a period, or the rising edge k_ plus the ADC conversion delay).
  std::optional<std::int64_t> item_time() const {
    if (!triggered_) return t0_ + seconds_to_ns(static_cast<double>(k_) / rate_hz_);
    const auto edge = parts_.world().rising_edge_ns(k_, parts_.world().clock().now_ns());
    if (!edge) return std::nullopt;
    return *edge + conversion_ns_;
  }
  std::optional<std::int64_t> next_due() const {
    const auto t = item_time();
    if (!t) return std::nullopt;
    return *t + parts_.delay_ns(*t);
  }
  void emit(std::vector<FsrSample>& out) {
    const std::int64_t t = *item_time();
    const std::uint64_t k = k_++;
    const double noise = parts_.gauss();
    if (parts_.lost(t)) {
      count_lost(1);
      return;
    }
    const double force = std::max(0.0, parts_.world().true_force_n(t) + parts_.spike_n(t));
    const double creep = 1.0 + creep_per_s_ * static_cast<double>(t - t0_) * 1e-9;
    const double raw = cal_.to_raw(force * gain_ * creep) + noise_raw_ * noise;
    FsrSample s;
    s.raw = static_cast<std::uint32_t>(std::clamp(std::round(raw), 0.0, cal_.full_scale));
    s.force_n = cal_.to_newtons(s.raw);
    s.channel = channel_;
    s.sequence = triggered_ ? k - first_edge_ : k - 1;
    const std::int64_t delay = parts_.delay_ns(t);
    s.host_ns = t + delay;
    s.device_stamp_ns = parts_.device_stamp(t);
    if (triggered_) s.trigger_index = k;
    if (delay > late_ns_) count_late(1);
    out.push_back(s);
  }

 protected:
  Status on_configure(ConfigNode node) override {
    std::string sampling = "periodic";
    node.optional("sampling", sampling, {"periodic", "triggered"});
    triggered_ = sampling == "triggered";
    node.optional("rate_hz", rate_hz_, Bounds{0.0, 100000.0, true, false});
    node.optional("channel", channel_);
    node.optional("noise_raw", noise_raw_, Bounds::non_negative());
    node.optional("gain", gain_, Bounds::positive());
    node.optional("creep_per_s", creep_per_s_);
    double conversion_s = 20e-6;
    node.optional("conversion_s", conversion_s, Bounds::non_negative());
    conversion_ns_ = seconds_to_ns(conversion_s);
    double late_s = 0.005;
    node.optional("late_after_s", late_s, Bounds::positive());
    late_ns_ = seconds_to_ns(late_s);
    if (std::optional<ConfigNode> c = node.find("calibration")) {
      c->optional("full_scale", cal_.full_scale, Bounds::positive());
      c->optional("threshold", cal_.threshold, Bounds{0.0, 1.0, false, true});
      c->optional("scale_n", cal_.scale_n, Bounds::positive());
      c->optional("exponent", cal_.exponent, Bounds::positive());
    }
    return node.status();
  }
  Status on_activate() override {
    const std::int64_t now = parts_.world().clock().now_ns();
    HC_RETURN_IF_ERROR(parts_.connected(now));
    t0_ = now;
    // Triggered: follow the edges from the next one on; periodic: first sample one period in.
    k_ = triggered_ ? parts_.world().pulses_by(now) : 1;
    first_edge_ = k_;
    return {};
  }
  Status on_deactivate() override { return {}; }
  Status on_reset() override { return parts_.connected(parts_.world().clock().now_ns()); }
  Result<std::size_t> on_read(std::vector<FsrSample>& out, Duration timeout) override {
    return stream_read(*this, parts_, out, timeout);
  }
  void describe(DeviceInfo& info) const override {
    info.model = "simulated FSR";
    info.details = {{"sampling", triggered_ ? "triggered" : "periodic"},
                    {"rate_hz", std::to_string(rate_hz_)}};
  }

 private:
  SimParts parts_;
  FsrCalibration cal_;
  bool triggered_ = false;
  double rate_hz_ = 1000.0;
  std::uint32_t channel_ = 0;
  double noise_raw_ = 2.0;
  double gain_ = 1.0;
  double creep_per_s_ = 0.0;
  std::int64_t conversion_ns_ = 20'000;
  std::int64_t late_ns_ = 5'000'000;
  std::int64_t t0_ = 0;
  std::uint64_t k_ = 1;
  std::uint64_t first_edge_ = 0;
};

// ------------------------------------------------------------------------------------------------
class SimTrigger final : public Trigger {
 public:
  SimTrigger(const DeviceContext& ctx, std::shared_ptr<World> world)
      : Trigger(ctx), parts_(ctx, std::move(world)) {}

  bool running() const override {
    return state() == DeviceState::kActive &&
           parts_.world().trigger_running(parts_.world().clock().now_ns());
  }
  std::vector<std::uint32_t> lines() const override { return lines_; }

  std::optional<std::int64_t> next_due() const {
    const auto rise = parts_.world().rising_edge_ns(k_, parts_.world().clock().now_ns());
    if (!rise) return std::nullopt;
    return falling_next_ ? *rise + parts_.world().pulse_width_ns(k_) : *rise;
  }
  void emit(std::vector<TriggerEdge>& out) {
    const std::int64_t t = *next_due();
    const bool rising = !falling_next_;
    const std::uint64_t k = k_;
    if (rising && report_falling_) {
      falling_next_ = true;
    } else {
      falling_next_ = false;
      ++k_;
    }
    if (rising && parts_.lost(t)) {  // a lost edge takes its falling edge with it
      count_lost(lines_.size());
      falling_next_ = false;
      k_ = k + 1;
      return;
    }
    for (std::uint32_t line : lines_) {
      TriggerEdge e;
      e.index = k - first_;
      e.line = line;
      e.rising = rising;
      e.host_ns = t;
      e.device_stamp_ns = parts_.device_stamp(t);
      e.device_counter = k;
      out.push_back(e);
    }
  }

 protected:
  Status on_configure(ConfigNode node) override {
    node.optional("lines", lines_);
    node.optional("report_falling", report_falling_);
    if (lines_.empty()) node.error("lines", "needs at least one line");
    return node.status();
  }
  Status on_activate() override {
    const std::int64_t now = parts_.world().clock().now_ns();
    HC_RETURN_IF_ERROR(parts_.connected(now));
    k_ = first_ = parts_.world().pulses_by(now);
    falling_next_ = false;
    return {};
  }
  Status on_deactivate() override {
    parts_.world().trigger_stop(parts_.world().clock().now_ns());
    return {};
  }
  Status on_reset() override { return parts_.connected(parts_.world().clock().now_ns()); }
  Status on_start(const PulseTrain& train) override {
    const std::int64_t now = parts_.world().clock().now_ns();
    HC_RETURN_IF_ERROR(parts_.connected(now));
    return parts_.world().trigger_start(train, now);
  }
  Status on_stop() override {
    const std::int64_t now = parts_.world().clock().now_ns();
    HC_RETURN_IF_ERROR(parts_.connected(now));
    parts_.world().trigger_stop(now);
    return {};
  }
  Status on_fire() override {
    const std::int64_t now = parts_.world().clock().now_ns();
    HC_RETURN_IF_ERROR(parts_.connected(now));
    return parts_.world().trigger_fire(1e-3, now);
  }
  Result<std::size_t> on_read(std::vector<TriggerEdge>& out, Duration timeout) override {
    return stream_read(*this, parts_, out, timeout);
  }
  void describe(DeviceInfo& info) const override {
    info.model = "simulated trigger lines";
    std::string l;
    for (std::uint32_t line : lines_) {
      if (!l.empty()) l.push_back(',');
      l.append(std::to_string(line));
    }
    info.details = {{"lines", l}};
  }

 private:
  SimParts parts_;
  std::vector<std::uint32_t> lines_{0};
  bool report_falling_ = false;
  std::uint64_t k_ = 0;
  std::uint64_t first_ = 0;
  bool falling_next_ = false;
};

// ------------------------------------------------------------------------------------------------
// What a simulated camera needs to render a frame, fixed while it streams (copied, so the render
// thread shares nothing with the device or the world).
struct RenderSetup {
  sim::PinholeCamera cam;
  sim::DotStyle style;
  sim::ProbeLook probe;
  double marker_radius_m = 0.0;
  double pixel_noise = 0.0;
  std::uint64_t noise_seed = 0;  // the device's "/pixels" seed (xor the frame index per frame)
};

// Pixels of `f` (its header already set) showing `truth`; `layer` is scratch reused between frames.
void render_frame(const RenderSetup& s, const sim::GroundTruth& truth, sim::ProbeLayer& layer,
                  Frame& f) {
  f.pixels.assign(static_cast<std::size_t>(s.cam.width) * s.cam.height, s.style.background);
  if (truth.board_pose_index) {  // a calibration capture: the board only
    sim::render_board(s.cam, truth.board_spec, truth.board_pose, f);
  } else {
    const sim::ProbeLayer* occluder = nullptr;
    if (truth.probe_shown) {
      layer.render(s.cam, truth.probe_geometry, s.probe, static_cast<int>(s.cam.width),
                   static_cast<int>(s.cam.height));
      layer.composite(f);
      occluder = &layer;
    }
    sim::render_dots(s.cam, truth.markers_m, s.marker_radius_m, s.style, f, occluder);
  }
  if (s.pixel_noise <= 0.0) return;
  // xorshift64 and a sum of two uniforms (triangular, std sigma): per-pixel normal draws would
  // cost more than the rendering itself.
  std::uint64_t x = s.noise_seed ^ f.frame_index;
  x |= 1;
  const double scale = s.pixel_noise * std::sqrt(6.0);
  for (std::uint8_t& p : f.pixels) {
    x ^= x << 13;
    x ^= x >> 7;
    x ^= x << 17;
    const double a = static_cast<double>(x & 0xFFFF) / 65536.0;
    const double b = static_cast<double>((x >> 16) & 0xFFFF) / 65536.0;
    const double v = p + scale * (a + b - 1.0);
    p = static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L));
  }
}

// One frame handed to the render threads: its header and the scene at mid-exposure.
struct RenderJob {
  Frame frame;             // everything but the pixels
  sim::GroundTruth truth;  // a copy, taken on the reading thread
  std::int64_t ready_ns;   // exposure end + readout: when the camera would have the frame
};
struct RenderedFrame {
  Frame frame;
  std::int64_t ready_ns = 0;
  std::int64_t finished_ns = 0;  // on the device's clock, when the render thread was done
};

// One simulated camera's frames on their way through the render threads, in submission order,
// like a real camera's frame buffers filled by the driver's threads: rendering never stalls the
// thread that reads the devices (rigd's control loop). `buffers` bounds the frames queued, being
// rendered or rendered but not yet taken; submit() fails when all are in use (a buffer overrun:
// the caller counts the frame lost). Thread-safe.
class FrameStream {
 public:
  struct Slot {
    RenderJob job;
    RenderedFrame done;
    bool finished = false;  // guarded by the stream's mutex; job/done belong to the renderer
  };                        // until it is set

  FrameStream(RenderSetup setup, std::size_t buffers, std::shared_ptr<Clock> clock)
      : setup_(std::move(setup)),
        buffers_(std::max<std::size_t>(1, buffers)),
        clock_(std::move(clock)) {}

  // A slot for `job` (moved from only on success), or null when every buffer is in use.
  std::shared_ptr<Slot> reserve(RenderJob& job) {
    std::lock_guard lock(mutex_);
    if (stopping_ || slots_.size() >= buffers_) return nullptr;
    auto slot = std::make_shared<Slot>();
    slot->job = std::move(job);
    slots_.push_back(slot);
    return slot;
  }
  // On a render thread: renders the slot unless the stream was stopped meanwhile.
  void render(Slot& slot, sim::ProbeLayer& layer) {
    {
      std::lock_guard lock(mutex_);
      if (stopping_) return;
    }
    render_frame(setup_, slot.job.truth, layer, slot.job.frame);
    slot.done = RenderedFrame{std::move(slot.job.frame), slot.job.ready_ns, clock_->now_ns()};
    slot.job.truth = {};
    {
      std::lock_guard lock(mutex_);
      slot.finished = true;
    }
    cv_.notify_all();
  }
  // Moves the frames finished in order (oldest first, up to the first unfinished one) to `out`.
  void take(std::vector<RenderedFrame>& out) {
    std::lock_guard lock(mutex_);
    while (!slots_.empty() && slots_.front()->finished) {
      out.push_back(std::move(slots_.front()->done));
      slots_.pop_front();
    }
  }
  bool idle() const {
    std::lock_guard lock(mutex_);
    return all_finished();
  }
  // Blocks until every submitted frame is rendered.
  void wait_all() {
    std::unique_lock lock(mutex_);
    cv_.wait(lock, [&] { return stopping_ || all_finished(); });
  }
  // Blocks until the oldest frame is rendered or `d` passed (real time).
  void wait_any(Duration d) {
    std::unique_lock lock(mutex_);
    cv_.wait_for(lock, d,
                 [&] { return stopping_ || (!slots_.empty() && slots_.front()->finished); });
  }
  // Forgets every frame not taken yet (a frame being rendered is finished and thrown away by its
  // render thread); returns how many there were. Never blocks on a render.
  std::size_t stop() {
    std::size_t dropped = 0;
    {
      std::lock_guard lock(mutex_);
      if (stopping_) return 0;
      stopping_ = true;
      dropped = slots_.size();
      slots_.clear();
    }
    cv_.notify_all();
    return dropped;
  }

 private:
  bool all_finished() const {
    return std::all_of(slots_.begin(), slots_.end(), [](const auto& s) { return s->finished; });
  }

  const RenderSetup setup_;  // immutable: read by the render threads without the lock
  const std::size_t buffers_;
  const std::shared_ptr<Clock> clock_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;  // a frame finished, or stopping
  std::deque<std::shared_ptr<Slot>> slots_;
  bool stopping_ = false;
};

// The render threads every simulated camera of the process shares: hardware threads - 1 (at least
// 1, at most 4), at a lower scheduling priority (nice +10) so that on a busy machine rendering
// yields the CPU to the threads that poll the devices. A job holds its stream and slot, so a camera
// may stop or go away while its frame renders.
class RenderPool {
 public:
  static std::shared_ptr<RenderPool> shared() {
    static std::mutex mutex;
    static std::weak_ptr<RenderPool> pool;
    std::lock_guard lock(mutex);
    std::shared_ptr<RenderPool> p = pool.lock();
    if (!p) {
      const unsigned hw = std::max(2u, std::thread::hardware_concurrency());
      p = std::make_shared<RenderPool>(std::min(hw - 1, 4u));
      pool = p;
    }
    return p;
  }

  explicit RenderPool(unsigned threads) {
    for (unsigned i = 0; i < threads; ++i) threads_.emplace_back([this] { run(); });
  }
  ~RenderPool() {
    {
      std::lock_guard lock(mutex_);
      stopping_ = true;
    }
    cv_.notify_all();
    for (std::thread& t : threads_) t.join();
  }
  RenderPool(const RenderPool&) = delete;
  RenderPool& operator=(const RenderPool&) = delete;

  void push(std::shared_ptr<FrameStream> stream, std::shared_ptr<FrameStream::Slot> slot) {
    {
      std::lock_guard lock(mutex_);
      jobs_.push_back({std::move(stream), std::move(slot)});
    }
    cv_.notify_one();
  }

 private:
  struct Job {
    std::shared_ptr<FrameStream> stream;
    std::shared_ptr<FrameStream::Slot> slot;
  };
  void run() {
    // Linux: setpriority(PRIO_PROCESS, tid) sets one thread's nice value. Failure (a sandbox
    // forbidding it) only costs the priority.
    (void)::setpriority(PRIO_PROCESS, static_cast<id_t>(::syscall(SYS_gettid)), 10);
    sim::ProbeLayer layer;  // scratch, reused between frames
    std::unique_lock lock(mutex_);
    while (true) {
      cv_.wait(lock, [&] { return stopping_ || !jobs_.empty(); });
      if (stopping_) return;
      Job job = std::move(jobs_.front());
      jobs_.pop_front();
      lock.unlock();
      job.stream->render(*job.slot, layer);
      job = {};
      lock.lock();
    }
  }

  std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<Job> jobs_;
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

// ------------------------------------------------------------------------------------------------
class SimCamera final : public Camera {
 public:
  SimCamera(const DeviceContext& ctx, std::shared_ptr<World> world)
      : Camera(ctx), parts_(ctx, std::move(world)) {}
  ~SimCamera() override { stop_rendering(); }

  CameraInfo camera_info() const override {
    CameraInfo info;
    info.width = cam_.width;
    info.height = cam_.height;
    info.format = PixelFormat::kMono8;
    info.trigger_mode = mode_;
    info.frame_rate_hz = rate_hz_;
    info.exposure_s = exposure_s_;
    return info;
  }
  const sim::PinholeCamera& pinhole() const { return cam_; }

  // Exposure start of frame k_ (nullopt: not triggered yet).
  std::optional<std::int64_t> exposure_start() const {
    switch (mode_) {
      case TriggerMode::kFreeRun:
        return t0_ + seconds_to_ns(static_cast<double>(k_) / rate_hz_);
      case TriggerMode::kSoftware:
        if (pending_.empty()) return std::nullopt;
        return pending_.front();
      case TriggerMode::kHardware:
        return parts_.world().rising_edge_ns(edge_, parts_.world().clock().now_ns());
    }
    return std::nullopt;
  }
  std::optional<std::int64_t> next_due() const {
    const auto t = exposure_start();
    if (!t) return std::nullopt;
    return *t + exposure_ns_ + readout_ns_ + parts_.delay_ns(*t);
  }
  // The frame due now: its stamps, lost/late accounting and the scene at mid-exposure are settled
  // here, on the reading thread (cheap); the pixels are rendered here (render_thread: false) or
  // on the render threads.
  void emit(std::vector<Frame>& out) {
    const std::int64_t t = *exposure_start();
    const std::uint64_t index = k_++;
    std::optional<std::uint64_t> trigger;
    if (mode_ == TriggerMode::kHardware) trigger = edge_++;
    if (mode_ == TriggerMode::kSoftware) pending_.pop_front();
    if (parts_.lost(t)) {
      count_lost(1);
      return;
    }
    RenderJob job;
    Frame& f = job.frame;
    f.format = PixelFormat::kMono8;
    f.width = cam_.width;
    f.height = cam_.height;
    f.stride_bytes = cam_.width;
    f.frame_id = (first_frame_id_ + index) & 0xFFFFu;
    f.frame_index = index;
    f.device_stamp_ns = parts_.device_stamp(t);
    const std::int64_t delay = parts_.delay_ns(t);
    job.ready_ns = t + exposure_ns_ + readout_ns_;
    f.host_ns = job.ready_ns + delay;
    f.trigger_index = trigger;
    f.exposure_s = exposure_s_;
    // The scene at mid-exposure; ground truth for that instant goes to the separate channel.
    const std::int64_t t_scene = t + exposure_ns_ / 2;
    job.truth = parts_.world().ground_truth(t_scene, trigger, false);
    parts_.world().publish_ground_truth(t_scene, trigger);
    if (stream_) {
      std::shared_ptr<FrameStream::Slot> slot = stream_->reserve(job);
      if (!slot && !parts_.world().clock().is_simulated()) {
        count_lost(1);  // every frame buffer in use: an overrun
        return;
      }
      if (!slot) {
        // Rendering takes no simulated time: free the buffers instead (read_rendered() delivers).
        stream_->wait_all();
        stream_->take(rendered_);
        slot = stream_->reserve(job);
      }
      if (slot) pool_->push(stream_, std::move(slot));
      return;
    }
    render_frame(setup_, job.truth, probe_layer_, f);
    if (delay > late_ns_) count_late(1);
    out.push_back(std::move(f));
  }

 protected:
  Status on_configure(ConfigNode node) override {
    sim::PinholeCamera cam;
    // A default view: 0.35 m above and in front of the specimen, looking at its centre.
    const auto& spec = parts_.world().options().specimen;
    sim::look_at(Eigen::Vector3d(spec.center_m.x(), spec.center_m.y() - 0.2, spec.top_z_m + 0.3),
                 Eigen::Vector3d(spec.center_m.x(), spec.center_m.y(), spec.top_z_m), cam);
    HC_RETURN_IF_ERROR(sim::read_pinhole(node, cam));
    cam_ = cam;
    parts_.world().register_camera(name(), cam_);
    node.optional("trigger", mode_,
                  {{"hardware", TriggerMode::kHardware},
                   {"software", TriggerMode::kSoftware},
                   {"free_run", TriggerMode::kFreeRun}});
    node.optional("frame_rate_hz", rate_hz_, Bounds{0.0, 1000.0, true, false});
    node.optional("exposure_s", exposure_s_, Bounds::positive());
    // Basler piA1600-35gm readout: AOI height x 20.52 us + 3873.2 us (RIG_PROTOCOL_FACTS.md).
    double readout_s = cam_.height * 20.52e-6 + 3873.2e-6;
    node.optional("readout_s", readout_s, Bounds::non_negative());
    node.optional("first_frame_id", first_frame_id_, Bounds::between(0, 65535));
    sim::DotStyle style;
    node.optional("background", style.background);
    node.optional("dot", style.dot);
    double pixel_noise = 0.0;
    node.optional("pixel_noise", pixel_noise, Bounds::non_negative());
    double late_s = 0.05;
    node.optional("late_after_s", late_s, Bounds::positive());
    std::string format = "mono8";
    node.optional("format", format, {"mono8"});
    // Rendering inside read() (default) or on the shared render threads (render_thread: true);
    // frame buffers of its stream (queued + rendering + unread). The threads keep a real-time
    // high-resolution capture from stalling the control loop, but at nice +10 on a loaded 2-core
    // machine they fall behind and frames are lost (counted) where the inline path only slowed
    // the loop: the sanitizer build's real-time rigd test lost 15 of 840 frames. Inline keeps
    // every simulated frame; turn the threads on for real-time captures on an idle machine.
    node.optional("render_thread", render_thread_);
    node.optional("render_buffers", render_buffers_, Bounds::between(1, 1024));
    exposure_ns_ = seconds_to_ns(exposure_s_);
    readout_ns_ = seconds_to_ns(readout_s);
    late_ns_ = seconds_to_ns(late_s);
    setup_.cam = cam_;
    setup_.style = style;
    setup_.probe = parts_.world().options().probe;
    setup_.marker_radius_m = parts_.world().specimen().marker_radius_m();
    setup_.pixel_noise = pixel_noise;
    setup_.noise_seed = parts_.world().device_seed(name() + "/pixels");
    return node.status();
  }
  Status on_activate() override {
    const std::int64_t now = parts_.world().clock().now_ns();
    HC_RETURN_IF_ERROR(parts_.connected(now));
    t0_ = now;
    k_ = 0;
    edge_ = parts_.world().pulses_by(now);
    pending_.clear();
    stop_rendering();
    if (render_thread_) {
      if (!pool_) pool_ = RenderPool::shared();
      stream_ = std::make_shared<FrameStream>(setup_, static_cast<std::size_t>(render_buffers_),
                                              parts_.world().clock_ptr());
    }
    return {};
  }
  Status on_deactivate() override {
    pending_.clear();
    stop_rendering();
    return {};
  }
  Status on_reset() override {
    stop_rendering();
    return parts_.connected(parts_.world().clock().now_ns());
  }
  Status on_software_trigger() override {
    if (mode_ != TriggerMode::kSoftware)
      return failed_precondition("camera '" + name() + "' is not in software trigger mode");
    const std::int64_t now = parts_.world().clock().now_ns();
    HC_RETURN_IF_ERROR(parts_.connected(now));
    pending_.push_back(now);
    return {};
  }
  Result<std::size_t> on_read(std::vector<Frame>& out, Duration timeout) override {
    if (!stream_) return stream_read(*this, parts_, out, timeout);
    return read_rendered(out, timeout);
  }
  void describe(DeviceInfo& info) const override {
    info.model = "simulated camera";
    info.details = {{"size", std::to_string(cam_.width) + "x" + std::to_string(cam_.height)},
                    {"trigger", std::string(to_string(mode_))},
                    {"render", render_thread_ ? "thread" : "inline"}};
  }

 private:
  // stream_read() with the render threads: frames due are handed to them, and read() returns the
  // frames it has finished. Simulated time: every frame handed over is waited for in the same
  // read(), so frames arrive exactly when (and as) the inline renderer delivers them and the
  // session stays deterministic. Real time: read() never waits for pixels beyond its timeout; a
  // frame finished after its host_ns keeps its stamps and counts late when it comes more than
  // late_after_s after exposure end + readout, like a real camera's late frame.
  Result<std::size_t> read_rendered(std::vector<Frame>& out, Duration timeout) {
    Clock& clock = parts_.world().clock();
    const bool simulated = clock.is_simulated();
    const std::int64_t deadline = clock.now_ns() + std::max<std::int64_t>(0, timeout.count());
    const std::size_t before = out.size();
    while (true) {
      const std::int64_t now = clock.now_ns();
      // Frames finished before a disconnect are still delivered (the error comes next read).
      const Status connected = parts_.connected(now);
      std::optional<std::int64_t> due;
      std::size_t emitted = 0;
      if (connected.ok())
        while (emitted < kMaxBatch && (due = next_due()) && *due <= now) {
          emit(out);
          ++emitted;
        }
      if (simulated) stream_->wait_all();
      stream_->take(rendered_);  // after the frames emit() may have taken already
      for (RenderedFrame& r : rendered_) {
        const std::int64_t arrived =
            simulated ? r.frame.host_ns : std::max(r.frame.host_ns, r.finished_ns);
        if (arrived - r.ready_ns > late_ns_) count_late(1);
        out.push_back(std::move(r.frame));
      }
      rendered_.clear();
      if (out.size() > before) return out.size() - before;
      if (!connected.ok()) return connected;
      if (now >= deadline) return std::size_t{0};
      const std::int64_t wake =
          due ? std::min(*due, deadline) : std::min(now + 1'000'000, deadline);
      if (!simulated && !stream_->idle())
        stream_->wait_any(Duration(std::max<std::int64_t>(wake - now, 1)));
      else
        clock.sleep_until_ns(std::max(wake, now + 1));
    }
  }
  // Frames handed to the render threads and never delivered are lost (a real camera stopped
  // mid-acquisition drops its in-flight buffers too).
  void stop_rendering() {
    if (!stream_) return;
    if (const std::size_t dropped = stream_->stop(); dropped > 0) count_lost(dropped);
    stream_.reset();
  }

  SimParts parts_;
  sim::PinholeCamera cam_;
  TriggerMode mode_ = TriggerMode::kHardware;
  double rate_hz_ = 15.0;
  double exposure_s_ = 0.002;
  std::int64_t exposure_ns_ = 2'000'000;
  std::int64_t readout_ns_ = 0;
  std::int64_t late_ns_ = 50'000'000;
  std::uint32_t first_frame_id_ = 65400;  // like the fake GigE camera: wraps early
  RenderSetup setup_;
  sim::ProbeLayer probe_layer_;  // scratch of the inline renderer, reused between frames
  bool render_thread_ = false;  // see on_configure
  int render_buffers_ = 8;
  std::int64_t t0_ = 0;
  std::uint64_t k_ = 0;
  std::uint64_t edge_ = 0;
  std::deque<std::int64_t> pending_;
  std::vector<RenderedFrame> rendered_;  // taken from the render threads, not yet delivered
  std::shared_ptr<RenderPool> pool_;     // the shared render threads (render_thread: true)
  std::shared_ptr<FrameStream> stream_;  // while active with render_thread
};

// ------------------------------------------------------------------------------------------------
class SimArm final : public Arm {
 public:
  SimArm(const DeviceContext& ctx, std::shared_ptr<World> world)
      : Arm(ctx), parts_(ctx, std::move(world)) {}

  ArmLimits limits() const override { return parts_.world().options().arm_limits; }

 protected:
  Status on_configure(ConfigNode node) override { return node.status(); }
  Status on_activate() override { return parts_.connected(parts_.world().clock().now_ns()); }
  Status on_deactivate() override {
    parts_.world().arm_stop(parts_.world().clock().now_ns());
    return {};
  }
  Status on_reset() override { return parts_.connected(parts_.world().clock().now_ns()); }
  Status on_write(const ArmCommand& command) override {
    const std::int64_t now = parts_.world().clock().now_ns();
    HC_RETURN_IF_ERROR(parts_.connected(now));
    return parts_.world().arm_command(command, now);
  }
  Result<ArmState> on_read() override {
    const std::int64_t now = parts_.world().clock().now_ns();
    HC_RETURN_IF_ERROR(parts_.connected(now));
    ArmState s = parts_.world().arm_state(now);
    s.sequence = sequence_++;
    s.device_stamp_ns = parts_.device_stamp(now);
    return s;
  }
  Status on_stop() override {
    const std::int64_t now = parts_.world().clock().now_ns();
    HC_RETURN_IF_ERROR(parts_.connected(now));
    parts_.world().arm_stop(now);
    return {};
  }
  void describe(DeviceInfo& info) const override { info.model = "simulated 4-DOF arm"; }

 private:
  SimParts parts_;
  std::uint64_t sequence_ = 0;
};

template <typename D, typename Impl>
DeviceFactory<D> sim_factory() {
  return [](const DeviceContext& ctx) -> Result<std::unique_ptr<D>> {
    HC_ASSIGN_OR_RETURN(std::shared_ptr<World> world, need_world(ctx));
    return std::unique_ptr<D>(std::make_unique<Impl>(ctx, std::move(world)));
  };
}

}  // namespace

Status register_sim_backends(BackendRegistry& registry) {
  HC_RETURN_IF_ERROR(registry.add<Camera>("sim", sim_factory<Camera, SimCamera>(),
                                          "camera rendering the simulated specimen's markers"));
  HC_RETURN_IF_ERROR(
      registry.add<Trigger>("sim", sim_factory<Trigger, SimTrigger>(), "simulated trigger lines"));
  HC_RETURN_IF_ERROR(
      registry.add<Fsr>("sim", sim_factory<Fsr, SimFsr>(), "simulated FSR (power-law response)"));
  HC_RETURN_IF_ERROR(registry.add<ForceTorque>("sim", sim_factory<ForceTorque, SimForceTorque>(),
                                               "simulated 6-axis force-torque sensor"));
  HC_RETURN_IF_ERROR(
      registry.add<Arm>("sim", sim_factory<Arm, SimArm>(), "simulated 4-DOF arm with the probe"));
  return {};
}

}  // namespace hc::devices
