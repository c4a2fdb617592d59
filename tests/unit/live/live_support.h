// A daemon on the embedded default rig, running on the host's clock (the page is about real
// time), with its live page on a free loopback port, and an HTTP client for it.
#pragma once

#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <string>
#include <thread>

#include "rig_daemon/daemon/daemon.h"
#include "rig_daemon/daemon/http_server.h"
#include "rig_daemon/daemon/plan.h"
#include "rig_daemon/daemon/rig_config.h"
#include "test_data.h"
// After Eigen (through the daemon's headers): httplib.h includes <resolv.h>, whose `_res` macro
// breaks Eigen's headers when they come later.
#include <httplib.h>

namespace hc::rig::testing {

// A press long enough to outlast any test (each test stops it; about a minute otherwise): two
// locations, two levels, 150 steps each, two cameras.
inline Plan long_press() {
  Result<Plan> p = parse_plan(R"(protocol: automated
name: live
locations:
  - {position_m: [0.0, 0.0, 0.062], direction: [0, 0, -1]}
  - {position_m: [0.015, 0.0, 0.062], direction: [0, 0, -1]}
force_levels_n: [20, 30]
steps: 150
settle_s: 0.05
max_force_n: 40
workspace: {min_m: [-0.05, -0.05, 0.0], max_m: [0.05, 0.05, 0.12]}
cameras: [cam0, cam1]
)",
                              "live.yaml");
  EXPECT_TRUE(p.ok()) << p.status().to_string();
  return *p;
}

struct LiveRig {
  hc::testing::ScratchDir dir;
  std::unique_ptr<Daemon> daemon;
  std::unique_ptr<HttpServer> http;
  std::string token;

  explicit LiveRig(HttpOptions o = {}) {
    Result<RigConfig> cfg = embedded_default_rig_config();
    EXPECT_TRUE(cfg.ok());
    cfg->sessions_dir = dir.path() / "sessions";
    // Real time on a loaded (or sanitized) machine can pause longer than the default 50 ms stall
    // limit, which would (correctly) abort the capture; the stall trip is tested on simulated time.
    cfg->stall_timeout_s = 1.0;
    Daemon::Options d;
    d.config = *cfg;
    d.software_version = "test";
    Result<std::unique_ptr<Daemon>> created = Daemon::create(d);
    EXPECT_TRUE(created.ok()) << created.status().to_string();
    daemon = std::move(created).value();
    Result<std::string> t = make_token();
    EXPECT_TRUE(t.ok());
    token = *t;
    o.port = 0;
    o.token = token;
    Result<std::unique_ptr<HttpServer>> s = HttpServer::start(*daemon, o);
    EXPECT_TRUE(s.ok()) << s.status().to_string();
    http = std::move(s).value();
  }
  ~LiveRig() {
    http.reset();
    if (daemon) {
      (void)daemon->stop();
      daemon->wait_idle(60000);
    }
  }
  httplib::Client client() const {
    httplib::Client c("127.0.0.1", http->port());
    c.set_read_timeout(10, 0);
    c.set_connection_timeout(5, 0);
    return c;
  }
  httplib::Headers bearer() const { return {{"Authorization", "Bearer " + token}}; }
  // Waits (up to 30 s) until the session reports `state`.
  bool wait_state(const std::string& state) const {
    for (int i = 0; i < 600; ++i) {
      if (daemon->status()["state"] == state) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return false;
  }
};

}  // namespace hc::rig::testing
