#include "rig_daemon/daemon/control_socket.h"

#include <fcntl.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <string_view>

namespace hc::rig {
namespace {

Status errno_status(std::string_view what) {
  return io_error(std::string(what) + ": " + std::strerror(errno));
}

Result<sockaddr_un> socket_address(const std::filesystem::path& path) {
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  const std::string s = path.string();
  if (s.empty() || s.size() >= sizeof(addr.sun_path))
    return invalid_argument("control socket path '" + s + "': must be 1-" +
                            std::to_string(sizeof(addr.sun_path) - 1) + " bytes");
  std::memcpy(addr.sun_path, s.data(), s.size());
  return addr;
}

bool set_nonblocking(int fd) {
  const int flags = fcntl(fd, F_GETFL, 0);
  return flags >= 0 && fcntl(fd, F_SETFL, flags | O_NONBLOCK) == 0;
}

// send() that never raises SIGPIPE when the peer is gone.
ssize_t send_some(int fd, const std::string& buf) {
  return ::send(fd, buf.data(), buf.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
}

}  // namespace

Result<std::unique_ptr<ControlServer>> ControlServer::start(const std::filesystem::path& path,
                                                            Handler handler, Limits limits) {
  HC_ASSIGN_OR_RETURN(sockaddr_un addr, socket_address(path));
  std::error_code ec;
  if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path(), ec);
  if (ec) return io_error("cannot create " + path.parent_path().string() + ": " + ec.message());

  // A socket file that still accepts connections belongs to a live daemon; one that refuses is a
  // leftover of a crash and is replaced.
  if (std::filesystem::exists(std::filesystem::symlink_status(path, ec))) {
    const int probe = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    const bool live =
        probe >= 0 && ::connect(probe, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) == 0;
    if (probe >= 0) ::close(probe);
    if (live) return failed_precondition("another rigd is already listening on " + path.string());
    std::filesystem::file_status st = std::filesystem::symlink_status(path, ec);
    if (st.type() != std::filesystem::file_type::socket)
      return failed_precondition(path.string() + " exists and is not a socket; not replacing it");
    std::filesystem::remove(path, ec);
  }

  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return errno_status("socket");
  // The umask makes the socket owner-only from the moment it exists (no window in which another
  // user could connect before the chmod below).
  const mode_t old_mask = ::umask(0177);
  const int bound = ::bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr));
  ::umask(old_mask);
  if (bound != 0) {
    Status s = errno_status("bind " + path.string());
    ::close(fd);
    return s;
  }
  if (::chmod(path.c_str(), 0600) != 0 || ::listen(fd, 16) != 0 || !set_nonblocking(fd)) {
    Status s = errno_status("listen on " + path.string());
    ::close(fd);
    std::filesystem::remove(path, ec);
    return s;
  }
  std::unique_ptr<ControlServer> server(new ControlServer(path, fd, std::move(handler), limits));
  if (::pipe2(server->wake_pipe_, O_CLOEXEC | O_NONBLOCK) != 0) return errno_status("pipe");
  server->thread_ = std::thread([s = server.get()] { s->run(); });
  return server;
}

ControlServer::ControlServer(std::filesystem::path path, int listen_fd, Handler handler,
                             Limits limits)
    : path_(std::move(path)),
      listen_fd_(listen_fd),
      handler_(std::move(handler)),
      limits_(limits) {}

ControlServer::~ControlServer() {
  stop_ = true;
  wake();
  if (thread_.joinable()) thread_.join();
  for (auto& c : connections_) ::close(c->fd);
  if (listen_fd_ >= 0) ::close(listen_fd_);
  for (int fd : wake_pipe_)
    if (fd >= 0) ::close(fd);
  std::error_code ec;
  std::filesystem::remove(path_, ec);
}

void ControlServer::wake() {
  if (wake_pipe_[1] >= 0) {
    const char b = 1;
    [[maybe_unused]] ssize_t n = ::write(wake_pipe_[1], &b, 1);
  }
}

void ControlServer::broadcast(std::string_view event, const Json& fields) {
  const std::string line = encode_event(event, fields) + "\n";
  {
    std::lock_guard lock(mutex_);
    for (auto& c : connections_) {
      if (!c->subscribed || c->closing) continue;
      if (c->out.size() + line.size() > kMaxPendingBytes) {
        c->closing = true;  // a client this far behind is gone or stuck
        c->out.clear();
        continue;
      }
      c->out += line;
    }
  }
  wake();
}

void ControlServer::run() {
  std::vector<pollfd> fds;
  std::vector<Connection*> polled;
  while (!stop_) {
    fds.clear();
    polled.clear();
    fds.push_back({listen_fd_, POLLIN, 0});
    fds.push_back({wake_pipe_[0], POLLIN, 0});
    {
      std::lock_guard lock(mutex_);
      for (auto& c : connections_) {
        short events = c->read_closed ? 0 : POLLIN;
        if (!c->out.empty()) events |= POLLOUT;
        fds.push_back({c->fd, events, 0});
        polled.push_back(c.get());
      }
    }
    // The timeout bounds how late idle connections are expired.
    if (::poll(fds.data(), fds.size(), 100) < 0 && errno != EINTR) break;
    if (fds[1].revents & POLLIN) {
      char buf[64];
      while (::read(wake_pipe_[0], buf, sizeof(buf)) > 0) {
      }
    }
    TimePoint now = std::chrono::steady_clock::now();
    if (fds[0].revents & POLLIN) accept_all(now);
    for (std::size_t i = 0; i < polled.size(); ++i) {
      Connection& c = *polled[i];
      if ((fds[i + 2].revents & (POLLIN | POLLHUP | POLLERR)) && !c.read_closed) {
        read_input(c);
        if (!c.linger_until) answer_requests(c);
      }
      now = std::chrono::steady_clock::now();
      expire(c, now);
      flush(c, now);
    }
    std::lock_guard lock(mutex_);
    std::erase_if(connections_, [&](const std::unique_ptr<Connection>& c) {
      const bool done = c->linger_until && (c->read_closed || now >= *c->linger_until);
      if (done) ::close(c->fd);
      return done;
    });
    connection_count_ = connections_.size();
  }
}

void ControlServer::accept_all(TimePoint now) {
  while (true) {
    const int cfd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
    if (cfd < 0) return;
    std::lock_guard lock(mutex_);
    // Connections being closed (answered, lingering a moment for the client to read) do not hold
    // a slot; the hard bound on all of them keeps a flood from growing the set without limit.
    const auto open = static_cast<std::size_t>(std::count_if(
        connections_.begin(), connections_.end(), [](const auto& c) { return !c->closing; }));
    if (connections_.size() >= limits_.max_connections + 2 * limits_.reserved_connections + 16) {
      ::close(cfd);
      continue;
    }
    auto c = std::make_unique<Connection>();
    c->fd = cfd;
    c->last_request = now;
    if (open >= limits_.max_connections + limits_.reserved_connections) {
      c->out =
          encode_error(0, Status(StatusCode::kUnavailable,
                                 "rigd: all " + std::to_string(open) +
                                     " control connections are in use, including the ones "
                                     "kept for estop; idle connections close after " +
                                     std::to_string(limits_.idle_timeout.count() / 1000) + " s")) +
          "\n";
      c->closing = true;
    } else if (open >= limits_.max_connections) {
      c->reserved = true;
    }
    connections_.push_back(std::move(c));
  }
}

void ControlServer::read_input(Connection& c) {
  char buf[65536];
  while (true) {
    const ssize_t n = ::recv(c.fd, buf, sizeof(buf), MSG_DONTWAIT);
    if (n > 0) {
      if (!c.linger_until) c.framer.append(std::string_view(buf, static_cast<std::size_t>(n)));
      continue;
    }
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return;
    if (n < 0 && errno == EINTR) continue;
    // End-of-file (the client half-closed or closed) or a broken connection: no more input, but
    // the complete lines already buffered are still executed (an estop must not be lost).
    c.framer.finish();
    c.read_closed = true;
    return;
  }
}

void ControlServer::answer_requests(Connection& c) {
  while (!c.closing) {
    std::optional<std::string> line = c.framer.next();
    if (!line) break;
    c.last_request = std::chrono::steady_clock::now();
    std::string reply;
    Result<Request> req = decode_request(*line);
    if (!req.ok()) {
      reply = encode_error(0, req.status());
    } else if (c.reserved && req->command != Command::kEstop) {
      reply = encode_error(
          req->id,
          Status(StatusCode::kUnavailable,
                 "rigd: all " + std::to_string(limits_.max_connections) +
                     " control connections are in use; this extra connection serves only estop "
                     "(connections that send nothing for " +
                     std::to_string(limits_.idle_timeout.count() / 1000) + " s are closed)"));
    } else {
      Status error;
      Json result = handler_(*req, error);
      reply = error.ok() ? encode_ok(req->id, result) : encode_error(req->id, error);
      if (error.ok() && req->command == Command::kSubscribe) {
        std::lock_guard lock(mutex_);
        c.subscribed = true;
      }
    }
    std::lock_guard lock(mutex_);
    c.out += reply + "\n";
    if (c.reserved) c.closing = true;  // one request per reserved connection
  }
  std::lock_guard lock(mutex_);
  if (c.framer.overlong()) {
    c.out += encode_error(0, invalid_argument("control request: longer than " +
                                              std::to_string(kMaxRequestBytes) + " bytes")) +
             "\n";
    c.closing = true;
  }
  if (c.framer.drained()) c.closing = true;  // end-of-file and every line answered
}

void ControlServer::expire(Connection& c, TimePoint now) {
  if (c.closing || c.subscribed) return;
  const auto limit = c.reserved ? limits_.reserved_deadline : limits_.idle_timeout;
  if (now - c.last_request < limit) return;
  std::lock_guard lock(mutex_);
  c.out +=
      encode_error(
          0, Status(StatusCode::kDeadlineExceeded,
                    "rigd: no request for " +
                        std::to_string(
                            std::chrono::duration_cast<std::chrono::milliseconds>(limit).count()) +
                        " ms; closing this control connection")) +
      "\n";
  c.closing = true;
}

void ControlServer::flush(Connection& c, TimePoint now) {
  std::lock_guard lock(mutex_);
  while (!c.out.empty()) {
    const ssize_t n = send_some(c.fd, c.out);
    if (n > 0) {
      c.out.erase(0, static_cast<std::size_t>(n));
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK) {
      c.out.clear();  // the peer is gone
      c.closing = true;
    }
    break;
  }
  if (c.closing && c.out.empty() && !c.linger_until) {
    // Shut our side and read (discarding) until the client closes: closing a Unix socket with
    // unread input would reset the connection and could lose the reply just sent.
    ::shutdown(c.fd, SHUT_WR);
    c.linger_until = now + std::chrono::milliseconds(500);
  }
}

// ---- client ----

Result<ControlClient> ControlClient::connect(const std::filesystem::path& path) {
  HC_ASSIGN_OR_RETURN(sockaddr_un addr, socket_address(path));
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return errno_status("socket");
  if (::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) != 0) {
    const int err = errno;
    ::close(fd);
    return Status(StatusCode::kUnavailable, "cannot connect to rigd at " + path.string() + ": " +
                                                std::strerror(err) + " (is rigd running?)");
  }
  return ControlClient(fd);
}

ControlClient::ControlClient(ControlClient&& o) noexcept
    : fd_(o.fd_), next_id_(o.next_id_), in_(std::move(o.in_)) {
  o.fd_ = -1;
}

ControlClient& ControlClient::operator=(ControlClient&& o) noexcept {
  if (this != &o) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = o.fd_;
    next_id_ = o.next_id_;
    in_ = std::move(o.in_);
    o.fd_ = -1;
  }
  return *this;
}

ControlClient::~ControlClient() {
  if (fd_ >= 0) ::close(fd_);
}

Result<std::string> ControlClient::read_line(int timeout_ms) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  while (true) {
    if (std::size_t pos = in_.find('\n'); pos != std::string::npos) {
      std::string line = in_.substr(0, pos);
      in_.erase(0, pos + 1);
      return line;
    }
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
                          deadline - std::chrono::steady_clock::now())
                          .count();
    if (left <= 0) return Status(StatusCode::kDeadlineExceeded, "no answer from rigd in time");
    pollfd p{fd_, POLLIN, 0};
    const int r = ::poll(&p, 1, static_cast<int>(left));
    if (r < 0 && errno != EINTR) return errno_status("poll");
    if (r <= 0) continue;
    char buf[65536];
    const ssize_t n = ::recv(fd_, buf, sizeof(buf), 0);
    if (n == 0) return Status(StatusCode::kUnavailable, "rigd closed the connection");
    if (n < 0) {
      if (errno == EINTR || errno == EAGAIN) continue;
      return errno_status("recv");
    }
    in_.append(buf, static_cast<std::size_t>(n));
    if (in_.size() > (std::size_t{64} << 20))
      return invalid_argument("rigd sent a line longer than 64 MiB");
  }
}

Result<Json> ControlClient::call(Request request, int timeout_ms,
                                 const std::function<void(const Reply&)>& on_event) {
  request.id = next_id_++;
  const std::string line = encode_request(request) + "\n";
  std::size_t sent = 0;
  while (sent < line.size()) {
    const ssize_t n = ::send(fd_, line.data() + sent, line.size() - sent, MSG_NOSIGNAL);
    if (n < 0) {
      if (errno == EINTR) continue;
      return errno_status("send to rigd");
    }
    sent += static_cast<std::size_t>(n);
  }
  while (true) {
    HC_ASSIGN_OR_RETURN(std::string text, read_line(timeout_ms));
    HC_ASSIGN_OR_RETURN(Reply reply, decode_reply(text));
    if (reply.is_event) {
      if (on_event) on_event(reply);
      continue;
    }
    if (reply.id != request.id && reply.id != 0) continue;
    if (!reply.status.ok()) return reply.status;
    return reply.body;
  }
}

Result<Reply> ControlClient::next_event(int timeout_ms) {
  while (true) {
    HC_ASSIGN_OR_RETURN(std::string text, read_line(timeout_ms));
    HC_ASSIGN_OR_RETURN(Reply reply, decode_reply(text));
    if (reply.is_event) return reply;
  }
}

}  // namespace hc::rig
