#include "rig_daemon/daemon/control_protocol.h"

#include <array>
#include <utility>

namespace hc::rig {
namespace {

constexpr std::array<std::pair<Command, std::string_view>, 10> kCommands{{
    {Command::kStatus, "status"},
    {Command::kDevices, "devices"},
    {Command::kStart, "start"},
    {Command::kPause, "pause"},
    {Command::kResume, "resume"},
    {Command::kStop, "stop"},
    {Command::kEstop, "estop"},
    {Command::kReset, "reset"},
    {Command::kSubscribe, "subscribe"},
    {Command::kShutdown, "shutdown"},
}};

constexpr std::array<std::pair<StatusCode, std::string_view>, 10> kCodes{{
    {StatusCode::kOk, "ok"},
    {StatusCode::kInvalidArgument, "invalid_argument"},
    {StatusCode::kNotFound, "not_found"},
    {StatusCode::kIoError, "io_error"},
    {StatusCode::kUnsupported, "unsupported"},
    {StatusCode::kFailedPrecondition, "failed_precondition"},
    {StatusCode::kUnavailable, "unavailable"},
    {StatusCode::kDeadlineExceeded, "deadline_exceeded"},
    {StatusCode::kCancelled, "cancelled"},
    {StatusCode::kInternal, "internal"},
}};

Status bad_request(std::string_view what) {
  return invalid_argument("control request: " + std::string(what));
}

// JSON strings must be valid UTF-8 for nlohmann's dump(); replace rather than throw.
std::string dump_line(const Json& j) {
  return j.dump(-1, ' ', false, Json::error_handler_t::replace);
}

}  // namespace

std::string_view to_string(Command c) {
  for (const auto& [cmd, name] : kCommands)
    if (cmd == c) return name;
  return "unknown";
}

std::optional<Command> command_from_string(std::string_view name) {
  for (const auto& [cmd, n] : kCommands)
    if (n == name) return cmd;
  return std::nullopt;
}

Result<Request> decode_request(std::string_view line) {
  if (line.size() > kMaxRequestBytes)
    return bad_request("longer than " + std::to_string(kMaxRequestBytes) + " bytes");
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  Result<Json> parsed = parse_json(line, "request");
  if (!parsed.ok()) return bad_request(parsed.status().message());
  const Json& j = *parsed;
  if (!j.is_object()) return bad_request("expected a JSON object");
  Request r;
  bool have_cmd = false;
  for (const auto& [key, value] : j.items()) {
    if (key == "id") {
      if (!value.is_number_integer()) return bad_request("id: expected an integer");
      r.id = value.get<std::int64_t>();
    } else if (key == "cmd") {
      if (!value.is_string()) return bad_request("cmd: expected a string");
      const auto& name = value.get_ref<const std::string&>();
      std::optional<Command> c = command_from_string(name);
      if (!c) {
        std::string known;
        for (const auto& [cmd, n] : kCommands)
          known += (known.empty() ? "" : ", ") + std::string(n);
        return bad_request("cmd: unknown command '" + name.substr(0, 64) + "' (expected one of " +
                           known + ")");
      }
      r.command = *c;
      have_cmd = true;
    } else if (key == "plan") {
      if (!value.is_string()) return bad_request("plan: expected the plan's YAML text");
      r.plan = value.get<std::string>();
    } else if (key == "plan_name") {
      if (!value.is_string()) return bad_request("plan_name: expected a string");
      r.plan_name = value.get<std::string>();
      if (r.plan_name.size() > 4096) return bad_request("plan_name: longer than 4096 bytes");
    } else {
      return bad_request("unknown key '" + key.substr(0, 64) + "'");
    }
  }
  if (!have_cmd) return bad_request("missing key 'cmd'");
  if (r.command == Command::kStart && r.plan.empty())
    return bad_request("start: missing key 'plan' (the plan's YAML text)");
  if (r.command != Command::kStart && (!r.plan.empty() || !r.plan_name.empty()))
    return bad_request(std::string(to_string(r.command)) + ": takes no plan");
  if (r.plan_name.empty()) r.plan_name = "plan.yaml";
  return r;
}

std::string encode_request(const Request& request) {
  Json j{{"id", request.id}, {"cmd", to_string(request.command)}};
  if (request.command == Command::kStart) {
    j["plan"] = request.plan;
    j["plan_name"] = request.plan_name;
  }
  return dump_line(j);
}

std::string encode_ok(std::int64_t id, const Json& result) {
  return dump_line(Json{{"id", id}, {"ok", true}, {"result", result}});
}

std::string encode_error(std::int64_t id, const Status& status) {
  return dump_line(
      Json{{"id", id},
           {"ok", false},
           {"error", {{"code", status_code_name(status.code())}, {"message", status.message()}}}});
}

std::string encode_event(std::string_view event, Json fields) {
  if (!fields.is_object()) fields = Json::object();
  fields["event"] = event;
  return dump_line(fields);
}

Result<Reply> decode_reply(std::string_view line) {
  Result<Json> parsed = parse_json(line, "reply");
  if (!parsed.ok()) return invalid_argument("rigd reply: " + parsed.status().message());
  Json& j = *parsed;
  if (!j.is_object()) return invalid_argument("rigd reply: expected a JSON object");
  Reply r;
  if (auto e = j.find("event"); e != j.end()) {
    if (!e->is_string()) return invalid_argument("rigd reply: event: expected a string");
    r.is_event = true;
    r.event = e->get<std::string>();
    r.body = std::move(j);
    return r;
  }
  auto id = j.find("id");
  auto ok = j.find("ok");
  if (id == j.end() || !id->is_number_integer() || ok == j.end() || !ok->is_boolean())
    return invalid_argument("rigd reply: expected {\"id\": N, \"ok\": true|false, ...}");
  r.id = id->get<std::int64_t>();
  if (ok->get<bool>()) {
    if (auto res = j.find("result"); res != j.end()) r.body = *res;
    return r;
  }
  StatusCode code = StatusCode::kInternal;
  std::string message = "(no message)";
  if (auto err = j.find("error"); err != j.end() && err->is_object()) {
    if (auto c = err->find("code"); c != err->end() && c->is_string())
      for (const auto& [sc, name] : kCodes)
        if (name == c->get_ref<const std::string&>()) code = sc;
    if (auto m = err->find("message"); m != err->end() && m->is_string())
      message = m->get<std::string>();
  }
  if (code == StatusCode::kOk) code = StatusCode::kInternal;
  r.status = Status(code, message);
  return r;
}

void RequestFramer::append(std::string_view bytes) {
  if (overlong_ || eof_) return;
  if (head_ > 0 && head_ * 2 >= buffer_.size()) {  // drop what was taken (amortised O(1))
    buffer_.erase(0, head_);
    scanned_ -= head_;
    head_ = 0;
  }
  buffer_.append(bytes);
}

std::optional<std::string> RequestFramer::next() {
  while (!overlong_ && head_ < buffer_.size()) {
    const std::size_t nl = buffer_.find('\n', scanned_);
    std::string_view line;
    if (nl != std::string::npos) {
      line = std::string_view(buffer_).substr(head_, nl - head_);
      head_ = scanned_ = nl + 1;
    } else {
      scanned_ = buffer_.size();
      // "+ 1": a line of exactly max bytes may still be waiting for its "\r\n".
      if (buffer_.size() - head_ > max_line_bytes_ + 1) {
        overlong_ = true;
        buffer_.clear();
        head_ = scanned_ = 0;
        return std::nullopt;
      }
      if (!eof_) return std::nullopt;
      line = std::string_view(buffer_).substr(head_);  // end-of-file: the rest is a line
      head_ = scanned_ = buffer_.size();
    }
    if (line.empty() || line == "\r") continue;
    return std::string(line);
  }
  return std::nullopt;
}

}  // namespace hc::rig
