// Backend "libcamera": a camera through libcamera (0.0.x API), as a devices::Camera.
//
// Config keys:
//   camera_id      libcamera camera id (default: the first camera the manager lists)
//   width, height  requested size (default 1280 x 720; validate() may adjust it)
//   pixel_format   yuyv (default), mjpeg, mono8 (libcamera YUYV, MJPEG, R8)
//   buffers        requests in flight (default 4)
// libcamera cameras free-run. FrameMetadata::sequence is the frame id (gaps are lost frames) and
// FrameMetadata::timestamp (ns, CLOCK_MONOTONIC in libcamera's pipeline handlers) is host_ns.
// libcamera allows one CameraManager per process: the backend shares one.
#include <sys/mman.h>

#include <libcamera/libcamera.h>
#include <atomic>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <mutex>

#include "backend_factories.h"
#include "rig_daemon/backends/libcamera_cameras.h"

namespace hc::rig {

namespace lc = libcamera;

namespace {

std::mutex g_manager_mutex;
std::weak_ptr<lc::CameraManager> g_manager;

Result<std::shared_ptr<lc::CameraManager>> camera_manager() {
  std::lock_guard lock(g_manager_mutex);
  if (auto m = g_manager.lock()) return m;
  auto m = std::make_shared<lc::CameraManager>();
  if (const int rc = m->start(); rc != 0)
    return Status(StatusCode::kUnavailable,
                  std::string("libcamera: starting the camera manager: ") + std::strerror(-rc));
  g_manager = m;
  return m;
}

using devices::Frame;
using devices::PixelFormat;

class LibcameraCamera final : public devices::Camera {
 public:
  explicit LibcameraCamera(const devices::DeviceContext& ctx) : Camera(ctx) {}
  ~LibcameraCamera() override { release(); }

  devices::CameraInfo camera_info() const override { return info_; }

 protected:
  Status on_configure(ConfigNode node) override {
    std::string format = "yuyv", trigger = "free_run";
    int width = 1280, height = 720;
    node.optional("camera_id", camera_id_);
    node.optional("width", width, Bounds::between(1, 16384));
    node.optional("height", height, Bounds::between(1, 16384));
    node.optional("pixel_format", format, {"yuyv", "mjpeg", "mono8"});
    node.optional("buffers", buffers_, Bounds::between(2, 32));
    node.optional("trigger", trigger, {"free_run"});
    node.optional("frame_rate_hz", info_.frame_rate_hz, Bounds{0.0, 1000.0, true, false});
    HC_RETURN_IF_ERROR(node.status());
    info_.width = static_cast<std::uint32_t>(width);
    info_.height = static_cast<std::uint32_t>(height);
    info_.format = *devices::pixel_format_from_string(format);
    return {};
  }

  Status on_activate() override {
    Status s = start();
    if (!s.ok()) release();
    return s;
  }
  Status on_deactivate() override {
    release();
    return {};
  }
  Status on_reset() override {
    release();
    return {};
  }

  Result<std::size_t> on_read(std::vector<Frame>& out, devices::Duration timeout) override {
    std::unique_lock lock(mutex_);
    cv_.wait_for(lock, timeout, [&] { return !done_.empty(); });
    const std::size_t n = done_.size();
    for (Frame& f : done_) out.push_back(std::move(f));
    done_.clear();
    return n;
  }

  void describe(devices::DeviceInfo& info) const override {
    info.model = "libcamera camera";
    info.serial = camera_ ? camera_->id() : camera_id_;
  }

 private:
  Status start() {
    HC_ASSIGN_OR_RETURN(manager_, camera_manager());
    const auto cameras = manager_->cameras();
    if (cameras.empty()) return not_found("camera '" + name() + "': libcamera found no cameras");
    camera_ = camera_id_.empty() ? cameras.front() : manager_->get(camera_id_);
    if (!camera_) {
      std::string ids;
      for (const auto& c : cameras) ids += (ids.empty() ? "" : ", ") + c->id();
      return not_found("camera '" + name() + "': no libcamera camera '" + camera_id_ +
                       "' (found: " + ids + ")");
    }
    if (camera_->acquire() != 0)
      return Status(StatusCode::kUnavailable,
                    "camera '" + name() + "': " + camera_->id() + " is in use");
    acquired_ = true;
    config_ = camera_->generateConfiguration({lc::StreamRole::VideoRecording});
    if (!config_ || config_->empty())
      return failed_precondition("camera '" + name() + "': no video configuration");
    lc::StreamConfiguration& cfg = config_->at(0);
    cfg.size = {info_.width, info_.height};
    cfg.pixelFormat = info_.format == PixelFormat::kMjpeg   ? lc::formats::MJPEG
                      : info_.format == PixelFormat::kMono8 ? lc::formats::R8
                                                            : lc::formats::YUYV;
    const auto wanted = cfg.pixelFormat;
    if (config_->validate() == lc::CameraConfiguration::Invalid || cfg.pixelFormat != wanted)
      return failed_precondition("camera '" + name() + "': " + camera_->id() + " cannot deliver " +
                                 std::string(devices::to_string(info_.format)));
    if (camera_->configure(config_.get()) != 0)
      return failed_precondition("camera '" + name() + "': configure failed");
    info_.width = cfg.size.width;
    info_.height = cfg.size.height;
    stride_ = cfg.stride;
    stream_ = cfg.stream();
    allocator_ = std::make_unique<lc::FrameBufferAllocator>(camera_);
    if (allocator_->allocate(stream_) < 0)
      return Status(StatusCode::kUnavailable, "camera '" + name() + "': allocating buffers");
    for (const auto& buffer : allocator_->buffers(stream_)) {
      if (requests_.size() >= static_cast<std::size_t>(buffers_)) break;
      std::unique_ptr<lc::Request> request = camera_->createRequest();
      if (!request || request->addBuffer(stream_, buffer.get()) != 0)
        return Status(StatusCode::kUnavailable, "camera '" + name() + "': creating requests");
      const lc::FrameBuffer::Plane& plane = buffer->planes()[0];
      void* p = ::mmap(nullptr, plane.length, PROT_READ, MAP_SHARED, plane.fd.get(), plane.offset);
      if (p == MAP_FAILED)
        return Status(StatusCode::kUnavailable, "camera '" + name() + "': mmap of a buffer");
      maps_.emplace_back(buffer.get(), std::make_pair(p, static_cast<std::size_t>(plane.length)));
      requests_.push_back(std::move(request));
    }
    camera_->requestCompleted.connect(this, &LibcameraCamera::completed);
    if (camera_->start() != 0)
      return Status(StatusCode::kUnavailable, "camera '" + name() + "': start failed");
    started_ = true;
    have_sequence_ = false;
    for (auto& r : requests_) camera_->queueRequest(r.get());
    return {};
  }

  // libcamera's thread: copy the image out, then give the buffer back.
  void completed(lc::Request* request) {
    if (request->status() == lc::Request::RequestCancelled) return;
    lc::FrameBuffer* buffer = request->findBuffer(stream_);
    if (buffer != nullptr) {
      const lc::FrameMetadata& md = buffer->metadata();
      Frame f;
      f.format = info_.format;
      f.width = info_.width;
      f.height = info_.height;
      f.stride_bytes = info_.format == PixelFormat::kMjpeg ? 0 : stride_;
      for (const auto& [b, m] : maps_) {
        if (b != buffer) continue;
        const std::size_t used = md.planes().empty()
                                     ? m.second
                                     : std::min<std::size_t>(md.planes()[0].bytesused, m.second);
        const auto* data = static_cast<const std::uint8_t*>(m.first);
        f.pixels.assign(data, data + used);
      }
      f.frame_id = md.sequence;
      {
        std::lock_guard lock(mutex_);
        if (have_sequence_ && md.sequence > last_sequence_ + 1)
          count_lost(md.sequence - last_sequence_ - 1);
        if (!have_sequence_) first_sequence_ = md.sequence;
        have_sequence_ = true;
        last_sequence_ = md.sequence;
        f.frame_index = md.sequence - first_sequence_;
        f.device_stamp_ns = static_cast<std::int64_t>(md.timestamp);
        f.host_ns =
            clock().is_simulated() ? clock().now_ns() : static_cast<std::int64_t>(md.timestamp);
        done_.push_back(std::move(f));
      }
      cv_.notify_all();
    }
    request->reuse(lc::Request::ReuseBuffers);
    if (started_) camera_->queueRequest(request);
  }

  void release() {
    if (camera_ && started_) {
      started_ = false;
      camera_->stop();
    }
    if (camera_) camera_->requestCompleted.disconnect(this, &LibcameraCamera::completed);
    for (auto& [b, m] : maps_) ::munmap(m.first, m.second);
    maps_.clear();
    requests_.clear();
    allocator_.reset();
    if (camera_ && acquired_) camera_->release();
    acquired_ = false;
    config_.reset();
    camera_.reset();
    manager_.reset();
  }

  std::string camera_id_;
  int buffers_ = 4;
  devices::CameraInfo info_{1280, 720, PixelFormat::kYuyv, devices::TriggerMode::kFreeRun,
                            30.0, 0.0};
  std::shared_ptr<lc::CameraManager> manager_;
  std::shared_ptr<lc::Camera> camera_;
  std::unique_ptr<lc::CameraConfiguration> config_;
  std::unique_ptr<lc::FrameBufferAllocator> allocator_;
  lc::Stream* stream_ = nullptr;
  std::vector<std::unique_ptr<lc::Request>> requests_;
  std::vector<std::pair<lc::FrameBuffer*, std::pair<void*, std::size_t>>> maps_;
  std::uint32_t stride_ = 0;
  bool acquired_ = false;
  std::atomic<bool> started_{false};
  std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<Frame> done_;
  bool have_sequence_ = false;
  std::uint32_t last_sequence_ = 0;
  std::uint32_t first_sequence_ = 0;
};

}  // namespace

Result<std::vector<std::string>> list_libcamera_cameras() {
  HC_ASSIGN_OR_RETURN(auto manager, camera_manager());
  std::vector<std::string> ids;
  for (const auto& c : manager->cameras()) ids.push_back(c->id());
  return ids;
}

Result<std::unique_ptr<devices::Camera>> make_libcamera_camera(const devices::DeviceContext& ctx) {
  return std::unique_ptr<devices::Camera>(new LibcameraCamera(ctx));
}

}  // namespace hc::rig
