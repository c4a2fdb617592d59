#include "rig_daemon/backends/netft_client.h"
#include "common/clock.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <ctime>

namespace hc::rig {
namespace {

std::string errno_text(const char* what) { return std::string(what) + ": " + std::strerror(errno); }

Result<sockaddr_in> ipv4_address(const std::string& host, std::uint16_t port) {
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(port);
  if (::inet_pton(AF_INET, host.c_str(), &addr.sin_addr) != 1)
    return invalid_argument("'" + host + "' is not an IPv4 address");
  return addr;
}

// Milliseconds for poll(), rounded up so a short positive timeout still waits.
int poll_ms(std::chrono::nanoseconds timeout) {
  if (timeout <= std::chrono::nanoseconds::zero()) return 0;
  const auto ms = std::chrono::ceil<std::chrono::milliseconds>(timeout).count();
  return ms > 1'000'000 ? 1'000'000 : static_cast<int>(ms);
}

}  // namespace

Status NetFtOptions::read(ConfigNode node) {
  node.optional("host", host);
  node.optional("port", port);
  node.optional("calibration_source", calibration_source, {"config", "sensor"});
  node.optional("http_port", http_port);
  node.optional("counts_per_force", calibration.counts_per_force, Bounds::positive());
  node.optional("counts_per_torque", calibration.counts_per_torque, Bounds::positive());
  node.optional("force_unit", calibration.force_unit, {"N", "kN", "lbf"});
  node.optional("torque_unit", calibration.torque_unit, {"Nm", "Nmm", "kNm", "lbfin", "lbfft"});
  node.optional("start_attempts", start_attempts, Bounds::between(1, 100));
  node.optional("start_timeout_s", start_timeout_s, Bounds::between(0.001, 10));
  node.optional("buffered", buffered);
  node.optional("receive_buffer_bytes", receive_buffer_bytes, Bounds::between(4096, 1 << 28));
  return node.status();
}

Status NetFtOptions::validate() const {
  if (auto a = ipv4_address(host, port); !a.ok()) return a.status().with_context("host");
  if (port == 0) return invalid_argument("port: expected 1..65535, got 0");
  if (calibration_source != "config" && calibration_source != "sensor")
    return invalid_argument("calibration_source: expected 'config' or 'sensor', got '" +
                            calibration_source + "'");
  if (calibration_source == "config") HC_RETURN_IF_ERROR(rdt::validate(calibration));
  if (start_attempts < 1) return invalid_argument("start_attempts: expected >= 1");
  if (!(start_timeout_s > 0)) return invalid_argument("start_timeout_s: expected > 0");
  return {};
}

Result<std::unique_ptr<NetFtClient>> NetFtClient::open(const NetFtOptions& options) {
  HC_RETURN_IF_ERROR(options.validate());
  std::unique_ptr<NetFtClient> client(new NetFtClient(options));
  if (options.calibration_source == "sensor") {
    auto body = http_get(options.host, options.http_port, "/netftapi2.xml",
                         std::chrono::milliseconds(1000));
    if (!body.ok()) return body.status().with_context("Net F/T calibration");
    HC_ASSIGN_OR_RETURN(client->options_.calibration, rdt::parse_calibration_xml(*body));
  }
  HC_ASSIGN_OR_RETURN(sockaddr_in addr, ipv4_address(options.host, options.port));
  client->fd_ = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (client->fd_ < 0) return io_error(errno_text("Net F/T: socket"));
  const int rcvbuf = options.receive_buffer_bytes;
  // Best effort: the kernel caps it at net.core.rmem_max.
  (void)::setsockopt(client->fd_, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf);
  if (::connect(client->fd_, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0)
    return io_error(errno_text("Net F/T: connect"));
  return client;
}

NetFtClient::~NetFtClient() {
  if (fd_ >= 0) ::close(fd_);
}

Status NetFtClient::send(const rdt::Request& request) {
  const auto bytes = rdt::encode_request(request);
  if (::send(fd_, bytes.data(), bytes.size(), 0) != static_cast<ssize_t>(bytes.size()))
    return io_error(
        errno_text(("Net F/T: send " + std::string(rdt::command_name(request.command))).c_str()));
  return {};
}

Status NetFtClient::start(std::uint32_t sample_count) {
  const auto command =
      options_.buffered ? rdt::Command::kStartBuffered : rdt::Command::kStartRealtime;
  tracker_.reset();  // rdt_sequence restarts at 1 for each request
  const auto wait =
      std::chrono::nanoseconds(static_cast<std::int64_t>(options_.start_timeout_s * 1e9));
  for (int attempt = 0; attempt < options_.start_attempts; ++attempt) {
    ++stats_.start_attempts;
    HC_RETURN_IF_ERROR(send({static_cast<std::uint16_t>(command), sample_count}));
    const std::int64_t deadline = monotonic_ns() + wait.count();
    while (true) {
      const std::int64_t left = deadline - monotonic_ns();
      if (left <= 0) break;
      pollfd p{fd_, POLLIN, 0};
      const int rc = ::poll(&p, 1, poll_ms(std::chrono::nanoseconds(left)));
      if (rc < 0 && errno != EINTR) return io_error(errno_text("Net F/T: poll"));
      if (rc <= 0) continue;
      auto n = drain(pending_);
      // ECONNREFUSED here means nothing listens yet: keep retrying like a lost start packet.
      if (!n.ok() && n.status().code() != StatusCode::kUnavailable) return n.status();
      if (n.ok() && !pending_.empty()) return {};
    }
  }
  return {StatusCode::kDeadlineExceeded,
          "Net F/T at " + options_.host + ":" + std::to_string(options_.port) +
              ": no record after " + std::to_string(options_.start_attempts) +
              " start attempts of " + std::to_string(options_.start_timeout_s) + " s"};
}

Status NetFtClient::stop() {
  HC_RETURN_IF_ERROR(send({static_cast<std::uint16_t>(rdt::Command::kStop), 0}));
  pending_.clear();
  return {};
}

Status NetFtClient::bias() {
  return send({static_cast<std::uint16_t>(rdt::Command::kSetSoftwareBias), 0});
}

Result<std::size_t> NetFtClient::drain(std::vector<FtSample>& out) {
  std::size_t appended = 0;
  // One buffered datagram can carry kMaxRecordsPerPacket records; one more byte detects overlength.
  std::vector<std::uint8_t> buf(rdt::kMaxRecordsPerPacket * rdt::kRecordBytes + 1);
  for (int i = 0; i < 100000; ++i) {
    const ssize_t n = ::recv(fd_, buf.data(), buf.size(), MSG_DONTWAIT);
    if (n < 0) {
      if (errno == EAGAIN || errno == EWOULDBLOCK) break;
      if (errno == EINTR) continue;
      if (errno == ECONNREFUSED)
        return Status(StatusCode::kUnavailable, "Net F/T at " + options_.host + ":" +
                                                    std::to_string(options_.port) +
                                                    ": port unreachable (nothing listening)");
      return io_error(errno_text("Net F/T: recv"));
    }
    const std::int64_t now = monotonic_ns();
    ++stats_.datagrams;
    auto records = rdt::decode_records({buf.data(), static_cast<std::size_t>(n)});
    if (!records.ok()) {
      ++stats_.malformed;
      continue;
    }
    for (const rdt::Record& r : *records) {
      const auto verdict = tracker_.update(r.rdt_sequence);
      if (verdict == rdt::SequenceTracker::Verdict::kDuplicate ||
          verdict == rdt::SequenceTracker::Verdict::kStale)
        continue;
      if (r.status != 0) ++stats_.status_errors;
      out.push_back({now, r, rdt::to_si(r.counts, options_.calibration)});
      ++stats_.records;
      ++appended;
    }
  }
  return appended;
}

Result<std::size_t> NetFtClient::receive(std::vector<FtSample>& out,
                                         std::chrono::nanoseconds timeout) {
  std::size_t appended = 0;
  if (!pending_.empty()) {
    appended = pending_.size();
    out.insert(out.end(), pending_.begin(), pending_.end());
    pending_.clear();
    timeout = std::chrono::nanoseconds::zero();
  }
  pollfd p{fd_, POLLIN, 0};
  const int rc = ::poll(&p, 1, poll_ms(timeout));
  if (rc < 0 && errno != EINTR) return io_error(errno_text("Net F/T: poll"));
  if (rc > 0) {
    HC_ASSIGN_OR_RETURN(std::size_t n, drain(out));
    appended += n;
  }
  return appended;
}

NetFtStats NetFtClient::stats() const {
  NetFtStats s = stats_;
  s.lost = tracker_.lost();
  s.settled_lost = tracker_.settled_lost();
  s.late = tracker_.late();
  s.duplicates = tracker_.duplicates();
  s.stale = tracker_.stale();
  return s;
}

Result<std::string> http_get(const std::string& host, std::uint16_t port, const std::string& path,
                             std::chrono::milliseconds timeout) {
  HC_ASSIGN_OR_RETURN(sockaddr_in addr, ipv4_address(host, port));
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (fd < 0) return io_error(errno_text("HTTP: socket"));
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  const std::string where = "http://" + host + ":" + std::to_string(port) + path;
  const std::int64_t deadline = monotonic_ns() + timeout.count() * 1'000'000;
  auto wait_for = [&](short events) -> Status {
    while (true) {
      const std::int64_t left = deadline - monotonic_ns();
      if (left <= 0) return {StatusCode::kUnavailable, where + ": no answer in time"};
      pollfd p{fd, events, 0};
      const int rc = ::poll(&p, 1, poll_ms(std::chrono::nanoseconds(left)));
      if (rc < 0 && errno != EINTR) return io_error(errno_text("HTTP: poll"));
      if (rc > 0) return {};
    }
  };
  if (::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
    if (errno != EINPROGRESS) return Status(StatusCode::kUnavailable, errno_text(where.c_str()));
    HC_RETURN_IF_ERROR(wait_for(POLLOUT));
    int err = 0;
    socklen_t len = sizeof err;
    ::getsockopt(fd, SOL_SOCKET, SO_ERROR, &err, &len);
    if (err != 0)
      return Status(StatusCode::kUnavailable, where + ": " + std::string(std::strerror(err)));
  }
  const std::string request = "GET " + path + " HTTP/1.0\r\nHost: " + host + "\r\n\r\n";
  std::size_t sent = 0;
  while (sent < request.size()) {
    HC_RETURN_IF_ERROR(wait_for(POLLOUT));
    const ssize_t n = ::send(fd, request.data() + sent, request.size() - sent, MSG_NOSIGNAL);
    if (n < 0 && errno != EAGAIN && errno != EINTR) return io_error(errno_text(where.c_str()));
    if (n > 0) sent += static_cast<std::size_t>(n);
  }
  std::string answer;
  constexpr std::size_t kMaxAnswer = 1 << 20;  // the calibration page is a few kB
  while (true) {
    HC_RETURN_IF_ERROR(wait_for(POLLIN));
    char buf[4096];
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n < 0) {
      if (errno == EAGAIN || errno == EINTR) continue;
      return io_error(errno_text(where.c_str()));
    }
    if (n == 0) break;
    answer.append(buf, static_cast<std::size_t>(n));
    if (answer.size() > kMaxAnswer) return io_error(where + ": answer larger than 1 MiB");
  }
  const std::size_t eol = answer.find("\r\n");
  const std::string status_line = answer.substr(0, eol);
  if (status_line.rfind("HTTP/1.", 0) != 0 || status_line.size() < 12)
    return io_error(where + ": not an HTTP answer");
  if (status_line.compare(9, 3, "200") != 0) return io_error(where + ": " + status_line);
  const std::size_t body = answer.find("\r\n\r\n");
  if (body == std::string::npos) return io_error(where + ": answer has no header end");
  return answer.substr(body + 4);
}

}  // namespace hc::rig
