#include "common/json.h"

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <exception>

#include "common/file_io.h"

namespace hc {
namespace {

// nlohmann's what() is "[json.exception.parse_error.101] parse error at line 1, column 5: syntax
// error ..."; keep the part after the position, which we print in the file:line:col form instead.
std::string_view exception_detail(std::string_view what) {
  if (!what.empty() && what.front() == '[') {
    const std::size_t close = what.find("] ");
    if (close != std::string_view::npos) what.remove_prefix(close + 2);
  }
  constexpr std::string_view kParseError = "parse error";
  if (what.substr(0, kParseError.size()) == kParseError) {
    const std::size_t colon = what.find(": ");
    if (colon != std::string_view::npos) what.remove_prefix(colon + 2);
  }
  return what;
}

struct LineColumn {
  std::size_t line;
  std::size_t column;
};

// 1-based line and byte column of `offset` in `text`.
LineColumn line_column(std::string_view text, std::size_t offset) {
  const std::string_view before = text.substr(0, std::min(offset, text.size()));
  const auto line = 1 + static_cast<std::size_t>(std::count(before.begin(), before.end(), '\n'));
  const std::size_t line_start = before.rfind('\n');
  const std::size_t column =
      line_start == std::string_view::npos ? before.size() + 1 : before.size() - line_start;
  return {line, column};
}

// Offset of the first bracket that opens more than kMaxJsonDepth levels, or npos. Exact for valid
// JSON; on invalid text the parser reports the real error anyway.
std::size_t too_deep_at(std::string_view text) {
  int depth = 0;
  bool in_string = false;
  bool escaped = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (escaped) {
        escaped = false;
      } else if (c == '\\') {
        escaped = true;
      } else if (c == '"') {
        in_string = false;
      }
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > kMaxJsonDepth) return i;
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  return std::string_view::npos;
}

}  // namespace

std::string_view status_code_name(StatusCode code) {
  switch (code) {
    case StatusCode::kOk:
      return "ok";
    case StatusCode::kInvalidArgument:
      return "invalid_argument";
    case StatusCode::kNotFound:
      return "not_found";
    case StatusCode::kIoError:
      return "io_error";
    case StatusCode::kUnsupported:
      return "unsupported";
    case StatusCode::kFailedPrecondition:
      return "failed_precondition";
    case StatusCode::kUnavailable:
      return "unavailable";
    case StatusCode::kDeadlineExceeded:
      return "deadline_exceeded";
    case StatusCode::kCancelled:
      return "cancelled";
    case StatusCode::kInternal:
      return "internal";
  }
  return "unknown";
}

Json status_to_json(const Status& status) {
  if (status.ok()) return Json{{"ok", true}};
  return Json{{"ok", false},
              {"code", std::string(status_code_name(status.code()))},
              {"message", status.message()}};
}

std::string dump_json(const Json& json) {
  return json.dump(2, ' ', /*ensure_ascii=*/false, Json::error_handler_t::replace) + "\n";
}

Status print_json(const Json& json, std::FILE* out) {
  const std::string text = dump_json(json);
  errno = 0;
  const std::size_t written = std::fwrite(text.data(), 1, text.size(), out);
  if (written != text.size() || std::fflush(out) != 0)
    return io_error(
        fmt::format("cannot write JSON output: {}", errno ? std::strerror(errno) : "short write"));
  return {};
}

Result<Json> parse_json(std::string_view text, std::string_view name) {
  if (const std::size_t deep = too_deep_at(text); deep != std::string_view::npos) {
    const auto [line, column] = line_column(text, deep);
    return invalid_argument(fmt::format("{}:{}:{}: invalid JSON: nested deeper than {} levels",
                                        name, line, column, kMaxJsonDepth));
  }
  try {
    return Json::parse(text.begin(), text.end());
  } catch (const Json::parse_error& e) {
    // e.byte counts the characters read, the offending one included.
    const auto [line, column] = line_column(text, e.byte > 0 ? e.byte - 1 : 0);
    return invalid_argument(
        fmt::format("{}:{}:{}: invalid JSON: {}", name, line, column, exception_detail(e.what())));
  } catch (const Json::exception& e) {
    return invalid_argument(fmt::format("{}: invalid JSON: {}", name, exception_detail(e.what())));
  } catch (const std::exception& e) {
    return invalid_argument(fmt::format("{}: cannot parse JSON: {}", name, e.what()));
  }
}

Result<Json> load_json(const std::filesystem::path& path) {
  HC_ASSIGN_OR_RETURN(std::string text, read_file(path));
  return parse_json(text, path.string());
}

}  // namespace hc
