// The control protocol (strict decoding, round trips) and the control socket (0600, request /
// response, events, a stale socket replaced, a live one refused).
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <atomic>
#include <fstream>
#include <string>

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
  for (const char* name :
       {"status", "devices", "pause", "resume", "stop", "estop", "subscribe", "shutdown"}) {
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

}  // namespace
}  // namespace hc::rig
