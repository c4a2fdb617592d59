// Status and Result<T>: how every Hardcopy library reports failure (no exceptions across library
// boundaries). A message names the file, line or element at fault and what was expected.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <variant>

namespace hc {

enum class StatusCode : std::uint8_t {
  kOk = 0,
  kInvalidArgument,     // bad input from the user: malformed file, bad option, out-of-range value
  kNotFound,            // a file, key or device that is not there
  kIoError,             // the OS failed to read or write
  kUnsupported,         // valid request we do not implement (e.g. an unknown file extension)
  kFailedPrecondition,  // the input is well formed but cannot be used for this operation
  kUnavailable,         // a peer or device is not answering (may succeed later)
  kDeadlineExceeded,    // a time limit ran out
  kCancelled,           // stopped on request
  kInternal,            // a bug in Hardcopy or a library it calls
};

std::string_view to_string(StatusCode code);

class [[nodiscard]] Status {
 public:
  Status() = default;  // OK
  Status(StatusCode code, std::string message) : code_(code), message_(std::move(message)) {}

  static Status ok_status() { return {}; }

  bool ok() const { return code_ == StatusCode::kOk; }
  StatusCode code() const { return code_; }
  const std::string& message() const { return message_; }
  // "invalid argument: bunny.ply:12: expected 3 vertex indices, got 2"
  std::string to_string() const;

  // Returns a copy whose message is prefixed with `context` and ": ".
  Status with_context(std::string_view context) const;

 private:
  StatusCode code_ = StatusCode::kOk;
  std::string message_;
};

inline Status invalid_argument(std::string message) {
  return {StatusCode::kInvalidArgument, std::move(message)};
}
inline Status not_found(std::string message) { return {StatusCode::kNotFound, std::move(message)}; }
inline Status io_error(std::string message) { return {StatusCode::kIoError, std::move(message)}; }
inline Status unsupported(std::string message) {
  return {StatusCode::kUnsupported, std::move(message)};
}
inline Status failed_precondition(std::string message) {
  return {StatusCode::kFailedPrecondition, std::move(message)};
}
inline Status internal_error(std::string message) {
  return {StatusCode::kInternal, std::move(message)};
}

// "FILE:LINE: what" (line omitted when 0): the message shape every text-format reader uses.
Status parse_error(const std::filesystem::path& file, std::size_t line, std::string_view what);

// Result<T>: a T or the Status saying why there is none.
template <typename T>
class [[nodiscard]] Result {
 public:
  Result(T value) : v_(std::move(value)) {}        // NOLINT(google-explicit-constructor)
  Result(Status status) : v_(std::move(status)) {  // NOLINT(google-explicit-constructor)
    if (std::get<Status>(v_).ok())
      v_ = Status(StatusCode::kInternal, "Result built from OK status");
  }

  bool ok() const { return std::holds_alternative<T>(v_); }
  const Status& status() const {
    static const Status kOk;
    return ok() ? kOk : std::get<Status>(v_);
  }
  // Precondition: ok(). Calling these on an error is a programmer error.
  T& value() & { return std::get<T>(v_); }
  const T& value() const& { return std::get<T>(v_); }
  T&& value() && { return std::get<T>(std::move(v_)); }
  T& operator*() & { return value(); }
  const T& operator*() const& { return value(); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }

 private:
  std::variant<T, Status> v_;
};

}  // namespace hc

#define HC_STATUS_CONCAT_INNER(a, b) a##b
#define HC_STATUS_CONCAT(a, b) HC_STATUS_CONCAT_INNER(a, b)

// Returns the Status from the enclosing function if `expr` (a Status) is not OK.
#define HC_RETURN_IF_ERROR(expr)             \
  do {                                       \
    ::hc::Status hc_status_ = (expr);        \
    if (!hc_status_.ok()) return hc_status_; \
  } while (false)

// HC_ASSIGN_OR_RETURN(auto mesh, read_mesh(path)); returns the error Status if the Result failed.
#define HC_ASSIGN_OR_RETURN(lhs, expr) \
  HC_ASSIGN_OR_RETURN_IMPL(HC_STATUS_CONCAT(hc_result_, __LINE__), lhs, expr)
#define HC_ASSIGN_OR_RETURN_IMPL(tmp, lhs, expr) \
  auto tmp = (expr);                             \
  if (!tmp.ok()) return tmp.status();            \
  lhs = std::move(tmp).value()
