// The control socket: a Unix domain stream socket with owner-only permissions (0600) carrying the
// line-delimited JSON protocol of control_protocol.h. ControlServer is rigd's side (one poll()
// thread serving every connection); ControlClient is rigctl's.
//
// Estop always gets through: past max_connections the server still accepts reserved_connections
// more, which serve estop only (any other request is answered with why it was refused) and close
// after one request or reserved_deadline. Connections that neither subscribed nor sent a request
// for idle_timeout are closed with a message saying so; a client beyond even the reserve gets a
// message too, never a bare reset.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "common/json.h"
#include "common/status.h"
#include "rig_daemon/daemon/control_protocol.h"

namespace hc::rig {

// How many connections the control socket serves and how long it keeps quiet ones.
struct ControlLimits {
  std::size_t max_connections = 64;
  std::size_t reserved_connections = 8;  // beyond max_connections: estop only
  std::chrono::milliseconds idle_timeout{60'000};
  std::chrono::milliseconds reserved_deadline{2'000};  // a reserved connection's one request
};

class ControlServer {
 public:
  // Answers one request; called on the server thread. `subscribe` marks the connection as one that
  // receives events (the handler still answers the request).
  using Handler = std::function<Json(const Request& request, Status& error)>;

  using Limits = ControlLimits;

  // Binds `path` (creating its parent directory), restricts it to the owner (0600) and starts
  // serving. Fails with kFailedPrecondition when another process is listening there (a stale
  // socket file left by a crash is replaced).
  static Result<std::unique_ptr<ControlServer>> start(const std::filesystem::path& path,
                                                      Handler handler, Limits limits = {});
  ~ControlServer();  // stops the thread, closes every connection and removes the socket file
  ControlServer(const ControlServer&) = delete;
  ControlServer& operator=(const ControlServer&) = delete;

  // Queues an event line for every subscribed connection (any thread; never blocks on a client:
  // a client more than kMaxPendingBytes behind is disconnected).
  void broadcast(std::string_view event, const Json& fields);
  const std::filesystem::path& path() const { return path_; }
  std::size_t connections() const { return connection_count_.load(); }

  static constexpr std::size_t kMaxPendingBytes = std::size_t{4} << 20;

 private:
  using TimePoint = std::chrono::steady_clock::time_point;
  struct Connection {
    int fd = -1;
    RequestFramer framer;
    std::string out;
    TimePoint last_request;  // accepted, or the last request received
    bool subscribed = false;
    bool reserved = false;             // accepted past max_connections: estop only, one request
    bool read_closed = false;          // end-of-file or a read error: no more input
    std::atomic<bool> closing{false};  // close once `out` is flushed (broadcast() sets it too)
    std::optional<TimePoint> linger_until;  // output shut, discarding input until EOF or then
  };

  ControlServer(std::filesystem::path path, int listen_fd, Handler handler, Limits limits);
  void run();
  void wake();
  void accept_all(TimePoint now);
  void read_input(Connection& c);
  void answer_requests(Connection& c);
  void flush(Connection& c, TimePoint now);
  void expire(Connection& c, TimePoint now);

  std::filesystem::path path_;
  int listen_fd_ = -1;
  int wake_pipe_[2] = {-1, -1};
  Handler handler_;
  Limits limits_;
  std::atomic<bool> stop_{false};
  std::atomic<std::size_t> connection_count_{0};
  std::mutex mutex_;  // guards connections_' out buffers and subscribed flags against broadcast()
  std::vector<std::unique_ptr<Connection>> connections_;
  std::thread thread_;
};

class ControlClient {
 public:
  static Result<ControlClient> connect(const std::filesystem::path& path);
  ControlClient(ControlClient&&) noexcept;
  ControlClient& operator=(ControlClient&&) noexcept;
  ~ControlClient();

  // Sends `request` (its id is assigned) and waits up to timeout_ms for its response; events that
  // arrive meanwhile go to `on_event` (if set). Returns the result, or the daemon's error.
  Result<Json> call(Request request, int timeout_ms = 10000,
                    const std::function<void(const Reply&)>& on_event = {});
  // Waits up to timeout_ms for the next event line. kDeadlineExceeded on timeout; kUnavailable
  // when the daemon closed the connection.
  Result<Reply> next_event(int timeout_ms);

 private:
  explicit ControlClient(int fd) : fd_(fd) {}
  Result<std::string> read_line(int timeout_ms);
  int fd_ = -1;
  std::int64_t next_id_ = 1;
  std::string in_;
};

}  // namespace hc::rig
