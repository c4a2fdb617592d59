// The control protocol (strict decoding, round trips, line framing) and the control socket (0600,
// request / response, events, a stale socket replaced, a live one refused, half-closed clients
// answered, idle connections closed, estop served past the connection limit).
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <algorithm>
#include <atomic>
#include <fstream>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "raw_client.h"
#include "rig_daemon/daemon/control_protocol.h"
#include "rig_daemon/daemon/control_socket.h"
#include "test_data.h"

namespace hc::rig {
namespace {

TEST(ControlProtocol, RequestRoundTrip) {
  Request r;
  r.id = 42;
  r.command = Command::kStart;
  r.plan = "protocol: hand_held\n# \"quoted\" \xc3\xa9\n";
  r.plan_name = "p.yaml";
  const std::string line = encode_request(r);
  EXPECT_EQ(line.find('\n'), std::string::npos);  // one line
  Result<Request> back = decode_request(line);
  ASSERT_TRUE(back.ok()) << back.status().to_string();
  EXPECT_EQ(back->id, 42);
  EXPECT_EQ(back->command, Command::kStart);
  EXPECT_EQ(back->plan, r.plan);
  EXPECT_EQ(back->plan_name, "p.yaml");
}

TEST(ControlProtocol, EveryCommandRoundTrips) {
  for (const char* name : {"status", "devices", "pause", "resume", "stop", "estop", "reset",
                           "subscribe", "shutdown"}) {
    std::optional<Command> c = command_from_string(name);
    ASSERT_TRUE(c) << name;
    EXPECT_EQ(to_string(*c), name);
    Request r;
    r.command = *c;
    Result<Request> back = decode_request(encode_request(r));
    ASSERT_TRUE(back.ok()) << name;
    EXPECT_EQ(back->command, *c);
  }
}

TEST(ControlProtocol, MalformedRequestsAreClearErrors) {
  const struct {
    std::string line;
    const char* expected;
  } cases[] = {
      {"", "request:1:1"},
      {"{\"cmd\": \"status\"", "request:1:"},
      {"[1, 2]", "expected a JSON object"},
      {"{}", "missing key 'cmd'"},
      {"{\"cmd\": 3}", "cmd: expected a string"},
      {"{\"cmd\": \"launch\"}", "unknown command 'launch'"},
      {"{\"cmd\": \"status\", \"verbose\": true}", "unknown key 'verbose'"},
      {"{\"cmd\": \"status\", \"id\": \"7\"}", "id: expected an integer"},
      {"{\"cmd\": \"status\", \"id\": 1.5}", "id: expected an integer"},
      {"{\"cmd\": \"start\"}", "start: missing key 'plan'"},
      {"{\"cmd\": \"start\", \"plan\": 5}", "plan: expected the plan's YAML text"},
      {"{\"cmd\": \"stop\", \"plan\": \"x\"}", "stop: takes no plan"},
      {std::string(kMaxRequestBytes + 1, ' '), "longer than"},
  };
  for (const auto& c : cases) {
    Result<Request> r = decode_request(c.line);
    ASSERT_FALSE(r.ok()) << c.line.substr(0, 80);
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(r.status().message().find(c.expected), std::string::npos) << r.status().message();
  }
}

TEST(ControlProtocol, RepliesRoundTrip) {
  Result<Reply> ok = decode_reply(encode_ok(3, Json{{"state", "idle"}}));
  ASSERT_TRUE(ok.ok());
  EXPECT_FALSE(ok->is_event);
  EXPECT_EQ(ok->id, 3);
  EXPECT_TRUE(ok->status.ok());
  EXPECT_EQ(ok->body["state"], "idle");

  Result<Reply> err = decode_reply(encode_error(4, failed_precondition("busy")));
  ASSERT_TRUE(err.ok());
  EXPECT_EQ(err->status.code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(err->status.message(), "busy");

  Result<Reply> ev = decode_reply(encode_event("progress", Json{{"done", 5}}));
  ASSERT_TRUE(ev.ok());
  EXPECT_TRUE(ev->is_event);
  EXPECT_EQ(ev->event, "progress");
  EXPECT_EQ(ev->body["done"], 5);

  EXPECT_FALSE(decode_reply("{\"ok\": true}").ok());
  EXPECT_FALSE(decode_reply("nope").ok());
}

TEST(ControlSocket, OwnerOnlyRequestResponseAndEvents) {
  hc::testing::ScratchDir dir;
  const std::filesystem::path path = dir / "sub/rigd.sock";
  std::atomic<int> calls{0};
  Result<std::unique_ptr<ControlServer>> server =
      ControlServer::start(path, [&](const Request& r, Status& error) -> Json {
        ++calls;
        if (r.command == Command::kStop) {
          error = failed_precondition("nothing is running");
          return {};
        }
        return Json{{"cmd", to_string(r.command)}, {"plan_name", r.plan_name}};
      });
  ASSERT_TRUE(server.ok()) << server.status().to_string();

  struct stat st {};
  ASSERT_EQ(::stat(path.c_str(), &st), 0);
  EXPECT_TRUE(S_ISSOCK(st.st_mode));
  EXPECT_EQ(st.st_mode & 0777, 0600u);

  Result<ControlClient> client = ControlClient::connect(path);
  ASSERT_TRUE(client.ok()) << client.status().to_string();
  Request status_req;
  status_req.command = Command::kStatus;
  Result<Json> a = client->call(status_req);
  ASSERT_TRUE(a.ok()) << a.status().to_string();
  EXPECT_EQ((*a)["cmd"], "status");

  Request stop_req;
  stop_req.command = Command::kStop;
  Result<Json> b = client->call(stop_req);
  ASSERT_FALSE(b.ok());
  EXPECT_EQ(b.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(b.status().message(), "nothing is running");

  Request sub;
  sub.command = Command::kSubscribe;
  ASSERT_TRUE(client->call(sub).ok());
  (*server)->broadcast("progress", Json{{"done", 1}});
  (*server)->broadcast("finished", Json{{"done", 2}});
  Result<Reply> e1 = client->next_event(5000);
  ASSERT_TRUE(e1.ok()) << e1.status().to_string();
  EXPECT_EQ(e1->event, "progress");
  Result<Reply> e2 = client->next_event(5000);
  ASSERT_TRUE(e2.ok());
  EXPECT_EQ(e2->event, "finished");
  EXPECT_EQ(e2->body["done"], 2);
  EXPECT_EQ(calls.load(), 3);

  // A second daemon on the same socket is refused while the first is alive.
  Result<std::unique_ptr<ControlServer>> second =
      ControlServer::start(path, [](const Request&, Status&) { return Json{}; });
  ASSERT_FALSE(second.ok());
  EXPECT_EQ(second.status().code(), StatusCode::kFailedPrecondition);

  server->reset();
  EXPECT_FALSE(std::filesystem::exists(path));
  Result<Json> after = client->call(status_req, 2000);
  EXPECT_FALSE(after.ok());
}

TEST(ControlSocket, GarbageLineGetsAnErrorAndTheConnectionSurvives) {
  hc::testing::ScratchDir dir;
  const std::filesystem::path path = dir / "rigd.sock";
  Result<std::unique_ptr<ControlServer>> server =
      ControlServer::start(path, [](const Request&, Status&) {
        return Json{{"fine", true}};
      });
  ASSERT_TRUE(server.ok());
  Result<ControlClient> client = ControlClient::connect(path);
  ASSERT_TRUE(client.ok());
  Request r;
  r.command = Command::kDevices;
  ASSERT_TRUE(client->call(r).ok());
  EXPECT_FALSE(ControlClient::connect(dir / "missing.sock").ok());
}

TEST(ControlSocket, StaleSocketFileIsReplacedButOtherFilesAreNot) {
  hc::testing::ScratchDir dir;
  const std::filesystem::path path = dir / "rigd.sock";
  {
    Result<std::unique_ptr<ControlServer>> first =
        ControlServer::start(path, [](const Request&, Status&) { return Json{}; });
    ASSERT_TRUE(first.ok());
    // Leave the socket file behind as a crashed daemon would: move it aside and back.
    std::filesystem::rename(path, dir / "kept.sock");
  }
  std::filesystem::rename(dir / "kept.sock", path);
  Result<std::unique_ptr<ControlServer>> again =
      ControlServer::start(path, [](const Request&, Status&) { return Json{}; });
  EXPECT_TRUE(again.ok()) << again.status().to_string();
  again->reset();

  const std::filesystem::path regular = dir / "file.sock";
  { std::ofstream(regular) << "x"; }
  Result<std::unique_ptr<ControlServer>> refused =
      ControlServer::start(regular, [](const Request&, Status&) { return Json{}; });
  EXPECT_FALSE(refused.ok());
  EXPECT_TRUE(std::filesystem::exists(regular));
}

TEST(ControlProtocol, FramerYieldsEveryCompleteLineAndTheRestAtEndOfFile) {
  RequestFramer f(64);
  f.append("{\"cmd\":\"status\"}\n\r\n\n{\"cmd\":\"pa");
  EXPECT_EQ(f.next(), std::optional<std::string>("{\"cmd\":\"status\"}"));
  EXPECT_EQ(f.next(), std::nullopt);  // blank lines skipped, the partial one waits
  f.append("use\"}\r\n{\"cmd\":\"estop\"}");
  EXPECT_EQ(f.next(), std::optional<std::string>("{\"cmd\":\"pause\"}\r"));
  EXPECT_EQ(f.next(), std::nullopt);
  EXPECT_FALSE(f.drained());
  // The client half-closes: its unterminated last request is still a request (before the fix
  // end-of-file dropped everything buffered, the estop included).
  f.finish();
  EXPECT_EQ(f.next(), std::optional<std::string>("{\"cmd\":\"estop\"}"));
  EXPECT_EQ(f.next(), std::nullopt);
  EXPECT_TRUE(f.drained());

  RequestFramer g(16);
  g.append("{\"cmd\":\"estop\"}\n");
  g.append(std::string(40, 'x'));
  EXPECT_EQ(g.next(), std::optional<std::string>("{\"cmd\":\"estop\"}"));  // before the long one
  EXPECT_EQ(g.next(), std::nullopt);
  EXPECT_TRUE(g.overlong());
  EXPECT_TRUE(g.drained());
}

// A server whose handler answers every command with its name and counts the calls.
struct CountingServer {
  explicit CountingServer(const std::filesystem::path& path, ControlServer::Limits limits = {}) {
    Result<std::unique_ptr<ControlServer>> s = ControlServer::start(
        path,
        [this](const Request& r, Status&) -> Json {
          std::lock_guard lock(mutex);
          commands.push_back(std::string(to_string(r.command)));
          return Json{{"cmd", to_string(r.command)}};
        },
        limits);
    EXPECT_TRUE(s.ok()) << s.status().to_string();
    if (s.ok()) server = std::move(s).value();
  }
  std::vector<std::string> seen() {
    std::lock_guard lock(mutex);
    return commands;
  }
  std::mutex mutex;
  std::vector<std::string> commands;
  std::unique_ptr<ControlServer> server;
};

std::size_t count_of(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (std::size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

TEST(ControlSocket, HalfClosedClientGetsEveryRequestExecutedAndAnswered) {
  hc::testing::ScratchDir dir;
  CountingServer srv(dir / "rigd.sock");
  ASSERT_TRUE(srv.server);
  // `echo '{"id":1,"cmd":"estop"}' | socat - UNIX-CONNECT:rigd.sock`, 20 times: every one runs and
  // is answered (before the fix: no reply and the command dropped, most of the time).
  for (int i = 0; i < 20; ++i) {
    hc::testing::RawClient c(srv.server->path());
    ASSERT_TRUE(c.connected());
    ASSERT_TRUE(c.send("{\"id\":" + std::to_string(i + 1) + ",\"cmd\":\"estop\"}\n"));
    c.shutdown_write();
    bool closed = false;
    const std::string reply = c.read_until_closed(5000, &closed);
    EXPECT_TRUE(closed);
    EXPECT_NE(reply.find("\"id\":" + std::to_string(i + 1) + ",\"ok\":true"), std::string::npos)
        << i << ": " << reply;
  }
  const std::vector<std::string> seen = srv.seen();
  EXPECT_EQ(std::count(seen.begin(), seen.end(), "estop"), 20);

  // Three requests in one write, the last one unterminated, then end-of-file: three answers.
  hc::testing::RawClient c(srv.server->path());
  ASSERT_TRUE(
      c.send("{\"id\":7,\"cmd\":\"status\"}\n{\"id\":8,\"cmd\":\"pause\"}\r\n"
             "{\"id\":9,\"cmd\":\"estop\"}"));
  c.shutdown_write();
  const std::string replies = c.read_until_closed(5000);
  EXPECT_EQ(count_of(replies, "\"ok\":true"), 3u) << replies;
  EXPECT_NE(replies.find("\"id\":9"), std::string::npos) << replies;
}

TEST(ControlSocket, IdleConnectionsAreClosedWithAReason) {
  hc::testing::ScratchDir dir;
  ControlServer::Limits limits;
  limits.idle_timeout = std::chrono::milliseconds(300);
  CountingServer srv(dir / "rigd.sock", limits);
  ASSERT_TRUE(srv.server);
  hc::testing::RawClient idle(srv.server->path());
  ASSERT_TRUE(idle.connected());
  bool closed = false;
  const std::string said = idle.read_until_closed(5000, &closed);
  EXPECT_TRUE(closed);
  EXPECT_NE(said.find("no request for 300 ms; closing this control connection"), std::string::npos)
      << said;
  // A subscriber waits for events as long as it likes.
  Result<ControlClient> watcher = ControlClient::connect(srv.server->path());
  ASSERT_TRUE(watcher.ok());
  Request sub;
  sub.command = Command::kSubscribe;
  ASSERT_TRUE(watcher->call(sub).ok());
  std::this_thread::sleep_for(std::chrono::milliseconds(600));
  srv.server->broadcast("progress", Json{{"done", 1}});
  EXPECT_TRUE(watcher->next_event(5000).ok());
}

TEST(ControlSocket, EstopGetsThroughWhenEveryConnectionIsTaken) {
  hc::testing::ScratchDir dir;
  ControlServer::Limits limits;
  limits.max_connections = 6;
  limits.reserved_connections = 2;
  CountingServer srv(dir / "rigd.sock", limits);
  ASSERT_TRUE(srv.server);
  std::vector<std::unique_ptr<hc::testing::RawClient>> idle;
  for (std::size_t i = 0; i < limits.max_connections; ++i) {
    idle.push_back(std::make_unique<hc::testing::RawClient>(srv.server->path()));
    ASSERT_TRUE(idle.back()->connected());
  }
  for (int i = 0; i < 200 && srv.server->connections() < limits.max_connections; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  ASSERT_EQ(srv.server->connections(), limits.max_connections);

  // Another status: refused, saying why (before the fix: "Connection reset by peer").
  Result<ControlClient> extra = ControlClient::connect(srv.server->path());
  ASSERT_TRUE(extra.ok());
  Request status;
  status.command = Command::kStatus;
  Result<Json> refused = extra->call(status, 5000);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), StatusCode::kUnavailable);
  EXPECT_NE(refused.status().message().find("all 6 control connections are in use; this extra "
                                            "connection serves only estop"),
            std::string::npos)
      << refused.status().message();
  // Estop is served (twice: each reserved connection takes one request).
  for (int i = 0; i < 2; ++i) {
    Result<ControlClient> e = ControlClient::connect(srv.server->path());
    ASSERT_TRUE(e.ok());
    Request estop;
    estop.command = Command::kEstop;
    Result<Json> r = e->call(estop, 5000);
    ASSERT_TRUE(r.ok()) << r.status().to_string();
    EXPECT_EQ((*r)["cmd"], "estop");
  }
  const std::vector<std::string> seen = srv.seen();
  EXPECT_EQ(std::count(seen.begin(), seen.end(), "estop"), 2);
  EXPECT_EQ(std::count(seen.begin(), seen.end(), "status"), 0);

  // Past the reserve too: a message, not a bare reset.
  std::vector<std::unique_ptr<hc::testing::RawClient>> more;
  for (std::size_t i = 0; i < limits.reserved_connections; ++i)
    more.push_back(std::make_unique<hc::testing::RawClient>(srv.server->path()));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  hc::testing::RawClient last(srv.server->path());
  ASSERT_TRUE(last.connected());
  const std::string said = last.read_until_closed(5000);
  EXPECT_NE(said.find("control connections are in use, including the ones kept for estop"),
            std::string::npos)
      << said;
}

}  // namespace
}  // namespace hc::rig
