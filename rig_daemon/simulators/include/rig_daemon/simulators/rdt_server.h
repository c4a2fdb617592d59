// A Net F/T simulator that speaks RDT over UDP on a loopback address, so the real NetFtClient and
// the Net F/T backend are tested against the wire protocol: it answers start (real-time and
// buffered), stop, bias and threshold-latch reset, streams a configurable wrench signal at up to
// 7 kHz, serves netftapi2.xml over HTTP, and injects faults (stalled stream, dropped and reordered
// packets, a latched status word). One thread; everything public is thread-safe.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "common/status.h"
#include "rig_daemon/backends/rdt.h"

namespace hc::rig::sim {

struct RdtServerOptions {
  std::string address = "127.0.0.1";
  std::uint16_t port = 0;                     // 0: the OS picks one (see RdtServer::port())
  bool serve_http = true;                     // netftapi2.xml on a TCP port of its own
  std::uint16_t http_port = 0;                // 0: the OS picks one
  double output_rate_hz = rdt::kMaxRateHz;    // records per second while streaming
  double internal_rate_hz = rdt::kMaxRateHz;  // ft_sequence increments per second
  std::size_t records_per_buffered_packet = 10;
  double tick_s = 0.001;  // the sender wakes this often and sends every record that is due
  rdt::Calibration calibration{1e6, 1e6, "N", "Nm"};
  // The load on the sensor at time t (s since the server started). Default: constant zero.
  std::function<rdt::Wrench(double t_s)> signal;
  std::uint64_t seed = 1;  // for drop_probability

  Status validate() const;
};

struct RdtFaults {
  bool stalled = false;           // keep the socket open but send nothing (a frozen sensor)
  double drop_probability = 0.0;  // each packet is numbered, then lost with this probability
  bool reorder = false;           // send packets pairwise swapped (2, 1, 4, 3, ...)
  std::uint32_t status_word = 0;  // reported in every record (0 = OK)
};

struct RdtServerStats {
  std::uint64_t requests = 0;
  std::uint64_t malformed_requests = 0;
  std::uint64_t packets_sent = 0;
  std::uint64_t records_sent = 0;
  std::uint64_t packets_dropped = 0;  // by the drop fault (their sequence numbers are skipped)
  std::uint64_t http_requests = 0;
  bool streaming = false;
};

class RdtServer {
 public:
  // Binds the sockets and starts the thread. kInvalidArgument for bad options, kIoError when a
  // socket cannot be bound.
  static Result<std::unique_ptr<RdtServer>> start(RdtServerOptions options);
  ~RdtServer();  // stops the thread
  RdtServer(const RdtServer&) = delete;
  RdtServer& operator=(const RdtServer&) = delete;

  std::uint16_t port() const { return port_; }
  std::uint16_t http_port() const { return http_port_; }
  void set_faults(const RdtFaults& faults);
  RdtServerStats stats() const;
  // The wrench the server reports at `t_s`, after the current bias (what a client should see).
  rdt::Wrench expected_wrench(double t_s) const;

 private:
  explicit RdtServer(RdtServerOptions options) : options_(std::move(options)) {}
  void run();
  void handle_request(const std::uint8_t* data, std::size_t size, const void* from,
                      unsigned from_len);
  void stream_due(std::int64_t now_ns);
  void serve_http_once();
  void send_packet(const std::vector<rdt::Record>& records);
  std::array<std::int32_t, 6> raw_counts(double t_s) const;

  RdtServerOptions options_;
  int udp_fd_ = -1;
  int http_fd_ = -1;
  int wake_fd_[2] = {-1, -1};
  std::uint16_t port_ = 0;
  std::uint16_t http_port_ = 0;
  std::int64_t epoch_ns_ = 0;
  std::thread thread_;
  std::atomic<bool> quit_{false};

  mutable std::mutex mutex_;  // guards everything below
  RdtFaults faults_;
  RdtServerStats stats_;
  std::array<std::int32_t, 6> bias_{};
  // Streaming state (run() thread, read under mutex by stats()).
  bool has_client_ = false;
  std::array<std::uint8_t, 128> client_addr_{};  // a sockaddr_storage
  unsigned client_len_ = 0;
  bool buffered_ = false;
  std::uint32_t remaining_ = 0;  // 0 = unlimited
  bool limited_ = false;
  std::uint32_t rdt_sequence_ = 0;
  std::int64_t stream_start_ns_ = 0;
  std::uint64_t records_due_done_ = 0;
  std::vector<rdt::Record> batch_;
  std::vector<std::uint8_t> held_;  // reorder fault: the packet waiting for its successor
  std::uint64_t rng_state_ = 0;
};

}  // namespace hc::rig::sim
