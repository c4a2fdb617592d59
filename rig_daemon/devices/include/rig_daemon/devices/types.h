// Data that devices produce and consume: camera frames, pulse trains, calibrations, the arm's
// workspace, and the samples a session records (trigger edges, FSR and force-torque samples, arm
// commands and states), which live in the session library (rig_daemon/session/records.h) and are
// named here in the devices' namespace.
//
// Every sample carries
//  * host_ns: host monotonic time (ns, on the Clock the device was created with) at which the host
//    received the sample (for frames: when the last byte arrived), and
//  * the device's own counter (frame id, sequence number) and, when the device has a clock,
//    device_stamp_ns (ns on the device's time line, which is NOT the host's; e.g. GigE Vision
//    timestamp ticks converted to ns, the firmware's µs timer × 1000).
// trigger_index, when set, is the index of the trigger edge (TriggerEdge::index) that caused the
// sample; backends set it only when the device itself tells them (firmware ADC sample latched on an
// edge, simulated hardware-triggered camera); otherwise the scheduler associates by time.
//
// SI units throughout (m, rad, N, N·m, s); names carry units.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "rig_daemon/session/records.h"

namespace hc::devices {

// The samples a session records, named here in the devices' namespace (rig_daemon/session/
// records.h).
using session::ArmCommand;
using session::ArmMotion;
using session::ArmPose;
using session::ArmState;
using session::FsrSample;
using session::to_string;
using session::TriggerEdge;
using session::WrenchSample;

// ---------------------------------------------------------------------------------------------
// Cameras

enum class PixelFormat : std::uint8_t {
  kMono8,   // 1 byte per pixel
  kMono16,  // 2 bytes per pixel, little-endian
  kRgb8,    // 3 bytes per pixel, R G B
  kBgr8,    // 3 bytes per pixel, B G R
  kYuyv,    // 4 bytes per 2 pixels (YUV 4:2:2, Y0 U Y1 V)
  kMjpeg,   // compressed JPEG; `pixels` holds one JPEG file, stride_bytes = 0
};

// "mono8", "mono16", "rgb8", "bgr8", "yuyv", "mjpeg".
std::string_view to_string(PixelFormat format);
// Inverse of to_string(); nullopt for an unknown name.
std::optional<PixelFormat> pixel_format_from_string(std::string_view name);
// The `encoding` field of foxglove.RawImage ("mono8", "mono16", "rgb8", "bgr8", "yuyv"), or
// "jpeg" (the `format` field of foxglove.CompressedImage) for kMjpeg.
std::string_view foxglove_encoding(PixelFormat format);
// Bytes per pixel for uncompressed formats (kYuyv: 2); 0 for kMjpeg.
std::size_t bytes_per_pixel(PixelFormat format);

// One image from a camera. Rows are top to bottom; row r starts at pixels[r * stride_bytes].
struct Frame {
  std::vector<std::uint8_t> pixels;
  PixelFormat format = PixelFormat::kMono8;
  std::uint32_t width = 0;         // pixels
  std::uint32_t height = 0;        // pixels
  std::uint32_t stride_bytes = 0;  // bytes per row (>= width * bytes_per_pixel)
  // The camera's own frame id as it reports it (GigE Vision block ids are 16-bit on old devices
  // and wrap; the fake camera starts at 65400). See frame_index for a non-wrapping count.
  std::uint64_t frame_id = 0;
  // Frames delivered by this device since activate(), counting from 0 and including lost ones
  // (a gap means frames were lost); backends unwrap frame_id into it.
  std::uint64_t frame_index = 0;
  std::optional<std::int64_t> device_stamp_ns;  // camera clock, when it has one
  std::int64_t host_ns = 0;                     // host monotonic ns when the frame completed
  std::optional<std::uint64_t> trigger_index;   // see the file comment
  double exposure_s = 0.0;                      // 0 when unknown
  // Bytes the camera announced but did not deliver (GigE packet loss filled with zeros); a
  // frame with missing bytes is still delivered and counted in DeviceStats::incomplete.
  std::uint32_t missing_bytes = 0;

  // True when the buffer is consistent with format, width, height and stride.
  bool valid() const;
};

// ---------------------------------------------------------------------------------------------
// Trigger

// A pulse train to fire on every configured line at once.
struct PulseTrain {
  double rate_hz = 15.0;        // pulses per second (> 0)
  double pulse_width_s = 1e-3;  // high time (> 0, < 1 / rate_hz)
  std::uint64_t count = 0;      // pulses to fire; 0 = until stop()
};

// ---------------------------------------------------------------------------------------------
// Force-sensing resistor (FSR)

// Maps a raw FSR reading to newtons. The FSR's conductance follows a power law of the force past a
// break force (Interlink FSR 400 datasheet), read through a voltage divider; we calibrate the
// reading directly against a reference load cell:
//   x = raw / full_scale;  F = 0 if x < threshold, else scale_n * ((x - threshold) / (1 -
//   threshold))^exponent
struct FsrCalibration {
  double full_scale = 4095.0;  // raw value at the top of the range (12-bit ADC; Phidget: 1000)
  double threshold = 0.02;     // fraction of full scale below which the force reads 0
  double scale_n = 60.0;       // force at full scale, N
  double exponent = 1.6;       // power-law exponent (dimensionless)

  double to_newtons(double raw) const;
  // Inverse of to_newtons() for forces > 0 (raw at or above the threshold); 0 N maps to the
  // threshold. Used by the simulator.
  double to_raw(double force_n) const;
};

// ---------------------------------------------------------------------------------------------
// Six-axis force-torque sensor

// Counts per unit, as the ATI Net F/T reports them (its calibration: counts per force unit and per
// torque unit), converted to SI: force_n = counts / counts_per_n, torque_nm = counts /
// counts_per_nm.
struct WrenchCalibration {
  double counts_per_n = 1'000'000.0;   // ATI default "counts per force" with force in N
  double counts_per_nm = 1'000'000.0;  // ATI default "counts per torque" with torque in N·m
};

// ---------------------------------------------------------------------------------------------
// 4-DOF arm (x, y, z and yaw of the tool; a SCARA-like arm pressing a vertical probe)

// Axis-aligned workspace box of the tool tip plus speed limit.
struct ArmLimits {
  ArmPose min{-0.2, -0.2, 0.0, -3.14159265358979};
  ArmPose max{0.2, 0.2, 0.3, 3.14159265358979};
  double max_speed_m_s = 0.05;
  bool contains(const ArmPose& p) const;
};

}  // namespace hc::devices
