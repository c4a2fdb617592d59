// The live page's HTTP API against an in-process daemon: the same status as the control socket,
// server-sent snapshots, control only with the token (403 and nothing changed without it), estop
// stopping the arm before its response returns, and bad input — unknown routes, oversized or
// malformed requests, foreign Host headers, slow and stuck clients — without a crash or a stall
// of the capture.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <fstream>

#include "common/file_io.h"
#include "live_support.h"

namespace hc::rig {
namespace {

using testing::LiveRig;
using testing::long_press;

// A raw TCP connection to the server (for requests no well-behaved client sends).
struct RawSocket {
  int fd = -1;
  explicit RawSocket(int port) {
    fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    EXPECT_EQ(::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof(a)), 0);
  }
  ~RawSocket() { ::close(fd); }
  void send(const std::string& s) const {
    EXPECT_EQ(::send(fd, s.data(), s.size(), MSG_NOSIGNAL), static_cast<ssize_t>(s.size()));
  }
  std::string receive_some() const {
    char buf[4096];
    timeval tv{5, 0};
    ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof(tv));
    const ssize_t n = ::recv(fd, buf, sizeof(buf), 0);
    return n > 0 ? std::string(buf, static_cast<std::size_t>(n)) : std::string();
  }
};

Json body_json(const httplib::Result& r) {
  EXPECT_TRUE(r) << "no response";
  if (!r) return Json();
  return Json::parse(r->body, nullptr, false);
}

TEST(LiveHttp, StatusIsTheControlSocketsAndThePageIsServed) {
  LiveRig rig;
  auto c = rig.client();
  // Idle, the status is static: exactly what the control protocol's status command answers.
  Status err;
  const Json via_socket = rig.daemon->handle(Request{0, Command::kStatus, "", ""}, err);
  ASSERT_TRUE(err.ok());
  auto r = c.Get("/api/status");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  EXPECT_EQ(body_json(r), via_socket);
  auto page = c.Get("/");
  ASSERT_TRUE(page);
  EXPECT_EQ(page->status, 200);
  EXPECT_NE(page->get_header_value("Content-Type").find("text/html"), std::string::npos);
  EXPECT_NE(page->body.find("<title>rigd"), std::string::npos);
  EXPECT_NE(page->body.find("new EventSource(\"/api/events\")"), std::string::npos);
  auto devs = c.Get("/api/devices");
  ASSERT_TRUE(devs);
  EXPECT_EQ(body_json(devs)["devices"].size(), rig.daemon->rig().devices().size());
  EXPECT_EQ(c.Get("/api/auth")->status, 403);
  EXPECT_EQ(c.Get("/api/auth", rig.bearer())->status, 200);
}

TEST(LiveHttp, EventsCarryProgressForcesAndTheArm) {
  LiveRig rig;
  ASSERT_TRUE(rig.daemon->start(long_press()).ok());
  auto c = rig.client();
  std::vector<Json> events;
  std::string buffer;
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(3);
  auto r = c.Get("/api/events", [&](const char* data, std::size_t n) {
    buffer.append(data, n);
    std::size_t end;
    while ((end = buffer.find("\n\n")) != std::string::npos) {
      const std::string block = buffer.substr(0, end);
      buffer.erase(0, end + 2);
      if (block.rfind("data: ", 0) == 0) events.push_back(Json::parse(block.substr(6)));
    }
    return std::chrono::steady_clock::now() < until;  // then the client hangs up
  });
  ASSERT_GE(events.size(), 10u) << "fewer than 10 snapshots in 3 s";
  std::int64_t last_seq = 0, last_force_ns = 0, forces = 0;
  bool arm = false, devices = false;
  for (const Json& e : events) {
    EXPECT_GT(e["seq"].get<std::int64_t>(), last_seq);
    last_seq = e["seq"].get<std::int64_t>();
    for (const Json& f : e["force"]) {
      EXPECT_GT(f[0].get<std::int64_t>(), last_force_ns);  // no sample twice, in order
      last_force_ns = f[0].get<std::int64_t>();
      ++forces;
    }
    arm = arm || e.contains("arm");
    devices = devices || e.contains("devices");
    EXPECT_EQ(e["safety"]["state"], "ok");
    EXPECT_EQ(e["safety"]["max_force_n"], 50.0);
  }
  EXPECT_GT(forces, 100);  // the simulated F/T streams at 1 kHz
  EXPECT_TRUE(arm);
  EXPECT_TRUE(devices);
  EXPECT_EQ(events.back()["state"], "running");
  EXPECT_TRUE(events.back()["session"].contains("done"));
  // The client is gone: the stream's slot is released.
  for (int i = 0; i < 100 && rig.http->event_clients() > 0; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_EQ(rig.http->event_clients(), 0u);
}

TEST(LiveHttp, ControlNeedsTheTokenAndEstopStopsTheArmAtOnce) {
  LiveRig rig;
  ASSERT_TRUE(rig.daemon->start(long_press()).ok());
  ASSERT_TRUE(rig.wait_state("running"));
  auto c = rig.client();
  for (const char* cmd :
       {"/api/pause", "/api/resume", "/api/stop", "/api/estop", "/api/reset", "/api/start"}) {
    auto none = c.Post(cmd, "protocol: automated", "application/yaml");
    ASSERT_TRUE(none);
    EXPECT_EQ(none->status, 403) << cmd;
    auto wrong = c.Post(cmd, httplib::Headers{{"Authorization", "Bearer " + std::string(64, '0')}},
                        "", "text/plain");
    ASSERT_TRUE(wrong);
    EXPECT_EQ(wrong->status, 403) << cmd;
    auto scheme = c.Post(cmd, httplib::Headers{{"Authorization", "Basic " + rig.token}}, "",
                         "text/plain");
    EXPECT_EQ(scheme->status, 403) << cmd;
  }
  // Nothing changed: still running, no trip, the arm not stopped.
  const Json s = rig.daemon->status();
  EXPECT_EQ(s["state"], "running");
  EXPECT_FALSE(s["session"].contains("trip"));
  const auto& clock = rig.daemon->rig().clock();
  EXPECT_NE(rig.daemon->rig().world()->arm_state(clock.now_ns()).motion, devices::ArmMotion::kStopped);

  // With the token: pause, resume, then estop.
  EXPECT_EQ(c.Post("/api/pause", rig.bearer(), "", "text/plain")->status, 200);
  EXPECT_TRUE(rig.wait_state("paused"));
  EXPECT_EQ(c.Post("/api/resume", rig.bearer(), "", "text/plain")->status, 200);
  EXPECT_TRUE(rig.wait_state("running"));
  auto busy = c.Post("/api/start", rig.bearer(), long_press().source_text, "application/yaml");
  EXPECT_EQ(busy->status, 409) << busy->body;  // one session at a time, as on the socket
  const std::int64_t before = clock.now_ns();
  auto e = c.Post("/api/estop", rig.bearer(), "", "text/plain");
  const std::int64_t answered = clock.now_ns();
  ASSERT_TRUE(e);
  ASSERT_EQ(e->status, 200) << e->body;
  const Json ej = Json::parse(e->body);
  EXPECT_TRUE(ej["result"]["session_aborted"].get<bool>());
  EXPECT_TRUE(ej["result"]["arms"][0]["ok"].get<bool>());
  // Daemon::estop stops every arm before it answers: stopped when the response arrives.
  EXPECT_EQ(rig.daemon->rig().world()->arm_state(answered).motion, devices::ArmMotion::kStopped);
  ASSERT_TRUE(rig.daemon->wait_idle(30000));
  const Json summary = rig.daemon->last_summary();
  EXPECT_EQ(summary["state"], "aborted");
  EXPECT_EQ(summary["trip"]["kind"], "estop");
  // The session loop saw it in the cycle after the request (control_period_s = 1 ms): its stop
  // went out no later than one cycle after the response, with slack for a loaded machine.
  EXPECT_GE(summary["trip"]["detected_ns"].get<std::int64_t>(), before);
  EXPECT_TRUE(summary.contains("cycle"));
  // The estop leaves a safety stop: start is refused until reset (also over HTTP).
  EXPECT_EQ(c.Post("/api/start", rig.bearer(), long_press().source_text, "application/yaml")->status,
            409);
  EXPECT_EQ(c.Post("/api/reset", httplib::Headers{}, "", "text/plain")->status, 403);
  auto reset = c.Post("/api/reset", rig.bearer(), "", "text/plain");
  EXPECT_EQ(reset->status, 200) << reset->body;
  EXPECT_TRUE(rig.daemon->safety_stop().is_null());
}

TEST(LiveHttp, BadInputNeitherCrashesNorStallsTheCapture) {
  HttpOptions o;
  o.io_timeout_ms = 500;
  o.max_event_clients = 2;
  LiveRig rig(o);
  ASSERT_TRUE(rig.daemon->start(long_press()).ok());
  ASSERT_TRUE(rig.wait_state("running"));
  auto c = rig.client();
  // Unknown routes and methods.
  auto nope = c.Get("/nope");
  EXPECT_EQ(nope->status, 404);
  EXPECT_EQ(body_json(nope)["error"]["code"], "not_found");
  EXPECT_EQ(c.Post("/api/nope", rig.bearer(), "", "text/plain")->status, 404);
  EXPECT_EQ(c.Get("/api/frames/..%2F..%2Fetc%2Fpasswd.png")->status, 404);
  EXPECT_EQ(c.Get("/api/frames/nosuchcam.png")->status, 404);
  // An oversized request (2 MiB; the limit is 1 MiB), with the token: refused, nothing started.
  auto big = c.Post("/api/start", rig.bearer(), std::string(2u << 20, 'x'), "application/yaml");
  ASSERT_TRUE(big);
  EXPECT_EQ(big->status, 413);
  // A malformed plan is a clear 400 naming the problem.
  auto bad_plan = c.Post("/api/start?name=bad.yaml", rig.bearer(), "protocol: [", "application/yaml");
  EXPECT_EQ(bad_plan->status, 400);
  EXPECT_NE(body_json(bad_plan)["error"]["message"].get<std::string>().find("bad.yaml"),
            std::string::npos);
  // A foreign Host header (DNS rebinding) is refused.
  EXPECT_EQ(c.Get("/api/status", httplib::Headers{{"Host", "evil.example:7878"}})->status, 403);
  // A malformed request line.
  {
    RawSocket raw(rig.http->port());
    raw.send("GARBAGE\r\n\r\n");
    EXPECT_NE(raw.receive_some().find("400"), std::string::npos);
  }
  // A slow client that never finishes its headers, and an event stream that is never read:
  // others are still served meanwhile, and both are dropped after the I/O timeout.
  RawSocket slow(rig.http->port());
  slow.send("GET /api/status HTTP/1.1\r\nHost: 127.0.0.1");
  RawSocket stuck(rig.http->port());
  int small = 4096;
  ::setsockopt(stuck.fd, SOL_SOCKET, SO_RCVBUF, &small, sizeof(small));
  stuck.send("GET /api/events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
  const std::uint64_t cycles0 = rig.daemon->live().cycle_json()["cycles"].get<std::uint64_t>();
  const std::int64_t t0 = rig.daemon->rig().clock().now_ns();
  for (int i = 0; i < 20; ++i) {
    auto r = c.Get("/api/status");
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 200);
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  // A third and fourth event stream: one fits beside the stuck one, the next is refused.
  RawSocket second(rig.http->port());
  second.send("GET /api/events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  if (rig.http->event_clients() >= 2) {
    auto refused = c.Get("/api/events");
    ASSERT_TRUE(refused);
    EXPECT_EQ(refused->status, 503);
  }
  // The capture went on the whole time: the control loop kept cycling, force samples kept coming.
  EXPECT_EQ(rig.daemon->status()["state"], "running");
  EXPECT_GT(rig.daemon->live().cycle_json()["cycles"].get<std::uint64_t>(), cycles0);
  EXPECT_FALSE(rig.daemon->live().forces_since(t0, 0).empty());
  EXPECT_FALSE(rig.daemon->status()["session"].contains("trip"));
}

TEST(LiveHttp, TokenFileIsOwnerOnly) {
  hc::testing::ScratchDir dir;
  Result<std::string> a = make_token(), b = make_token();
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(a->size(), 64u);
  EXPECT_EQ(a->find_first_not_of("0123456789abcdef"), std::string::npos);
  EXPECT_NE(*a, *b);
  const auto path = dir / "rigd.token";
  ASSERT_TRUE(write_token_file(path, *a).ok());
  struct stat st{};
  ASSERT_EQ(::stat(path.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  Result<std::string> text = read_file(path);
  EXPECT_EQ(*text, *a + "\n");
}

TEST(LiveHttp, ListenAddressesAndTheLoopbackRule) {
  HttpOptions o;
  o.token = "t";
  ASSERT_TRUE(parse_listen_address("127.0.0.1:7878", o).ok());
  EXPECT_EQ(o.host, "127.0.0.1");
  EXPECT_EQ(o.port, 7878);
  EXPECT_TRUE(o.validate().ok());
  ASSERT_TRUE(parse_listen_address("[::1]:9000", o).ok());
  EXPECT_EQ(o.host, "::1");
  EXPECT_TRUE(o.validate().ok());
  ASSERT_TRUE(parse_listen_address("0.0.0.0:7878", o).ok());
  EXPECT_EQ(o.validate().code(), StatusCode::kInvalidArgument);
  o.allow_remote = true;
  EXPECT_TRUE(o.validate().ok());
  for (const char* bad : {"7878", "127.0.0.1:", ":80", "127.0.0.1:http", "127.0.0.1:99999"})
    EXPECT_EQ(parse_listen_address(bad, o).code(), StatusCode::kInvalidArgument) << bad;
  EXPECT_TRUE(is_loopback_host("127.1.2.3"));
  EXPECT_FALSE(is_loopback_host("127.evil.example"));
  EXPECT_FALSE(is_loopback_host("1270.0.0.1"));
  // The rig config's http section follows the same rule, naming the key.
  const std::string base(kEmbeddedDefaultRigConfig);
  Result<RigConfig> remote = parse_rig_config(base + "http: {listen: \"0.0.0.0:7878\"}\n", "rig.yaml");
  ASSERT_FALSE(remote.ok());
  EXPECT_NE(remote.status().message().find("http.listen"), std::string::npos)
      << remote.status().message();
  EXPECT_TRUE(parse_rig_config(base + "http: {listen: \"0.0.0.0:7878\", allow_remote: true}\n",
                               "rig.yaml")
                  .ok());
  Result<RigConfig> off = parse_rig_config(base + "http: {enabled: false}\n", "rig.yaml");
  ASSERT_TRUE(off.ok());
  EXPECT_FALSE(off->http.enabled);
}

}  // namespace
}  // namespace hc::rig
