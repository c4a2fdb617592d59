// Backend "aravis": a GigE Vision (or USB3 Vision) camera through Aravis 0.8, as a devices::Camera.
//
// Config keys:
//   address         camera IP address or Aravis device id (required), e.g. 192.168.1.10,
//                   "Basler-21234567"
//   width, height   region of interest in pixels (default: keep the camera's)
//   offset_x, offset_y
//   pixel_format    mono8 (default), mono16, rgb8
//   trigger         hardware (default), software, free_run
//   trigger_source  hardware trigger input (default Line0; rising edge)
//   frame_rate_hz   free-run rate (default 10); for triggered modes the expected maximum rate
//   exposure_s      exposure time (default: keep the camera's)
//   buffers         stream buffers (default 8)
//   packet_socket   use Aravis's PF_PACKET fast path (default false: it does not see loopback
//                   traffic, see FAKE_CAMERA_NOTES.md, and needs CAP_NET_RAW)
//   packet_size     GVSP packet size in bytes (default 0: keep the camera's)
//
// Frames keep the camera's 16-bit frame id (GigE Vision 1.x block ids run 1..65535 and skip 0 on
// wrap-around; Aravis's fake camera starts at 65400) and unwrap it into frame_index; gaps count
// as lost. device_stamp_ns is the buffer's device timestamp. A buffer completed with missing
// packets is delivered and counted incomplete; its missing_bytes is an estimate: the stream's
// new missing packets times the GVSP payload per packet (packet size - 36 bytes of IP, UDP and
// GVSP headers), capped at the frame size (Aravis does not report missing bytes per buffer).
#include <arv.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <ctime>

#include "backend_factories.h"

namespace hc::rig {
namespace {

using devices::CameraInfo;
using devices::Frame;
using devices::PixelFormat;
using devices::TriggerMode;

// GError -> Status (and frees it).
Status gerror_status(GError* error, StatusCode code, const std::string& what) {
  std::string message = what + ": " + (error != nullptr ? error->message : "unknown error");
  if (error != nullptr) g_error_free(error);
  return Status(code, std::move(message));
}

std::int64_t clock_ns(clockid_t id) {
  timespec ts{};
  ::clock_gettime(id, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

class AravisCamera final : public devices::Camera {
 public:
  explicit AravisCamera(const devices::DeviceContext& ctx) : Camera(ctx) {}
  ~AravisCamera() override { release(); }

  CameraInfo camera_info() const override { return info_; }

 protected:
  Status on_configure(ConfigNode node) override {
    std::string format = "mono8", trigger = "hardware";
    node.required("address", address_);
    node.optional("width", width_, Bounds::between(1, 65535));
    node.optional("height", height_, Bounds::between(1, 65535));
    node.optional("offset_x", offset_x_, Bounds::between(0, 65535));
    node.optional("offset_y", offset_y_, Bounds::between(0, 65535));
    node.optional("pixel_format", format, {"mono8", "mono16", "rgb8"});
    node.optional("trigger", trigger, {"hardware", "software", "free_run"});
    node.optional("trigger_source", trigger_source_);
    node.optional("frame_rate_hz", info_.frame_rate_hz, Bounds{0.0, 10000.0, true, false});
    node.optional("exposure_s", exposure_s_, Bounds::positive());
    node.optional("buffers", buffers_, Bounds::between(2, 256));
    node.optional("packet_socket", packet_socket_);
    node.optional("packet_size", packet_size_, Bounds::between(0, 65535));
    HC_RETURN_IF_ERROR(node.status());
    info_.format = *devices::pixel_format_from_string(format);
    info_.trigger_mode = *devices::trigger_mode_from_string(trigger);
    info_.exposure_s = exposure_s_;
    info_.width = static_cast<std::uint32_t>(width_);
    info_.height = static_cast<std::uint32_t>(height_);
    return {};
  }

  Status on_activate() override {
    GError* error = nullptr;
    camera_ = arv_camera_new(address_.c_str(), &error);
    if (camera_ == nullptr)
      return gerror_status(error, StatusCode::kUnavailable, "Aravis camera '" + address_ + "'");
    Status s = setup();
    if (!s.ok()) {
      release();
      return s;
    }
    return {};
  }

  Status on_deactivate() override {
    release();
    return {};
  }

  Status on_reset() override {
    release();
    return {};
  }

  Status on_software_trigger() override {
    if (info_.trigger_mode != TriggerMode::kSoftware)
      return failed_precondition("camera '" + name() +
                                 "': software_trigger needs trigger: software");
    GError* error = nullptr;
    arv_camera_software_trigger(camera_, &error);
    if (error != nullptr)
      return gerror_status(error, StatusCode::kUnavailable,
                           "camera '" + name() + "': TriggerSoftware");
    return {};
  }

  Result<std::size_t> on_read(std::vector<Frame>& out, devices::Duration timeout) override {
    std::size_t appended = 0;
    const auto timeout_us = static_cast<guint64>(std::max<std::int64_t>(
        0, std::chrono::duration_cast<std::chrono::microseconds>(timeout).count()));
    ArvBuffer* buffer = arv_stream_timeout_pop_buffer(stream_, timeout_us);
    while (buffer != nullptr) {
      if (take(buffer, out)) ++appended;
      arv_stream_push_buffer(stream_, buffer);
      buffer = arv_stream_try_pop_buffer(stream_);
    }
    return appended;
  }

  void describe(devices::DeviceInfo& info) const override {
    info.model = model_.empty() ? "GigE Vision camera (Aravis)" : model_;
    info.serial = serial_;
    info.details = {{"address", address_},
                    {"trigger", std::string(devices::to_string(info_.trigger_mode))}};
    if (stream_ == nullptr) return;
    for (const char* key :
         {"n_completed_buffers", "n_failures", "n_underruns", "n_received_packets",
          "n_missing_packets", "n_resend_requests", "n_resent_packets", "n_duplicated_packets"})
      info.details.emplace_back(key, std::to_string(stream_info(key)));
  }

 private:
  guint64 stream_info(const char* key) const {
    return stream_ != nullptr ? arv_stream_get_info_uint64_by_name(stream_, key) : 0;
  }

  Status setup() {
    GError* error = nullptr;
    auto check = [&](const char* what) -> Status {
      if (error == nullptr) return {};
      return gerror_status(std::exchange(error, nullptr), StatusCode::kFailedPrecondition,
                           "Aravis camera '" + address_ + "': " + what);
    };
    const char* vendor = arv_camera_get_vendor_name(camera_, &error);
    HC_RETURN_IF_ERROR(check("DeviceVendorName"));
    const char* model = arv_camera_get_model_name(camera_, &error);
    HC_RETURN_IF_ERROR(check("DeviceModelName"));
    const char* serial = arv_camera_get_device_serial_number(camera_, &error);
    g_clear_error(&error);  // optional on some cameras
    model_ = std::string(vendor != nullptr ? vendor : "") + " " + (model != nullptr ? model : "");
    serial_ = serial != nullptr ? serial : "";

    if (width_ > 0 || height_ > 0 || offset_x_ > 0 || offset_y_ > 0) {
      gint x = 0, y = 0, w = 0, h = 0;
      arv_camera_get_region(camera_, &x, &y, &w, &h, &error);
      HC_RETURN_IF_ERROR(check("reading the region"));
      arv_camera_set_region(camera_, offset_x_, offset_y_, width_ > 0 ? width_ : w,
                            height_ > 0 ? height_ : h, &error);
      HC_RETURN_IF_ERROR(check("setting the region"));
    }
    ArvPixelFormat format = ARV_PIXEL_FORMAT_MONO_8;
    if (info_.format == PixelFormat::kMono16) format = ARV_PIXEL_FORMAT_MONO_16;
    if (info_.format == PixelFormat::kRgb8) format = ARV_PIXEL_FORMAT_RGB_8_PACKED;
    arv_camera_set_pixel_format(camera_, format, &error);
    HC_RETURN_IF_ERROR(check("PixelFormat"));
    if (exposure_s_ > 0) {
      arv_camera_set_exposure_time(camera_, exposure_s_ * 1e6, &error);
      HC_RETURN_IF_ERROR(check("ExposureTime"));
    }
    arv_camera_set_acquisition_mode(camera_, ARV_ACQUISITION_MODE_CONTINUOUS, &error);
    HC_RETURN_IF_ERROR(check("AcquisitionMode"));
    switch (info_.trigger_mode) {
      case TriggerMode::kFreeRun:
        arv_camera_clear_triggers(camera_, &error);
        HC_RETURN_IF_ERROR(check("TriggerMode Off"));
        arv_camera_set_frame_rate(camera_, info_.frame_rate_hz, &error);
        HC_RETURN_IF_ERROR(check("AcquisitionFrameRate"));
        break;
      case TriggerMode::kSoftware:
        arv_camera_set_trigger(camera_, "Software", &error);
        HC_RETURN_IF_ERROR(check("TriggerSource Software"));
        break;
      case TriggerMode::kHardware:
        arv_camera_set_trigger(camera_, trigger_source_.c_str(), &error);
        HC_RETURN_IF_ERROR(check(("TriggerSource " + trigger_source_).c_str()));
        break;
    }
    gint x = 0, y = 0, w = 0, h = 0;
    arv_camera_get_region(camera_, &x, &y, &w, &h, &error);
    HC_RETURN_IF_ERROR(check("reading the region"));
    info_.width = static_cast<std::uint32_t>(w);
    info_.height = static_cast<std::uint32_t>(h);
    if (info_.exposure_s == 0) {
      const double us = arv_camera_get_exposure_time(camera_, &error);
      g_clear_error(&error);
      info_.exposure_s = us * 1e-6;
    }
    const gboolean gv = arv_camera_is_gv_device(camera_);
    if (gv) {
      if (packet_size_ > 0) {
        arv_camera_gv_set_packet_size(camera_, packet_size_, &error);
        HC_RETURN_IF_ERROR(check("GevSCPSPacketSize"));
      }
      gv_packet_size_ = arv_camera_gv_get_packet_size(camera_, &error);
      g_clear_error(&error);
      if (!packet_socket_)
        arv_camera_gv_set_stream_options(camera_, ARV_GV_STREAM_OPTION_PACKET_SOCKET_DISABLED);
    }
    payload_ = static_cast<std::size_t>(arv_camera_get_payload(camera_, &error));
    HC_RETURN_IF_ERROR(check("PayloadSize"));
    stream_ = arv_camera_create_stream(camera_, nullptr, nullptr, &error);
    if (stream_ == nullptr)
      return gerror_status(error, StatusCode::kUnavailable,
                           "Aravis camera '" + address_ + "': creating the stream");
    for (int i = 0; i < buffers_; ++i)
      arv_stream_push_buffer(stream_, arv_buffer_new(payload_, nullptr));
    have_last_id_ = false;
    missing_packets_seen_ = 0;
    arv_camera_start_acquisition(camera_, &error);
    HC_RETURN_IF_ERROR(check("AcquisitionStart"));
    return {};
  }

  void release() {
    if (camera_ != nullptr && stream_ != nullptr) arv_camera_stop_acquisition(camera_, nullptr);
    if (stream_ != nullptr) g_object_unref(stream_);
    if (camera_ != nullptr) g_object_unref(camera_);
    stream_ = nullptr;
    camera_ = nullptr;
  }

  // Converts a popped buffer into a frame; false when it holds no image.
  bool take(ArvBuffer* buffer, std::vector<Frame>& out) {
    const ArvBufferStatus status = arv_buffer_get_status(buffer);
    const std::uint64_t id = arv_buffer_get_frame_id(buffer);
    const std::uint64_t missing_now = stream_info("n_missing_packets");
    const std::uint64_t new_missing = missing_now - std::min(missing_now, missing_packets_seen_);
    missing_packets_seen_ = missing_now;
    // A buffer whose leader was lost has no frame id (0): it cannot be placed; the gap it leaves
    // in the ids is counted lost when the next identified frame arrives.
    if (id == 0) return false;
    // Unwrap: 16-bit ids cycle through 1..65535; extended (64-bit) ids just increase.
    std::uint64_t index;
    if (id <= 0xFFFF) {
      if (!have_last_id_) {
        unwrapped_ = 0;
      } else {
        const std::uint64_t step = (id + 65535 - last_id_) % 65535;  // cycle of 65535 ids
        if (step == 0) return false;                                 // the same frame again
        if (step < 32768) {
          unwrapped_ += step;
          if (step > 1) count_lost(step - 1);
        } else {
          return false;  // an older frame arriving late: already counted lost
        }
      }
      index = unwrapped_;
    } else {
      if (have_last_id_ && id > last_id_ + 1) count_lost(id - last_id_ - 1);
      if (!have_last_id_) first_id_ = id;
      index = id - first_id_;
    }
    have_last_id_ = true;
    last_id_ = id;
    if (status != ARV_BUFFER_STATUS_SUCCESS && status != ARV_BUFFER_STATUS_MISSING_PACKETS) {
      count_lost(1);  // aborted, timeout, size mismatch: no usable image
      return false;
    }
    size_t size = 0;
    const void* data = arv_buffer_get_data(buffer, &size);
    Frame f;
    f.format = info_.format;
    // A buffer whose leader packet was lost has no geometry: use the configured region.
    // Only a complete buffer has reliable image parts (Aravis asserts on the others).
    const bool has_image = status == ARV_BUFFER_STATUS_SUCCESS &&
                           arv_buffer_get_payload_type(buffer) == ARV_BUFFER_PAYLOAD_TYPE_IMAGE;
    const gint bw = has_image ? arv_buffer_get_image_width(buffer) : 0;
    const gint bh = has_image ? arv_buffer_get_image_height(buffer) : 0;
    f.width = bw > 0 ? static_cast<std::uint32_t>(bw) : info_.width;
    f.height = bh > 0 ? static_cast<std::uint32_t>(bh) : info_.height;
    f.stride_bytes = f.width * static_cast<std::uint32_t>(devices::bytes_per_pixel(f.format));
    const std::size_t expected = static_cast<std::size_t>(f.stride_bytes) * f.height;
    f.pixels.assign(expected, 0);
    std::memcpy(f.pixels.data(), data, std::min(size, expected));
    f.frame_id = id;
    f.frame_index = index;
    f.device_stamp_ns = static_cast<std::int64_t>(arv_buffer_get_timestamp(buffer));
    // The system timestamp is wall-clock ns; move it onto the monotonic time line.
    const std::int64_t now_mono =
        clock().is_simulated() ? clock().now_ns() : clock_ns(CLOCK_MONOTONIC);
    const auto sys = static_cast<std::int64_t>(arv_buffer_get_system_timestamp(buffer));
    const std::int64_t age =
        sys > 0 ? std::max<std::int64_t>(0, clock_ns(CLOCK_REALTIME) - sys) : 0;
    f.host_ns = now_mono - age;
    f.exposure_s = info_.exposure_s;
    if (status == ARV_BUFFER_STATUS_MISSING_PACKETS || size < expected) {
      const std::uint64_t per_packet = gv_packet_size_ > 36 ? gv_packet_size_ - 36 : 1;
      std::uint64_t missing = std::max<std::uint64_t>(1, new_missing) * per_packet;
      if (size < expected) missing = std::max<std::uint64_t>(missing, expected - size);
      f.missing_bytes = static_cast<std::uint32_t>(std::min<std::uint64_t>(missing, expected));
      count_incomplete(1);
    }
    out.push_back(std::move(f));
    return true;
  }

  std::string address_;
  int width_ = 0, height_ = 0, offset_x_ = 0, offset_y_ = 0;
  std::string trigger_source_ = "Line0";
  double exposure_s_ = 0;
  int buffers_ = 8;
  bool packet_socket_ = false;
  int packet_size_ = 0;
  CameraInfo info_{0, 0, PixelFormat::kMono8, TriggerMode::kHardware, 10.0, 0.0};
  std::string model_, serial_;
  ArvCamera* camera_ = nullptr;
  ArvStream* stream_ = nullptr;
  std::size_t payload_ = 0;
  std::uint64_t gv_packet_size_ = 0;
  bool have_last_id_ = false;
  std::uint64_t last_id_ = 0;
  std::uint64_t first_id_ = 0;
  std::uint64_t unwrapped_ = 0;
  std::uint64_t missing_packets_seen_ = 0;
};

}  // namespace

Result<std::unique_ptr<devices::Camera>> make_aravis_camera(const devices::DeviceContext& ctx) {
  return std::unique_ptr<devices::Camera>(new AravisCamera(ctx));
}

}  // namespace hc::rig
