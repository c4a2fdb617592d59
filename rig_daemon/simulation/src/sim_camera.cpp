// The "sim" camera: frames of the simulated specimen's markers, rendered on a shared pool of
// threads while the device streams.
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

#include "rig_daemon/simulation/sim_dots.h"
#include "rig_daemon/simulation/sim_scene.h"

#include "sim_devices_internal.h"

namespace hc::devices::sim_backend {

namespace {

// What a simulated camera needs to render a frame, fixed while it streams (copied, so the render
// thread shares nothing with the device or the world).
struct RenderSetup {
  CameraModel cam;
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
  const CameraModel& pinhole() const { return cam_; }

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
    CameraModel cam = sim::default_camera();
    // A default view: 0.35 m above and in front of the specimen, looking at its centre.
    const auto& spec = parts_.world().options().specimen;
    look_at(Eigen::Vector3d(spec.center_m.x(), spec.center_m.y() - 0.2, spec.top_z_m + 0.3),
            Eigen::Vector3d(spec.center_m.x(), spec.center_m.y(), spec.top_z_m), cam);
    HC_RETURN_IF_ERROR(read_camera(node, cam));
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
  CameraModel cam_;
  TriggerMode mode_ = TriggerMode::kHardware;
  double rate_hz_ = 15.0;
  double exposure_s_ = 0.002;
  std::int64_t exposure_ns_ = 2'000'000;
  std::int64_t readout_ns_ = 0;
  std::int64_t late_ns_ = 50'000'000;
  std::uint32_t first_frame_id_ = 65400;  // like the fake GigE camera: wraps early
  RenderSetup setup_;
  sim::ProbeLayer probe_layer_;  // scratch of the inline renderer, reused between frames
  bool render_thread_ = false;   // see on_configure
  int render_buffers_ = 8;
  std::int64_t t0_ = 0;
  std::uint64_t k_ = 0;
  std::uint64_t edge_ = 0;
  std::deque<std::int64_t> pending_;
  std::vector<RenderedFrame> rendered_;  // taken from the render threads, not yet delivered
  std::shared_ptr<RenderPool> pool_;     // the shared render threads (render_thread: true)
  std::shared_ptr<FrameStream> stream_;  // while active with render_thread
};

}  // namespace

DeviceFactory<Camera> camera_factory(std::shared_ptr<World> world) {
  return sim_factory<Camera, SimCamera>(std::move(world));
}

}  // namespace hc::devices::sim_backend
