// The hardware backends with no hardware present (CI machines, containers): every one is
// registered, and activating it fails with a clear Status instead of crashing or hanging.
#include <gtest/gtest.h>

#include <filesystem>

#include "rig_daemon/backends/hardware_backends.h"
#include "rig_daemon/backends/libcamera_cameras.h"
#include "rig_daemon/devices/registry.h"

namespace hc::rig {
namespace {

using devices::DeviceKind;

template <typename D>
std::unique_ptr<D> make(const std::string& backend, const std::string& yaml, Status* configured) {
  devices::BackendRegistry registry;
  EXPECT_TRUE(register_hardware_backends(registry).ok());
  devices::DeviceContext ctx;
  ctx.name = "dev";
  ctx.backend = backend;
  auto d = registry.create<D>(ctx);
  EXPECT_TRUE(d.ok()) << d.status().to_string();
  if (!d.ok()) return nullptr;
  *configured = devices::configure_from_yaml(**d, yaml);
  return std::move(*d);
}

TEST(HardwareBackends, AllAreRegisteredByName) {
  devices::BackendRegistry registry;
  ASSERT_TRUE(register_hardware_backends(registry).ok());
  EXPECT_TRUE(registry.has(DeviceKind::kForceTorque, "netft"));
  EXPECT_TRUE(registry.has(DeviceKind::kArm, "modbus"));
  for (const char* cam : {"aravis", "v4l2", "libcamera"})
    EXPECT_TRUE(registry.has(DeviceKind::kCamera, cam)) << cam;
  EXPECT_TRUE(registry.has(DeviceKind::kTrigger, "gpiod"));
  EXPECT_TRUE(registry.has(DeviceKind::kFsr, "phidget"));
  EXPECT_FALSE(registry.description(DeviceKind::kCamera, "v4l2").empty());
}

TEST(V4l2Backend, MissingDeviceAndNonV4l2DeviceFailClearly) {
  Status configured;
  auto cam = make<devices::Camera>("v4l2", "device: /dev/hardcopy-no-video\n", &configured);
  ASSERT_TRUE(cam);
  ASSERT_TRUE(configured.ok()) << configured.to_string();
  Status s = cam->activate();
  EXPECT_EQ(s.code(), StatusCode::kNotFound) << s.to_string();
  EXPECT_NE(s.message().find("/dev/hardcopy-no-video"), std::string::npos);
  auto null_dev = make<devices::Camera>("v4l2", "device: /dev/null\n", &configured);
  ASSERT_TRUE(null_dev);
  s = null_dev->activate();
  EXPECT_EQ(s.code(), StatusCode::kFailedPrecondition) << s.to_string();
  EXPECT_NE(s.message().find("not a V4L2 device"), std::string::npos) << s.to_string();
  EXPECT_EQ(null_dev->state(), devices::DeviceState::kError);
  auto bad = make<devices::Camera>("v4l2", "pixel_format: h264\n", &configured);
  EXPECT_NE(configured.message().find("pixel_format"), std::string::npos) << configured.to_string();
}

TEST(GpiodBackend, MissingChipAndMissingLinesFailClearly) {
  Status configured;
  auto trig =
      make<devices::Trigger>("gpiod", "chip: hardcopy-no-chip\nlines: [3, 4]\n", &configured);
  ASSERT_TRUE(trig);
  ASSERT_TRUE(configured.ok()) << configured.to_string();
  EXPECT_EQ(trig->lines(), (std::vector<std::uint32_t>{3, 4}));
  Status s = trig->activate();
  EXPECT_FALSE(s.ok());
  EXPECT_NE(s.message().find("hardcopy-no-chip"), std::string::npos) << s.to_string();
  auto none = make<devices::Trigger>("gpiod", "chip: gpiochip0\n", &configured);
  EXPECT_NE(configured.message().find("lines"), std::string::npos) << configured.to_string();
}

TEST(LibcameraBackend, EnumeratesAndFailsClearlyWithoutCameras) {
  auto ids = list_libcamera_cameras();
  ASSERT_TRUE(ids.ok()) << ids.status().to_string();
  Status configured;
  auto cam =
      make<devices::Camera>("libcamera", "camera_id: hardcopy-no-such-camera\n", &configured);
  ASSERT_TRUE(cam);
  ASSERT_TRUE(configured.ok()) << configured.to_string();
  Status s = cam->activate();
  EXPECT_EQ(s.code(), StatusCode::kNotFound) << s.to_string();
  if (ids->empty())
    EXPECT_NE(s.message().find("libcamera found no cameras"), std::string::npos) << s.to_string();
  else
    EXPECT_NE(s.message().find("hardcopy-no-such-camera"), std::string::npos) << s.to_string();
}

TEST(PhidgetBackend, NoBoardFailsClearly) {
  Status configured;
  auto fsr = make<devices::Fsr>("phidget", "sensor: 3\ncalibration: {scale_n: 40, exponent: 1.5}\n",
                                &configured);
  ASSERT_TRUE(fsr);
  ASSERT_TRUE(configured.ok()) << configured.to_string();
  EXPECT_DOUBLE_EQ(fsr->calibration().full_scale, 1000.0);  // the board's 0..1000 sensor value
  EXPECT_DOUBLE_EQ(fsr->calibration().scale_n, 40.0);
  Status s = fsr->activate();
  if (s.ok()) GTEST_SKIP() << "a real InterfaceKit 8/8/8 is connected";
  EXPECT_NE(s.message().find("InterfaceKit"), std::string::npos) << s.to_string();
  auto bad = make<devices::Fsr>("phidget", "sensor: 8\n", &configured);
  EXPECT_NE(configured.message().find("sensor"), std::string::npos) << configured.to_string();
}

}  // namespace
}  // namespace hc::rig
