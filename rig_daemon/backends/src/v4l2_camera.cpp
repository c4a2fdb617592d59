// Backend "v4l2": a Video4Linux2 capture device with mmap streaming, as a devices::Camera.
//
// Config keys:
//   device         /dev/videoN (default /dev/video0)
//   width, height  requested size (default 640 x 480; the driver may adjust, camera_info() tells)
//   pixel_format   yuyv (default), mjpeg, mono8 (V4L2 YUYV, MJPG, GREY)
//   frame_rate_hz  requested rate (VIDIOC_S_PARM; default 30)
//   buffers        mmap buffers (default 4)
// V4L2 cameras free-run (trigger: free_run only). Buffers carry the driver's sequence number
// (frame_id; gaps are lost frames) and a CLOCK_MONOTONIC timestamp (host_ns when the driver says
// V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC, else the time of dequeue).
#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>

#include "backend_factories.h"

namespace hc::rig {
namespace {

using devices::Frame;
using devices::PixelFormat;

int xioctl(int fd, unsigned long request, void* arg) {
  int rc;
  do {
    rc = ::ioctl(fd, request, arg);
  } while (rc == -1 && errno == EINTR);
  return rc;
}

class V4l2Camera final : public devices::Camera {
 public:
  explicit V4l2Camera(const devices::DeviceContext& ctx) : Camera(ctx) {}
  ~V4l2Camera() override { release(); }

  devices::CameraInfo camera_info() const override { return info_; }

 protected:
  Status on_configure(ConfigNode node) override {
    std::string format = "yuyv";
    int width = 640, height = 480;
    node.optional("device", device_);
    node.optional("width", width, Bounds::between(1, 16384));
    node.optional("height", height, Bounds::between(1, 16384));
    node.optional("pixel_format", format, {"yuyv", "mjpeg", "mono8"});
    node.optional("frame_rate_hz", info_.frame_rate_hz, Bounds{0.0, 1000.0, true, false});
    node.optional("buffers", buffers_, Bounds::between(2, 32));
    std::string trigger = "free_run";
    node.optional("trigger", trigger, {"free_run"});
    HC_RETURN_IF_ERROR(node.status());
    info_.width = static_cast<std::uint32_t>(width);
    info_.height = static_cast<std::uint32_t>(height);
    info_.format = *devices::pixel_format_from_string(format);
    info_.trigger_mode = devices::TriggerMode::kFreeRun;
    return {};
  }

  Status on_activate() override {
    Status s = open_and_stream();
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
    std::size_t appended = 0;
    int wait_ms = static_cast<int>(std::max<std::int64_t>(
        0, std::chrono::duration_cast<std::chrono::milliseconds>(timeout).count()));
    while (true) {
      pollfd p{fd_, POLLIN, 0};
      const int rc = ::poll(&p, 1, wait_ms);
      if (rc < 0 && errno != EINTR) return error("poll");
      if (rc <= 0) return appended;
      v4l2_buffer buf{};
      buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      buf.memory = V4L2_MEMORY_MMAP;
      if (xioctl(fd_, VIDIOC_DQBUF, &buf) != 0) {
        if (errno == EAGAIN) return appended;
        return error("VIDIOC_DQBUF");
      }
      Frame f;
      f.format = info_.format;
      f.width = info_.width;
      f.height = info_.height;
      f.stride_bytes = info_.format == PixelFormat::kMjpeg ? 0 : stride_;
      const auto& m = maps_[buf.index];
      const std::size_t used = std::min<std::size_t>(buf.bytesused, m.second);
      const auto* data = static_cast<const std::uint8_t*>(m.first);
      f.pixels.assign(data, data + used);
      if (f.format != PixelFormat::kMjpeg && used < static_cast<std::size_t>(stride_) * f.height) {
        f.missing_bytes =
            static_cast<std::uint32_t>(static_cast<std::size_t>(stride_) * f.height - used);
        f.pixels.resize(static_cast<std::size_t>(stride_) * f.height, 0);
        count_incomplete(1);
      }
      f.frame_id = buf.sequence;
      if (have_sequence_ && buf.sequence > last_sequence_ + 1)
        count_lost(buf.sequence - last_sequence_ - 1);
      if (!have_sequence_) first_sequence_ = buf.sequence;
      have_sequence_ = true;
      last_sequence_ = buf.sequence;
      f.frame_index = buf.sequence - first_sequence_;
      const bool monotonic =
          (buf.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) == V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC;
      const std::int64_t stamp = static_cast<std::int64_t>(buf.timestamp.tv_sec) * 1'000'000'000 +
                                 static_cast<std::int64_t>(buf.timestamp.tv_usec) * 1000;
      f.host_ns = monotonic && !clock().is_simulated() ? stamp : clock().now_ns();
      f.device_stamp_ns = stamp;
      out.push_back(std::move(f));
      ++appended;
      if (xioctl(fd_, VIDIOC_QBUF, &buf) != 0) return error("VIDIOC_QBUF");
      wait_ms = 0;
    }
  }

  void describe(devices::DeviceInfo& info) const override {
    info.model = card_.empty() ? "V4L2 camera" : card_;
    info.details = {{"device", device_}, {"driver", driver_}};
  }

 private:
  Status error(const char* what) {
    return Status(
        errno == ENODEV ? StatusCode::kUnavailable : StatusCode::kIoError,
        "camera '" + name() + "' (" + device_ + "): " + what + ": " + std::strerror(errno));
  }

  Status open_and_stream() {
    fd_ = ::open(device_.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
    if (fd_ < 0)
      return Status(errno == ENOENT ? StatusCode::kNotFound : StatusCode::kUnavailable,
                    "camera '" + name() + "': " + device_ + ": " + std::strerror(errno));
    v4l2_capability cap{};
    if (xioctl(fd_, VIDIOC_QUERYCAP, &cap) != 0)
      return Status(StatusCode::kFailedPrecondition, "camera '" + name() + "': " + device_ +
                                                         " is not a V4L2 device (" +
                                                         std::strerror(errno) + ")");
    driver_ = reinterpret_cast<const char*>(cap.driver);
    card_ = reinterpret_cast<const char*>(cap.card);
    const std::uint32_t caps =
        (cap.capabilities & V4L2_CAP_DEVICE_CAPS) != 0 ? cap.device_caps : cap.capabilities;
    if ((caps & V4L2_CAP_VIDEO_CAPTURE) == 0 || (caps & V4L2_CAP_STREAMING) == 0)
      return failed_precondition("camera '" + name() + "': " + device_ + " (" + card_ +
                                 ") cannot capture video with streaming I/O");
    v4l2_format fmt{};
    fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    fmt.fmt.pix.width = info_.width;
    fmt.fmt.pix.height = info_.height;
    fmt.fmt.pix.pixelformat = info_.format == PixelFormat::kMjpeg   ? V4L2_PIX_FMT_MJPEG
                              : info_.format == PixelFormat::kMono8 ? V4L2_PIX_FMT_GREY
                                                                    : V4L2_PIX_FMT_YUYV;
    fmt.fmt.pix.field = V4L2_FIELD_NONE;
    const std::uint32_t wanted = fmt.fmt.pix.pixelformat;
    if (xioctl(fd_, VIDIOC_S_FMT, &fmt) != 0) return error("VIDIOC_S_FMT");
    if (fmt.fmt.pix.pixelformat != wanted)
      return failed_precondition("camera '" + name() + "': " + device_ +
                                 " does not offer pixel format " +
                                 std::string(devices::to_string(info_.format)));
    info_.width = fmt.fmt.pix.width;
    info_.height = fmt.fmt.pix.height;
    stride_ = fmt.fmt.pix.bytesperline;
    v4l2_streamparm parm{};
    parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    parm.parm.capture.timeperframe.numerator = 1000;
    parm.parm.capture.timeperframe.denominator =
        static_cast<std::uint32_t>(info_.frame_rate_hz * 1000.0);
    if (xioctl(fd_, VIDIOC_S_PARM, &parm) == 0 && parm.parm.capture.timeperframe.numerator > 0)
      info_.frame_rate_hz = static_cast<double>(parm.parm.capture.timeperframe.denominator) /
                            parm.parm.capture.timeperframe.numerator;
    v4l2_requestbuffers req{};
    req.count = static_cast<std::uint32_t>(buffers_);
    req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    req.memory = V4L2_MEMORY_MMAP;
    if (xioctl(fd_, VIDIOC_REQBUFS, &req) != 0) return error("VIDIOC_REQBUFS");
    if (req.count < 2) return failed_precondition("camera '" + name() + "': too few buffers");
    for (std::uint32_t i = 0; i < req.count; ++i) {
      v4l2_buffer buf{};
      buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      buf.memory = V4L2_MEMORY_MMAP;
      buf.index = i;
      if (xioctl(fd_, VIDIOC_QUERYBUF, &buf) != 0) return error("VIDIOC_QUERYBUF");
      void* p = ::mmap(nullptr, buf.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, buf.m.offset);
      if (p == MAP_FAILED) return error("mmap");
      maps_.emplace_back(p, buf.length);
      if (xioctl(fd_, VIDIOC_QBUF, &buf) != 0) return error("VIDIOC_QBUF");
    }
    v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (xioctl(fd_, VIDIOC_STREAMON, &type) != 0) return error("VIDIOC_STREAMON");
    streaming_ = true;
    have_sequence_ = false;
    return {};
  }

  void release() {
    if (streaming_) {
      v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      xioctl(fd_, VIDIOC_STREAMOFF, &type);
      streaming_ = false;
    }
    for (auto& [p, len] : maps_) ::munmap(p, len);
    maps_.clear();
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }

  std::string device_ = "/dev/video0";
  int buffers_ = 4;
  devices::CameraInfo info_{640,  480, PixelFormat::kYuyv, devices::TriggerMode::kFreeRun,
                            30.0, 0.0};
  int fd_ = -1;
  bool streaming_ = false;
  std::uint32_t stride_ = 0;
  std::vector<std::pair<void*, std::size_t>> maps_;
  std::string driver_, card_;
  bool have_sequence_ = false;
  std::uint32_t last_sequence_ = 0;
  std::uint32_t first_sequence_ = 0;
};

}  // namespace

Result<std::unique_ptr<devices::Camera>> make_v4l2_camera(const devices::DeviceContext& ctx) {
  return std::unique_ptr<devices::Camera>(new V4l2Camera(ctx));
}

}  // namespace hc::rig
