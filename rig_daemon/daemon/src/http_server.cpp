#include "rig_daemon/daemon/http_server.h"

#include <fcntl.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <map>
#include <mutex>
#include <thread>

#include "rig_daemon/daemon/daemon.h"
#include "rig_daemon/daemon/live_feed.h"
#include "rig_daemon/daemon/live_page.h"
#include "rig_daemon/recording/mcap_tools.h"
// Last: httplib.h includes <resolv.h>, whose `_res` macro breaks Eigen's headers included after it.
#include <httplib.h>

namespace hc::rig {
namespace {

// Thumbnails are asked for at this rate (they cost the control loop a point-sampled copy).
constexpr double kThumbnailHz = 2.0;
// Device tables and the last session's summary change slowly: sent with every this many snapshots
// (2 Hz at the default 20 Hz), which halves what a snapshot costs to build.
constexpr int kDevicesEvery = 10;
// Force points per snapshot at most (the page draws a few thousand points at 20 Hz).
constexpr std::size_t kMaxForcePointsPerPush = 200;
// Threads for requests besides the event streams (page, API, thumbnails).
constexpr std::size_t kRequestThreads = 6;

bool constant_time_equal(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  unsigned char d = 0;
  for (std::size_t i = 0; i < a.size(); ++i)
    d |= static_cast<unsigned char>(a[i] ^ b[i]);
  return d == 0;
}

void send_json(httplib::Response& res, int status, const Json& body) {
  res.status = status;
  res.set_header("Cache-Control", "no-store");
  res.set_content(body.dump(), "application/json");
}

void send_error(httplib::Response& res, int status, std::string_view code, std::string message) {
  send_json(res, status, Json{{"ok", false}, {"error", {{"code", code}, {"message", message}}}});
}

int http_status_of(const Status& s) {
  switch (s.code()) {
    case StatusCode::kInvalidArgument:
      return 400;
    case StatusCode::kFailedPrecondition:
      return 409;
    case StatusCode::kNotFound:
      return 404;
    default:
      return 500;
  }
}

Json arm_json(const devices::ArmState& a) {
  return Json{{"x_m", a.pose.x_m},
              {"y_m", a.pose.y_m},
              {"z_m", a.pose.z_m},
              {"yaw_rad", a.pose.yaw_rad},
              {"target", {{"x_m", a.target.x_m}, {"y_m", a.target.y_m}, {"z_m", a.target.z_m}}},
              {"motion", devices::to_string(a.motion)},
              {"homed", a.homed},
              {"fault", a.fault},
              {"host_ns", a.host_ns}};
}

}  // namespace

// ---- options, token ----

bool is_loopback_host(std::string_view host) {
  if (host == "localhost" || host == "::1" || host == "[::1]") return true;
  return host.substr(0, 4) == "127." && host.find_first_not_of("0123456789.") == std::string_view::npos;
}

Status HttpOptions::validate() const {
  if (!allow_remote && !is_loopback_host(host))
    return invalid_argument("http: " + host +
                            " is not a loopback address; the page is served to other machines only "
                            "when the rig config says http: {allow_remote: true}");
  if (token.empty()) return invalid_argument("http: no token");
  if (!(push_hz >= 1.0 && push_hz <= 100.0)) return invalid_argument("http: push_hz must be 1..100");
  if (max_event_clients == 0) return invalid_argument("http: max_event_clients must be > 0");
  if (port < 0 || port > 65535) return invalid_argument("http: port must be 0..65535");
  return {};
}

Status parse_listen_address(std::string_view text, HttpOptions& options) {
  const std::size_t colon = text.rfind(':');
  if (colon == std::string_view::npos || colon == 0 || colon + 1 == text.size())
    return invalid_argument("'" + std::string(text) + "': expected ADDR:PORT, e.g. 127.0.0.1:7878");
  std::string host(text.substr(0, colon));
  if (host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  const std::string_view port_text = text.substr(colon + 1);
  int port = 0;
  for (char c : port_text) {
    if (c < '0' || c > '9' || port > 65535)
      return invalid_argument("'" + std::string(text) + "': the port must be a number 0..65535");
    port = port * 10 + (c - '0');
  }
  if (port > 65535)
    return invalid_argument("'" + std::string(text) + "': the port must be a number 0..65535");
  options.host = host;
  options.port = port;
  return {};
}

Result<std::string> make_token() {
  unsigned char bytes[32];
  std::size_t got = 0;
  while (got < sizeof(bytes)) {
    const ssize_t n = ::getrandom(bytes + got, sizeof(bytes) - got, 0);
    if (n < 0) {
      if (errno == EINTR) continue;
      return io_error(std::string("getrandom: ") + std::strerror(errno));
    }
    got += static_cast<std::size_t>(n);
  }
  static constexpr char kHex[] = "0123456789abcdef";
  std::string token;
  for (unsigned char b : bytes) {
    token += kHex[b >> 4];
    token += kHex[b & 15];
  }
  return token;
}

Status write_token_file(const std::filesystem::path& path, const std::string& token) {
  const std::filesystem::path tmp = path.string() + ".tmp-" + std::to_string(::getpid());
  // Created owner-only: no moment in which another user could read it.
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC | O_NOFOLLOW, 0600);
  if (fd < 0) return io_error("cannot create " + tmp.string() + ": " + std::strerror(errno));
  const std::string text = token + "\n";
  bool ok = ::fchmod(fd, 0600) == 0 &&
            ::write(fd, text.data(), text.size()) == static_cast<ssize_t>(text.size()) &&
            ::fsync(fd) == 0;
  ok = (::close(fd) == 0) && ok;
  if (!ok || std::rename(tmp.c_str(), path.c_str()) != 0) {
    const Status s = io_error("cannot write " + path.string() + ": " + std::strerror(errno));
    std::remove(tmp.c_str());
    return s;
  }
  return {};
}

// ---- snapshots ----

Json live_snapshot(Daemon& daemon, std::int64_t& last_force_ns, bool with_devices) {
  LiveFeed& live = daemon.live();
  const std::int64_t now = daemon.rig().clock().now_ns();
  Json status = daemon.status();
  Json j{{"t_ns", now}, {"state", status["state"]}};
  if (status.contains("session")) {
    const Json& s = status["session"];
    j["session"] = s;
    const auto done = s.value("done", std::int64_t{0});
    const auto total = s.value("total", std::int64_t{0});
    const double elapsed = s.value("elapsed_s", 0.0);
    const bool active = status["state"] == "running" || status["state"] == "paused";
    if (active && done > 0 && total >= done)
      j["time_left_s"] = elapsed * static_cast<double>(total - done) / static_cast<double>(done);
  }
  if (with_devices && status.contains("last_session")) j["last_session"] = status["last_session"];
  Json force = Json::array();
  for (const LiveFeed::ForcePoint& p : live.forces_since(last_force_ns, kMaxForcePointsPerPush)) {
    force.push_back(Json::array({p.host_ns, p.force_n, p.fz_n}));
    last_force_ns = p.host_ns;
  }
  j["force"] = std::move(force);
  if (std::optional<devices::ArmState> a = live.arm()) j["arm"] = arm_json(*a);
  const RigConfig& cfg = daemon.rig().config();
  Json safety{{"max_force_n", cfg.max_force_n},
              {"workspace", cfg.workspace.to_json()},
              {"stall_timeout_s", cfg.stall_timeout_s},
              {"state", "ok"}};
  // A trip of the running session, else the latched safety stop (a trip or an estop leaves one
  // until reset), else ok.
  if (status.contains("session") && status["session"].contains("trip")) {
    safety["trip"] = status["session"]["trip"];
    safety["state"] = status["session"]["trip"].value("kind", std::string("tripped"));
  }
  if (status.contains("safety_stop") && status["safety_stop"].is_object()) {
    safety["stop"] = status["safety_stop"];
    if (safety["state"] == "ok") safety["state"] = status["safety_stop"].value("kind", std::string("stopped"));
  }
  j["safety"] = std::move(safety);
  j["thumbnails"] = live.thumbnail_sequences();
  j["cycle"] = live.cycle_json();
  if (with_devices) j["devices"] = daemon.devices();
  return j;
}

// ---- the server ----

struct HttpServer::Impl {
  Daemon& daemon;
  HttpOptions options;
  httplib::Server server;
  int port = 0;
  std::thread listener;
  std::thread publisher;

  std::mutex mutex;  // guards snapshot, seq, stopping
  std::condition_variable cv;
  std::string snapshot;  // the latest event, ready to send ("data: ...\n\n")
  std::uint64_t seq = 0;
  bool stopping = false;
  std::atomic<std::size_t> event_clients{0};

  std::mutex sessions_mutex;
  struct Cached {
    std::uintmax_t size = 0;
    std::filesystem::file_time_type mtime;
    Json summary;
  };
  std::map<std::string, Cached> sessions_cache;

  Impl(Daemon& d, HttpOptions o) : daemon(d), options(std::move(o)) {}

  bool authorised(const httplib::Request& req) const {
    const std::string h = req.get_header_value("Authorization");
    constexpr std::string_view kBearer = "Bearer ";
    return h.size() > kBearer.size() && h.compare(0, kBearer.size(), kBearer) == 0 &&
           constant_time_equal(std::string_view(h).substr(kBearer.size()), options.token);
  }

  bool host_allowed(const httplib::Request& req) const {
    if (options.allow_remote) return true;
    std::string host = req.get_header_value("Host");
    if (host.empty()) return true;  // HTTP/1.0 clients; the socket is loopback anyway
    if (host.front() == '[')
      host = host.substr(0, host.find(']') + 1);  // "[::1]:7878" -> "[::1]"
    else
      host = host.substr(0, host.find(':'));
    return is_loopback_host(host);
  }

  void publish_loop();
  void serve_events(const httplib::Request& req, httplib::Response& res);
  void serve_sessions(httplib::Response& res);
  void serve_command(const httplib::Request& req, httplib::Response& res, Command command);
  void add_routes();
};

void HttpServer::Impl::publish_loop() {
  using Clock = std::chrono::steady_clock;
  const auto period = std::chrono::duration<double>(1.0 / options.push_hz);
  const auto thumb_period = std::chrono::duration<double>(1.0 / kThumbnailHz);
  auto next = Clock::now();
  auto next_thumbs = next;
  std::int64_t last_force_ns = daemon.rig().clock().now_ns() - 10'000'000'000;
  std::uint64_t n = 0;
  while (true) {
    {
      std::unique_lock lock(mutex);
      if (cv.wait_until(lock, next, [&] { return stopping; })) return;
    }
    next += std::chrono::duration_cast<Clock::duration>(period);
    if (next < Clock::now()) next = Clock::now();  // fell behind: do not burst
    if (event_clients.load() == 0) continue;       // nobody watches: build nothing
    if (Clock::now() >= next_thumbs) {
      daemon.live().request_thumbnails();
      next_thumbs = Clock::now() + std::chrono::duration_cast<Clock::duration>(thumb_period);
    }
    Json j = live_snapshot(daemon, last_force_ns, n % kDevicesEvery == 0);
    std::lock_guard lock(mutex);
    j["seq"] = ++seq;
    snapshot = "data: " + j.dump() + "\n\n";
    ++n;
    cv.notify_all();
  }
}

void HttpServer::Impl::serve_events(const httplib::Request&, httplib::Response& res) {
  if (event_clients.fetch_add(1) >= options.max_event_clients) {
    event_clients.fetch_sub(1);
    send_error(res, 503, "unavailable",
               "too many event streams (" + std::to_string(options.max_event_clients) + ")");
    return;
  }
  res.set_header("Cache-Control", "no-store");
  res.set_header("X-Accel-Buffering", "no");
  auto sent = std::make_shared<std::uint64_t>(0);
  res.set_chunked_content_provider(
      "text/event-stream",
      [this, sent](std::size_t, httplib::DataSink& sink) {
        std::string data;
        {
          std::unique_lock lock(mutex);
          // A comment line every second keeps idle streams alive and notices gone clients.
          const bool fresh = cv.wait_for(lock, std::chrono::seconds(1),
                                         [&] { return stopping || seq > *sent; });
          if (stopping) return false;
          if (fresh) {
            data = snapshot;
            *sent = seq;
          } else {
            data = ": keep-alive\n\n";
          }
        }
        return sink.write(data.data(), data.size());
      },
      [this](bool) { event_clients.fetch_sub(1); });
}

void HttpServer::Impl::serve_sessions(httplib::Response& res) {
  const Json status = daemon.status();
  const std::filesystem::path dir = status.value("sessions_dir", std::string());
  std::string recording;
  if (status.contains("session") && (status["state"] == "running" || status["state"] == "paused" ||
                                     status["state"] == "starting"))
    recording = status["session"].value("session", std::string());
  std::vector<std::pair<std::filesystem::file_time_type, std::filesystem::path>> files;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(dir, ec)) {
    if (!e.is_regular_file(ec) || e.path().extension() != ".mcap") continue;
    files.emplace_back(e.last_write_time(ec), e.path());
  }
  std::sort(files.begin(), files.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  if (files.size() > options.max_sessions_listed) files.resize(options.max_sessions_listed);
  Json list = Json::array();
  std::lock_guard lock(sessions_mutex);
  for (const auto& [mtime, path] : files) {
    const std::uintmax_t size = std::filesystem::file_size(path, ec);
    Json entry{{"name", path.filename().string()}, {"path", path.string()}, {"bytes", size}};
    if (!recording.empty() && std::filesystem::equivalent(path, recording, ec)) {
      entry["state"] = "recording";
      list.push_back(std::move(entry));
      continue;
    }
    Cached& c = sessions_cache[path.string()];
    if (c.summary.is_null() || c.size != size || c.mtime != mtime) {
      Result<recording::SessionInfo> info = recording::session_info(path);
      c.size = size;
      c.mtime = mtime;
      if (info.ok())
        c.summary = Json{{"state", info->session_state.empty() ? "unknown" : info->session_state},
                         {"reason", info->session_reason},
                         {"duration_s", info->duration_s},
                         {"messages", info->message_count},
                         {"channels", info->channels.size()}};
      else
        c.summary = Json{{"state", "unreadable"}, {"reason", info.status().message()}};
    }
    entry.update(c.summary);
    list.push_back(std::move(entry));
  }
  send_json(res, 200, Json{{"sessions_dir", dir.string()}, {"sessions", list}});
}

void HttpServer::Impl::serve_command(const httplib::Request& req, httplib::Response& res,
                                     Command command) {
  if (!authorised(req)) {
    send_error(res, 403, "permission_denied",
               "control needs 'Authorization: Bearer TOKEN' with the token in rigd.token (next to "
               "the control socket)");
    return;
  }
  Request r;
  r.command = command;
  if (command == Command::kStart) {
    r.plan = req.body;
    r.plan_name = req.has_param("name") ? req.get_param_value("name") : "plan from the page";
  }
  Status error;
  // The control socket's path: the same handler answers both.
  Json result = daemon.handle(r, error);
  if (!error.ok()) {
    send_error(res, http_status_of(error), status_code_name(error.code()), error.message());
    return;
  }
  send_json(res, 200, Json{{"ok", true}, {"result", result}});
}

void HttpServer::Impl::add_routes() {
  server.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
    if (host_allowed(req)) return httplib::Server::HandlerResponse::Unhandled;
    send_error(res, 403, "permission_denied", "Host header is not this loopback server");
    return httplib::Server::HandlerResponse::Handled;
  });
  server.Get("/", [](const httplib::Request&, httplib::Response& res) {
    res.set_header("Cache-Control", "no-store");
    res.set_header("Content-Security-Policy",
                   "default-src 'self'; img-src 'self' data:; style-src 'unsafe-inline'; "
                   "script-src 'unsafe-inline'");
    res.set_content(std::string(live_page_html()), "text/html; charset=utf-8");
  });
  server.Get("/api/status", [this](const httplib::Request&, httplib::Response& res) {
    send_json(res, 200, daemon.status());
  });
  server.Get("/api/devices", [this](const httplib::Request&, httplib::Response& res) {
    send_json(res, 200, Json{{"devices", daemon.devices()}});
  });
  server.Get("/api/auth", [this](const httplib::Request& req, httplib::Response& res) {
    if (authorised(req))
      send_json(res, 200, Json{{"ok", true}});
    else
      send_error(res, 403, "permission_denied", "no valid token");
  });
  server.Get("/api/events", [this](const httplib::Request& req, httplib::Response& res) {
    serve_events(req, res);
  });
  server.Get("/api/sessions", [this](const httplib::Request&, httplib::Response& res) {
    serve_sessions(res);
  });
  server.Get(R"(/api/frames/([A-Za-z0-9_.-]+)\.png)",
             [this](const httplib::Request& req, httplib::Response& res) {
               const std::optional<LiveFeed::Thumbnail> t = daemon.live().thumbnail(req.matches[1]);
               if (!t) {
                 send_error(res, 404, "not_found", "no frame from '" + std::string(req.matches[1]) + "' yet");
                 return;
               }
               Result<std::string> png = recording::encode_png(
                   t->width, t->height, 1, 8, false, t->width,
                   recording::ByteSpan(t->gray.data(), t->gray.size()));
               if (!png.ok()) {
                 send_error(res, 500, "internal", png.status().message());
                 return;
               }
               res.set_header("Cache-Control", "no-store");
               res.set_content(*png, "image/png");
             });
  const std::pair<const char*, Command> commands[] = {{"/api/start", Command::kStart},
                                                      {"/api/pause", Command::kPause},
                                                      {"/api/resume", Command::kResume},
                                                      {"/api/stop", Command::kStop},
                                                      {"/api/estop", Command::kEstop},
                                                      {"/api/reset", Command::kReset}};
  for (const auto& [path, command] : commands) {
    const Command c = command;
    server.Post(path, [this, c](const httplib::Request& req, httplib::Response& res) {
      serve_command(req, res, c);
    });
  }
  server.set_error_handler([](const httplib::Request& req, httplib::Response& res) {
    if (!res.body.empty()) return;  // a handler already explained
    const std::string what = res.status == 404   ? "no such route: " + req.method + " " + req.path
                             : res.status == 413 ? "request larger than the server accepts"
                                                 : "request refused";
    send_error(res, res.status, res.status == 404 ? "not_found" : "invalid_argument", what);
  });
  server.set_exception_handler(
      [](const httplib::Request&, httplib::Response& res, std::exception_ptr) {
        send_error(res, 500, "internal", "the request failed inside rigd");
      });
}

HttpServer::HttpServer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

Result<std::unique_ptr<HttpServer>> HttpServer::start(Daemon& daemon, HttpOptions options) {
  HC_RETURN_IF_ERROR(options.validate());
  auto impl = std::make_unique<Impl>(daemon, std::move(options));
  Impl& m = *impl;
  const std::size_t threads = m.options.max_event_clients + kRequestThreads;
  m.server.new_task_queue = [threads] { return new httplib::ThreadPool(threads); };
  m.server.set_payload_max_length(m.options.max_request_bytes);
  const auto sec = m.options.io_timeout_ms / 1000, usec = (m.options.io_timeout_ms % 1000) * 1000;
  m.server.set_read_timeout(sec, usec);
  m.server.set_write_timeout(sec, usec);
  m.server.set_keep_alive_timeout(2);
  m.server.set_keep_alive_max_count(100);
  m.add_routes();
  if (m.options.port == 0) {
    m.port = m.server.bind_to_any_port(m.options.host);
    if (m.port < 0) m.port = 0;
  } else if (m.server.bind_to_port(m.options.host, m.options.port)) {
    m.port = m.options.port;
  }
  if (m.port <= 0)
    return Status(StatusCode::kUnavailable,
                  "http: cannot listen on " + m.options.host + ":" +
                      std::to_string(m.options.port) + " (address in use or not local?)");
  m.listener = std::thread([&m] { m.server.listen_after_bind(); });
  m.publisher = std::thread([&m] { m.publish_loop(); });
  return std::unique_ptr<HttpServer>(new HttpServer(std::move(impl)));
}

HttpServer::~HttpServer() {
  {
    std::lock_guard lock(impl_->mutex);
    impl_->stopping = true;
  }
  impl_->cv.notify_all();
  impl_->server.stop();
  if (impl_->listener.joinable()) impl_->listener.join();
  if (impl_->publisher.joinable()) impl_->publisher.join();
}

int HttpServer::port() const { return impl_->port; }

std::string HttpServer::url() const {
  const std::string& h = impl_->options.host;
  const bool v6 = h.find(':') != std::string::npos;
  return "http://" + (v6 ? "[" + h + "]" : h) + ":" + std::to_string(impl_->port) + "/";
}

std::size_t HttpServer::event_clients() const { return impl_->event_clients.load(); }

std::uint64_t HttpServer::published() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->seq;
}

}  // namespace hc::rig
