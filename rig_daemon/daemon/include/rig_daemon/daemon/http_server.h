// rigd's live page: an HTTP server (cpp-httplib, Debian's libcpp-httplib) beside the control
// socket. Routes:
//
//   GET  /                      the page (embedded; rig_daemon/daemon/www/live.html)
//   GET  /api/status            Daemon::status(), the same document as `rigctl status --json`
//   GET  /api/devices           Daemon::devices() (`rigctl devices --json`)
//   GET  /api/events            server-sent events: one JSON snapshot per push (push_hz), see
//                               live_snapshot() below
//   GET  /api/frames/CAM.png    the latest thumbnail of a camera (grey, ≤ 192 px wide)
//   GET  /api/sessions          sessions on disk (newest first) with their summaries
//   GET  /api/auth              200 with a valid token, 403 without (the page's read-only check)
//   POST /api/start             body: the plan's YAML; ?name=PLAN.yaml names it in messages
//   POST /api/{pause,resume,stop,estop,reset}   (reset clears the safety stop an estop or a trip
//                               leaves, as `rigctl reset`)
//
// Reading is open to whoever can reach the address; every POST needs the header
// `Authorization: Bearer TOKEN` with the token rigd writes to an owner-only file (403 and nothing
// changed otherwise). Commands go through Daemon::handle, the path the control socket's requests
// take. The server binds to loopback unless Options::allow_remote; on loopback it also refuses
// requests whose Host header names another host (DNS rebinding).
//
// One publisher thread builds each snapshot once for every connected page; the session thread
// only feeds the LiveFeed (live_feed.h), so pages and slow or stuck clients cannot slow the
// control loop: a client that does not read is dropped after `io_timeout_ms`, requests larger
// than `max_request_bytes` get 413, more than `max_event_clients` event streams get 503.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>

#include "common/json.h"
#include "common/status.h"

namespace hc::rig {

class Daemon;

struct HttpOptions {
  std::string host = "127.0.0.1";
  int port = 7878;  // 0: any free port (tests)
  bool allow_remote = false;
  std::string token;  // required; compared in constant time
  double push_hz = 20.0;
  std::size_t max_event_clients = 16;
  std::size_t max_request_bytes = std::size_t{1} << 20;
  int io_timeout_ms = 3000;
  std::size_t max_sessions_listed = 50;

  // kInvalidArgument: a non-loopback host without allow_remote, an empty token, push_hz outside
  // 1..100, no event clients.
  Status validate() const;
};

// "ADDR:PORT" (IPv4, "localhost" or "[IPv6]"), e.g. from `rigd --http 127.0.0.1:7878`.
Status parse_listen_address(std::string_view text, HttpOptions& options);
// True for 127.0.0.0/8, ::1 and "localhost".
bool is_loopback_host(std::string_view host);

// 32 random bytes from the kernel (getrandom), hex-encoded.
Result<std::string> make_token();
// Writes the token to `path` created with mode 0600 (owner only) from the start, atomically.
Status write_token_file(const std::filesystem::path& path, const std::string& token);

class HttpServer {
 public:
  // Binds and starts serving (threads of its own). kUnavailable when the address is taken.
  static Result<std::unique_ptr<HttpServer>> start(Daemon& daemon, HttpOptions options);
  ~HttpServer();  // ends every event stream and stops serving
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;

  int port() const;
  // http://HOST:PORT/
  std::string url() const;
  std::size_t event_clients() const;
  // Snapshots published so far.
  std::uint64_t published() const;

  struct Impl;

 private:
  explicit HttpServer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// One event-stream snapshot: {"seq", "t_ns" (daemon clock), "state", "session" (progress),
// "time_left_s", "force": [[t_ns, |F|, Fz]...] since the previous snapshot, "arm", "safety",
// "thumbnails": {camera: sequence}, "cycle"; with `with_devices` also "devices" and
// "last_session"}.
Json live_snapshot(Daemon& daemon, std::int64_t& last_force_ns, bool with_devices);

}  // namespace hc::rig
