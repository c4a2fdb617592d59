// A client for the rig's 4-DOF arm controller over Modbus TCP or RTU (libmodbus), speaking the
// register map of arm_register_map.h. Thread-safe: one mutex serialises bus transactions, so
// stop() from another thread waits for at most one transaction in flight. A transaction that fails
// because the link is gone closes the connection; the next call reconnects once (so a controller
// that went away and came back is picked up again without a new client).
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <string>

#include "common/config.h"
#include "common/status.h"
#include "rig_daemon/backends/arm_register_map.h"

struct _modbus;  // libmodbus's modbus_t

namespace hc::rig {

struct ModbusArmOptions {
  std::string transport = "tcp";  // "tcp" or "rtu"
  // TCP
  std::string host = "127.0.0.1";
  std::uint16_t port = 502;
  // RTU (serial line)
  std::string device = "/dev/ttyUSB0";
  int baud = 115200;
  std::string parity = "N";  // N, E or O
  int data_bits = 8;
  int stop_bits = 1;
  // Both
  int slave_id = 1;                 // unit identifier (TCP) / slave address (RTU)
  double response_timeout_s = 0.2;  // per transaction
  double connect_timeout_s = 0.5;   // TCP connect (libmodbus uses the response timeout)

  Status read(ConfigNode node);
  Status validate() const;
  // "tcp://127.0.0.1:1502 unit 1" or "rtu:/dev/ttyUSB0 115200 8N1 slave 1".
  std::string describe() const;
};

struct ModbusArmStats {
  std::uint64_t transactions = 0;
  std::uint64_t failures = 0;
  std::uint64_t connects = 0;  // successful (re)connections
};

class ModbusArmClient {
 public:
  // Creates the libmodbus context (does not connect). kInvalidArgument for bad options.
  static Result<std::unique_ptr<ModbusArmClient>> create(const ModbusArmOptions& options);
  ~ModbusArmClient();
  ModbusArmClient(const ModbusArmClient&) = delete;
  ModbusArmClient& operator=(const ModbusArmClient&) = delete;

  // Connects (TCP) or opens the serial port (RTU) and checks MAP_VERSION. kUnavailable when the
  // controller does not answer, kFailedPrecondition for an incompatible register map.
  Status connect();
  void close();
  bool connected() const;

  // One function-16 write of registers 0..13 (see arm_register_map.h). The arm executes it before
  // it answers.
  Status send(const arm::CommandBlock& command);
  // One function-06 write of STOP = 1.
  Status stop();
  // One function-04 read of the 18 input registers.
  Result<arm::StatusBlock> read_status();
  // Reads holding registers (for tests and diagnostics).
  Result<std::vector<std::uint16_t>> read_holding(int address, int count);

  const ModbusArmOptions& options() const { return options_; }
  ModbusArmStats stats() const;

 private:
  explicit ModbusArmClient(ModbusArmOptions options) : options_(std::move(options)) {}
  Status connect_locked();
  Status ensure_connected_locked();
  // Maps errno after a failed libmodbus call to a Status and drops the link if it is gone.
  Status transaction_error_locked(const std::string& what);

  ModbusArmOptions options_;
  mutable std::mutex mutex_;
  _modbus* ctx_ = nullptr;
  bool connected_ = false;
  ModbusArmStats stats_;
};

}  // namespace hc::rig
