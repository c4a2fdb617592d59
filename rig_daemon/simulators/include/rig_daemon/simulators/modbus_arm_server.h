// A Modbus TCP arm controller simulator (libmodbus server) on a loopback address, implementing the
// register map of rig_daemon/backends/arm_register_map.h with a virtual 4-DOF arm that moves at
// finite speed (straight lines at the commanded Cartesian speed, yaw at its own speed), homes,
// stops, reports faults (workspace, speed, unknown command, not homed, injected following error /
// emergency stop), and can disappear (all connections dropped, port closed) and come back on the
// same port, for reconnect tests. One thread; public methods are thread-safe.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "common/status.h"
#include "rig_daemon/backends/arm_register_map.h"

namespace hc::rig::sim {

struct ArmPoseSi {
  double x_m = 0, y_m = 0, z_m = 0, yaw_rad = 0;
};

struct ModbusArmServerOptions {
  std::string address = "127.0.0.1";
  std::uint16_t port = 0;                        // 0: the OS picks one (see port())
  ArmPoseSi start_pose{0.05, -0.02, 0.15, 0.0};  // where the arm is at power-up (not homed)
  ArmPoseSi home_pose{0.0, 0.0, 0.25, 0.0};
  ArmPoseSi workspace_min{-0.2, -0.2, 0.0, -3.14159265358979};
  ArmPoseSi workspace_max{0.2, 0.2, 0.3, 3.14159265358979};
  double speed_m_s = 0.05;      // initial Cartesian speed limit
  double max_speed_m_s = 0.25;  // SPEED above this is fault 2
  double yaw_speed_rad_s = 1.0;
  double home_speed_m_s = 0.1;
  double cycle_s = 0.002;  // control cycle (position update, HEARTBEAT + 1)

  Status validate() const;
};

struct ModbusArmServerStats {
  std::uint64_t requests = 0;     // Modbus requests answered
  std::uint64_t connections = 0;  // accepted
  std::uint64_t commands = 0;     // COMMAND_SEQ changes executed
  std::uint64_t stops = 0;
};

class ModbusArmServer {
 public:
  // Listens and starts the thread. kIoError if the port cannot be bound.
  static Result<std::unique_ptr<ModbusArmServer>> start(ModbusArmServerOptions options);
  ~ModbusArmServer();
  ModbusArmServer(const ModbusArmServer&) = delete;
  ModbusArmServer& operator=(const ModbusArmServer&) = delete;

  std::uint16_t port() const { return port_; }
  // Drops every connection and closes the port (the arm itself keeps its state and stops moving,
  // as a controller whose network link went down would after its watchdog).
  void disappear();
  // Listens again on the same port. kIoError if it cannot be bound.
  Status reappear();
  bool online() const;

  // Latches a fault (e.g. Fault::kFollowingError): the arm stops, MOTION 5.
  void inject_fault(arm::Fault fault);
  // The arm's state as the input registers would report it now.
  arm::StatusBlock status() const;
  ModbusArmServerStats stats() const;

 private:
  explicit ModbusArmServer(ModbusArmServerOptions options);
  Status listen_locked();
  void run();
  void step(double dt_s);
  void execute(const arm::CommandBlock& command);
  void publish_locked();  // state -> input registers
  void close_all_locked();

  ModbusArmServerOptions options_;
  std::uint16_t port_ = 0;
  std::thread thread_;
  std::atomic<bool> quit_{false};
  int wake_fd_[2] = {-1, -1};

  mutable std::mutex mutex_;  // guards everything below
  void* ctx_ = nullptr;       // modbus_t*
  void* mapping_ = nullptr;   // modbus_mapping_t*
  int listen_fd_ = -1;
  std::vector<int> clients_;
  // disappear() asks the server thread to close the sockets: closing a socket another thread is
  // blocked in select() on keeps it listening until select() returns.
  bool offline_request_ = false;
  bool thread_running_ = false;
  std::condition_variable offline_cv_;
  bool online_ = false;
  ArmPoseSi pose_;
  ArmPoseSi target_;
  double speed_m_s_;
  double yaw_speed_rad_s_;
  arm::Motion motion_ = arm::Motion::kIdle;
  std::uint16_t fault_ = 0;
  bool homed_ = false;
  std::uint16_t ack_sequence_ = 0;
  std::uint16_t heartbeat_ = 0;
  std::int64_t epoch_ns_ = 0;
  ModbusArmServerStats stats_;
};

}  // namespace hc::rig::sim
