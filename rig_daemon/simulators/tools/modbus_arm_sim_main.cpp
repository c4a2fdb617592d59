// hardcopy-modbus-arm-sim: runs the Modbus TCP arm simulator (register map of
// rig_daemon/backends/arm_register_map.h) on a loopback address until SIGINT/SIGTERM. Prints
// "modbus_port N" on stdout (port 0 = OS-chosen).
#include <CLI/CLI.hpp>
#include <csignal>
#include <iostream>
#include <thread>

#include "rig_daemon/simulators/modbus_arm_server.h"

namespace {
volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) { g_stop = 1; }
}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Modbus TCP 4-DOF arm simulator"};
  hc::rig::sim::ModbusArmServerOptions o;
  app.add_option("--address", o.address, "IPv4 address to bind")->capture_default_str();
  app.add_option("--port", o.port, "TCP port (0: OS-chosen; 502 needs privileges)")
      ->capture_default_str();
  app.add_option("--speed", o.speed_m_s, "initial Cartesian speed limit, m/s")
      ->capture_default_str();
  app.add_option("--home-speed", o.home_speed_m_s, "homing speed, m/s")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  auto server = hc::rig::sim::ModbusArmServer::start(o);
  if (!server.ok()) {
    std::cerr << "hardcopy-modbus-arm-sim: " << server.status().to_string() << "\n";
    return 2;
  }
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  std::cout << "modbus_port " << (*server)->port() << std::endl;
  while (!g_stop) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  const auto s = (*server)->stats();
  std::cout << "requests " << s.requests << "\ncommands " << s.commands << std::endl;
  return 0;
}
