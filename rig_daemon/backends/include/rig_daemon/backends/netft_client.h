// A client for an ATI Net F/T (or Axia) force-torque sensor over RDT/UDP: start real-time or
// buffered streaming, stop, software bias, and reception with host timestamps, loss and reorder
// accounting. The calibration (counts per force / torque unit) comes from the config or from the
// sensor's own netftapi2.xml over HTTP. Synchronous: the caller (a device backend's thread) calls
// receive() in a loop.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "common/config.h"
#include "common/status.h"
#include "rig_daemon/backends/rdt.h"

namespace hc::rig {

struct NetFtOptions {
  std::string host = "127.0.0.1";  // IPv4 address of the sensor
  std::uint16_t port = rdt::kDefaultPort;
  // Where counts per unit come from: "config" (the fields below) or "sensor" (HTTP netftapi2.xml).
  std::string calibration_source = "config";
  rdt::Calibration calibration;
  std::uint16_t http_port = 80;
  // Start handshake as in the ROS driver: resend the start command up to `start_attempts` times,
  // waiting `start_timeout_s` for the first record each time (start packets can be lost).
  int start_attempts = 10;
  double start_timeout_s = 0.1;
  bool buffered = false;               // kStartBuffered instead of kStartRealtime
  int receive_buffer_bytes = 1 << 21;  // 7000 x 36 B/s: 2 MiB holds ~8 s of records

  Status read(ConfigNode node);
  Status validate() const;
};

// One force-torque record as received.
struct FtSample {
  std::int64_t host_ns = 0;  // CLOCK_MONOTONIC when the datagram was read
  rdt::Record record;        // device counters (rdt_sequence, ft_sequence), status, raw counts
  rdt::Wrench wrench;        // counts in SI with the client's calibration
};

struct NetFtStats {
  std::uint64_t datagrams = 0;
  std::uint64_t records = 0;        // delivered to the caller
  std::uint64_t lost = 0;           // rdt_sequence gaps not filled (so far)
  std::uint64_t settled_lost = 0;   // gaps too old to be filled by a late packet (only grows)
  std::uint64_t late = 0;           // reordered records that filled a gap (delivered)
  std::uint64_t duplicates = 0;     // dropped
  std::uint64_t stale = 0;          // older than the reorder window (dropped)
  std::uint64_t malformed = 0;      // datagrams that did not decode (dropped)
  std::uint64_t status_errors = 0;  // records with a non-zero status word
  std::uint64_t start_attempts = 0;
};

class NetFtClient {
 public:
  // Opens the UDP socket (connected to host:port, so only the sensor's datagrams are read) and,
  // with calibration_source "sensor", fetches the calibration over HTTP. kInvalidArgument for bad
  // options, kUnavailable when the sensor's HTTP server does not answer.
  static Result<std::unique_ptr<NetFtClient>> open(const NetFtOptions& options);
  ~NetFtClient();
  NetFtClient(const NetFtClient&) = delete;
  NetFtClient& operator=(const NetFtClient&) = delete;

  // Sends the start command (real-time or buffered, `sample_count` 0 = until stopped) and waits for
  // the first record, resending as configured. The records received meanwhile are kept for the
  // next receive(). kDeadlineExceeded when no record came after every attempt.
  Status start(std::uint32_t sample_count = 0);
  // Sends stop (the sensor does not answer it) and discards datagrams already queued.
  Status stop();
  // Sends "set software bias": the sensor subtracts the current load from later records.
  Status bias();
  // Sends any command (e.g. reset threshold latch).
  Status send(const rdt::Request& request);

  // Waits up to `timeout` for data, then appends every record that is already queued (so a burst
  // is read in one call). Returns how many were appended; 0 on timeout. kIoError if the socket
  // fails (e.g. ICMP port unreachable surfaced as ECONNREFUSED is reported once and cleared).
  Result<std::size_t> receive(std::vector<FtSample>& out, std::chrono::nanoseconds timeout);

  const rdt::Calibration& calibration() const { return options_.calibration; }
  const NetFtOptions& options() const { return options_; }
  NetFtStats stats() const;

 private:
  explicit NetFtClient(NetFtOptions options) : options_(std::move(options)) {}
  // Reads every queued datagram without blocking.
  Result<std::size_t> drain(std::vector<FtSample>& out);

  NetFtOptions options_;
  int fd_ = -1;
  rdt::SequenceTracker tracker_;
  NetFtStats stats_;
  std::vector<FtSample> pending_;  // received during start()
};

// A minimal HTTP/1.0 GET (no redirects, no chunked encoding): returns the body of a 200 answer.
// Hand-written because the project has no HTTP client library and the sensor's calibration page
// is one small static document. kUnavailable when nothing answers within `timeout`, kIoError for a
// non-200 status or a malformed answer.
Result<std::string> http_get(const std::string& host, std::uint16_t port, const std::string& path,
                             std::chrono::milliseconds timeout);

}  // namespace hc::rig
