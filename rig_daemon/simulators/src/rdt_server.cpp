#include "rig_daemon/simulators/rdt_server.h"
#include "common/clock.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <ctime>

namespace hc::rig::sim {
namespace {

std::string errno_text(const std::string& what) { return what + ": " + std::strerror(errno); }

Result<int> bind_socket(int type, const std::string& address, std::uint16_t port,
                        std::uint16_t& bound_port) {
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(port);
  if (::inet_pton(AF_INET, address.c_str(), &addr.sin_addr) != 1)
    return invalid_argument("'" + address + "' is not an IPv4 address");
  const int fd = ::socket(AF_INET, type | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (fd < 0) return io_error(errno_text("socket"));
  const int one = 1;
  ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  if (::bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
    Status s = io_error(errno_text("bind " + address + ":" + std::to_string(port)));
    ::close(fd);
    return s;
  }
  socklen_t len = sizeof addr;
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
  bound_port = ntohs(addr.sin_port);
  return fd;
}

// splitmix64: a tiny seeded generator whose sequence does not depend on the standard library.
std::uint64_t next_random(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

}  // namespace

Status RdtServerOptions::validate() const {
  if (!(output_rate_hz > 0 && output_rate_hz <= rdt::kMaxRateHz))
    return invalid_argument("output_rate_hz: expected (0, 7000], got " +
                            std::to_string(output_rate_hz));
  if (!(internal_rate_hz > 0)) return invalid_argument("internal_rate_hz: expected > 0");
  if (records_per_buffered_packet < 1 || records_per_buffered_packet > rdt::kMaxRecordsPerPacket)
    return invalid_argument("records_per_buffered_packet: expected 1..1800");
  if (!(tick_s > 0 && tick_s <= 0.1)) return invalid_argument("tick_s: expected (0, 0.1]");
  return rdt::validate(calibration);
}

Result<std::unique_ptr<RdtServer>> RdtServer::start(RdtServerOptions options) {
  HC_RETURN_IF_ERROR(options.validate());
  std::unique_ptr<RdtServer> s(new RdtServer(std::move(options)));
  s->rng_state_ = s->options_.seed;
  HC_ASSIGN_OR_RETURN(s->udp_fd_,
                      bind_socket(SOCK_DGRAM, s->options_.address, s->options_.port, s->port_));
  if (s->options_.serve_http) {
    HC_ASSIGN_OR_RETURN(s->http_fd_, bind_socket(SOCK_STREAM, s->options_.address,
                                                 s->options_.http_port, s->http_port_));
    if (::listen(s->http_fd_, 8) != 0) return io_error(errno_text("listen"));
  }
  if (::pipe2(s->wake_fd_, O_CLOEXEC | O_NONBLOCK) != 0) return io_error(errno_text("pipe"));
  s->epoch_ns_ = monotonic_ns();
  s->thread_ = std::thread([p = s.get()] { p->run(); });
  return s;
}

RdtServer::~RdtServer() {
  quit_ = true;
  if (wake_fd_[1] >= 0) (void)!::write(wake_fd_[1], "x", 1);
  if (thread_.joinable()) thread_.join();
  for (int fd : {udp_fd_, http_fd_, wake_fd_[0], wake_fd_[1]})
    if (fd >= 0) ::close(fd);
}

void RdtServer::set_faults(const RdtFaults& faults) {
  std::lock_guard lock(mutex_);
  faults_ = faults;
}

RdtServerStats RdtServer::stats() const {
  std::lock_guard lock(mutex_);
  return stats_;
}

std::array<std::int32_t, 6> RdtServer::raw_counts(double t_s) const {
  const rdt::Wrench w = options_.signal ? options_.signal(t_s) : rdt::Wrench{};
  return rdt::to_counts(w, options_.calibration);
}

rdt::Wrench RdtServer::expected_wrench(double t_s) const {
  std::array<std::int32_t, 6> c = raw_counts(t_s);
  std::lock_guard lock(mutex_);
  for (std::size_t i = 0; i < 6; ++i) c[i] -= bias_[i];
  return rdt::to_si(c, options_.calibration);
}

void RdtServer::run() {
  std::vector<std::uint8_t> buf(2048);
  const auto tick_ns = static_cast<std::int64_t>(options_.tick_s * 1e9);
  while (!quit_) {
    pollfd fds[3] = {{udp_fd_, POLLIN, 0}, {wake_fd_[0], POLLIN, 0}, {http_fd_, POLLIN, 0}};
    const nfds_t n = http_fd_ >= 0 ? 3 : 2;
    bool streaming;
    {
      std::lock_guard lock(mutex_);
      streaming = stats_.streaming;
    }
    timespec timeout{0, streaming ? tick_ns : 50'000'000};
    ::ppoll(fds, n, &timeout, nullptr);
    if (quit_) break;
    if (fds[0].revents & POLLIN) {
      for (int i = 0; i < 64; ++i) {
        sockaddr_storage from{};
        socklen_t from_len = sizeof from;
        const ssize_t got = ::recvfrom(udp_fd_, buf.data(), buf.size(), 0,
                                       reinterpret_cast<sockaddr*>(&from), &from_len);
        if (got < 0) break;
        handle_request(buf.data(), static_cast<std::size_t>(got), &from, from_len);
      }
    }
    if (n == 3 && (fds[2].revents & POLLIN)) serve_http_once();
    stream_due(monotonic_ns());
  }
}

void RdtServer::handle_request(const std::uint8_t* data, std::size_t size, const void* from,
                               unsigned from_len) {
  auto request = rdt::decode_request({data, size});
  std::lock_guard lock(mutex_);
  ++stats_.requests;
  if (!request.ok()) {
    ++stats_.malformed_requests;  // a real sensor ignores what it cannot parse
    return;
  }
  const auto now = monotonic_ns();
  switch (static_cast<rdt::Command>(request->command)) {
    case rdt::Command::kStartRealtime:
    case rdt::Command::kStartBuffered:
    case rdt::Command::kStartMultiUnit:
      std::memcpy(client_addr_.data(), from, std::min<std::size_t>(from_len, client_addr_.size()));
      client_len_ = from_len;
      has_client_ = true;
      buffered_ = request->command == static_cast<std::uint16_t>(rdt::Command::kStartBuffered);
      limited_ = request->sample_count != 0;
      remaining_ = request->sample_count;
      rdt_sequence_ = 0;  // the first packet of each request is 1
      stream_start_ns_ = now;
      records_due_done_ = 0;
      batch_.clear();
      held_.clear();
      stats_.streaming = true;
      break;
    case rdt::Command::kStop:
      stats_.streaming = false;
      held_.clear();
      break;
    case rdt::Command::kSetSoftwareBias: {
      mutex_.unlock();  // raw_counts calls the user's signal; never hold the lock across it
      const auto counts = raw_counts(static_cast<double>(now - epoch_ns_) * 1e-9);
      mutex_.lock();
      bias_ = counts;
      break;
    }
    case rdt::Command::kResetThresholdLatch:
      faults_.status_word = 0;
      break;
  }
}

void RdtServer::send_packet(const std::vector<rdt::Record>& records) {
  // Called with mutex_ held.
  const std::vector<std::uint8_t> bytes = rdt::encode_records(records);
  if (options_.seed != 0 && faults_.drop_probability > 0 &&
      static_cast<double>(next_random(rng_state_) >> 11) * 0x1.0p-53 < faults_.drop_probability) {
    ++stats_.packets_dropped;
    return;
  }
  auto emit = [&](const std::vector<std::uint8_t>& b) {
    ::sendto(udp_fd_, b.data(), b.size(), 0, reinterpret_cast<const sockaddr*>(client_addr_.data()),
             client_len_);
    ++stats_.packets_sent;
    stats_.records_sent += b.size() / rdt::kRecordBytes;
  };
  if (faults_.reorder) {
    if (held_.empty()) {
      held_ = bytes;
      return;
    }
    emit(bytes);
    emit(held_);
    held_.clear();
    return;
  }
  if (!held_.empty()) {
    emit(held_);
    held_.clear();
  }
  emit(bytes);
}

void RdtServer::stream_due(std::int64_t now_ns) {
  std::unique_lock lock(mutex_);
  if (!stats_.streaming || !has_client_) return;
  const double elapsed_s = static_cast<double>(now_ns - stream_start_ns_) * 1e-9;
  auto due = static_cast<std::uint64_t>(std::floor(elapsed_s * options_.output_rate_hz)) + 1;
  if (faults_.stalled) {
    records_due_done_ = due;  // a frozen sensor: those samples never exist
    return;
  }
  // After a long pause (the host was busy) send at most 0.1 s worth at once.
  const auto max_burst = static_cast<std::uint64_t>(options_.output_rate_hz * 0.1) + 1;
  if (due - records_due_done_ > max_burst) records_due_done_ = due - max_burst;
  const std::size_t per_packet = buffered_ ? options_.records_per_buffered_packet : 1;
  const std::array<std::int32_t, 6> bias = bias_;
  const std::uint32_t status = faults_.status_word;
  while (records_due_done_ < due) {
    const double t_rec = static_cast<double>(stream_start_ns_ - epoch_ns_) * 1e-9 +
                         static_cast<double>(records_due_done_) / options_.output_rate_hz;
    ++records_due_done_;
    rdt::Record r;
    r.ft_sequence = static_cast<std::uint32_t>(
        static_cast<std::uint64_t>(std::llround(t_rec * options_.internal_rate_hz)));
    r.status = status;
    lock.unlock();
    const auto raw = raw_counts(t_rec);
    lock.lock();
    for (std::size_t i = 0; i < 6; ++i) r.counts[i] = raw[i] - bias[i];
    // Records are numbered one by one (in buffered mode too), so a client counts lost records.
    r.rdt_sequence = ++rdt_sequence_;
    batch_.push_back(r);
    if (batch_.size() >= per_packet) {
      send_packet(batch_);
      batch_.clear();
    }
    if (limited_ && --remaining_ == 0) {
      if (!batch_.empty()) send_packet(batch_);
      batch_.clear();
      if (!held_.empty()) {
        ::sendto(udp_fd_, held_.data(), held_.size(), 0,
                 reinterpret_cast<const sockaddr*>(client_addr_.data()), client_len_);
        held_.clear();
      }
      stats_.streaming = false;
      return;
    }
  }
}

void RdtServer::serve_http_once() {
  const int fd = ::accept4(http_fd_, nullptr, nullptr, SOCK_CLOEXEC);
  if (fd < 0) return;
  std::string request;
  const std::int64_t deadline = monotonic_ns() + 200'000'000;
  while (request.find("\r\n\r\n") == std::string::npos && request.size() < 8192 &&
         monotonic_ns() < deadline) {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 20) <= 0) continue;
    char buf[1024];
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) break;
    request.append(buf, static_cast<std::size_t>(n));
  }
  std::string answer;
  if (request.rfind("GET /netftapi2.xml ", 0) == 0) {
    const std::string body = rdt::calibration_xml(options_.calibration);
    answer = "HTTP/1.0 200 OK\r\nContent-Type: text/xml\r\nContent-Length: " +
             std::to_string(body.size()) + "\r\n\r\n" + body;
  } else {
    answer = "HTTP/1.0 404 Not Found\r\nContent-Length: 0\r\n\r\n";
  }
  (void)!::send(fd, answer.data(), answer.size(), MSG_NOSIGNAL);
  ::close(fd);
  std::lock_guard lock(mutex_);
  ++stats_.http_requests;
}

}  // namespace hc::rig::sim
