// Runs Debian's Aravis fake GigE Vision camera (`arv-fake-gv-camera-0.8`, package aravis-tools) as
// a child process on 127.0.0.1 for hardware-in-the-loop tests of the Aravis backend.
//
// The fake camera can only bind an address that an interface has (on lo: 127.0.0.1 only) and
// GVCP's fixed port 3956, so one instance per machine can run at a time: start() takes an
// exclusive lock (flock on /tmp/hardcopy-arv-fake-gv-camera.lock) that parallel tests (ctest -j,
// other test executables) wait for, and holds it until the camera is stopped.
// See ../shared/data/protocols/aravis_fake_gv_camera/FAKE_CAMERA_NOTES.md.
#pragma once

#include <sys/types.h>

#include <memory>
#include <string>

#include "common/status.h"

namespace hc::rig::sim {

struct FakeGvCameraOptions {
  std::string binary = "arv-fake-gv-camera-0.8";  // looked up in PATH
  std::string serial = "HCFAKE01";
  int gvsp_lost_per_thousand = 0;  // -r: GVSP packets dropped per thousand (fault injection)
  double lock_timeout_s = 60.0;    // waiting for another test's fake camera to finish
  double ready_timeout_s = 5.0;    // waiting for the camera to answer GVCP discovery
};

class FakeGvCamera {
 public:
  // The binary's full path, or empty when it is not installed.
  static std::string find_binary(const std::string& name = FakeGvCameraOptions{}.binary);

  // Locks, spawns the camera on 127.0.0.1 and waits until it answers a GVCP discovery request.
  // kNotFound when the binary is absent, kDeadlineExceeded when the lock or the camera does not
  // come in time, kIoError when it cannot be spawned.
  static Result<std::unique_ptr<FakeGvCamera>> start(const FakeGvCameraOptions& options = {});
  ~FakeGvCamera();  // SIGTERM (then SIGKILL), reap, unlock
  FakeGvCamera(const FakeGvCamera&) = delete;
  FakeGvCamera& operator=(const FakeGvCamera&) = delete;

  std::string address() const { return "127.0.0.1"; }
  const std::string& serial() const { return serial_; }
  pid_t pid() const { return pid_; }

 private:
  FakeGvCamera() = default;
  pid_t pid_ = -1;
  int lock_fd_ = -1;
  std::string serial_;
};

// Sends one GVCP DISCOVERY_CMD to address:3956 and waits for the DISCOVERY_ACK (GigE Vision 2.0
// section 16.1.1: key 0x42, flags 0x11, command 0x0002, length 0; ack 0x0003). True if it came.
bool gvcp_discovery_answers(const std::string& address, double timeout_s);

}  // namespace hc::rig::sim
