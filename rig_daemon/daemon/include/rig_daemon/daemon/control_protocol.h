// rigd's control protocol: line-delimited JSON over a Unix domain socket (owner-only, 0600).
// Every request is one JSON object on one line; rigd answers each with one response line, and
// pushes event lines to connections that subscribed:
//
//   -> {"id": 7, "cmd": "start", "plan": "<plan YAML text>", "plan_name": "block.yaml"}
//   <- {"id": 7, "ok": true, "result": {"session": "sessions/block-20261122T120501.mcap"}}
//   <- {"id": 8, "ok": false, "error": {"code": "failed_precondition", "message": "..."}}
//   -> {"id": 9, "cmd": "subscribe"}
//   <- {"event": "progress", "state": "running", "done": 12, "total": 180, ...}
//
// Commands: status, devices, start (plan, plan_name), pause, resume, stop, estop, reset (clears
// the safety stop that a trip or an estop leaves; see Daemon::reset), subscribe, shutdown. Every
// complete line is answered, also one that arrives just before the client half-closes its side
// (RequestFramer); an unterminated last line before end-of-file counts as a line. Requests are
// decoded strictly (unknown keys and commands are errors) so that a typo in a client is reported,
// not ignored.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "common/json.h"
#include "common/status.h"

namespace hc::rig {

// The longest request line rigd accepts: a plan with 1000 locations is well under 1 MiB.
inline constexpr std::size_t kMaxRequestBytes = std::size_t{1} << 20;
inline constexpr int kControlProtocolVersion = 1;

enum class Command {
  kStatus,
  kDevices,
  kStart,
  kPause,
  kResume,
  kStop,
  kEstop,
  kReset,
  kSubscribe,
  kShutdown
};
std::string_view to_string(Command c);
std::optional<Command> command_from_string(std::string_view name);

struct Request {
  std::int64_t id = 0;  // echoed in the response; 0 when the client sent none
  Command command = Command::kStatus;
  std::string plan;       // start: the plan's YAML text
  std::string plan_name;  // start: the name its messages use (the client's file name)
};

// Decodes one request line (without its '\n'). Fails with kInvalidArgument naming what is wrong:
// too long, not JSON, not an object, unknown key or command, missing or mistyped field.
Result<Request> decode_request(std::string_view line);
// One line, no '\n'.
std::string encode_request(const Request& request);

// Responses and events as lines (no '\n').
std::string encode_ok(std::int64_t id, const Json& result);
std::string encode_error(std::int64_t id, const Status& status);
std::string encode_event(std::string_view event, Json fields);

// A decoded response or event line (client side).
struct Reply {
  bool is_event = false;
  std::string event;    // events: "progress", "finished", "safety", ...
  std::int64_t id = 0;  // responses
  Status status;        // responses: OK or the daemon's error
  Json body;            // responses: result; events: the whole object
};
Result<Reply> decode_reply(std::string_view line);

// Splits a connection's byte stream into request lines: bytes go in as they arrive, complete lines
// come out in order. At end-of-file (finish()) the unterminated rest is a line too, so a client
// that writes its request and half-closes (`echo ... | socat - UNIX-CONNECT:...`) is served. A line
// growing past max_line_bytes makes overlong() true (the rest of the stream is not framed).
class RequestFramer {
 public:
  explicit RequestFramer(std::size_t max_line_bytes = kMaxRequestBytes)
      : max_line_bytes_(max_line_bytes) {}
  void append(std::string_view bytes);
  void finish() { eof_ = true; }
  // The next complete line without its '\n' (blank lines and a lone "\r" are skipped), or
  // nothing when no complete line is buffered.
  std::optional<std::string> next();
  bool overlong() const { return overlong_; }
  bool eof() const { return eof_; }
  // True when nothing more can come out: end-of-file seen and every buffered line taken.
  bool drained() const { return overlong_ || (eof_ && head_ == buffer_.size()); }

 private:
  std::size_t max_line_bytes_;
  std::string buffer_;
  std::size_t head_ = 0;     // buffer_[0, head_) was taken already
  std::size_t scanned_ = 0;  // buffer_[head_, scanned_) holds no '\n'
  bool eof_ = false;
  bool overlong_ = false;
};

}  // namespace hc::rig
