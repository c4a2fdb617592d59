// hardcopy-netft-sim: runs the Net F/T RDT simulator on a loopback address until SIGINT/SIGTERM,
// so a rigd configured with the "netft" backend can be tried without a sensor. Prints
// "rdt_port N" and "http_port N" on stdout (port 0 = OS-chosen).
#include <CLI/CLI.hpp>
#include <cmath>
#include <csignal>
#include <iostream>
#include <numbers>
#include <thread>

#include "rig_daemon/simulators/rdt_server.h"

namespace {
volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) { g_stop = 1; }
}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Net F/T RDT simulator (UDP) with netftapi2.xml over HTTP"};
  hc::rig::sim::RdtServerOptions o;
  double fz_n = 0.0, amplitude_n = 0.0, frequency_hz = 1.0, drop = 0.0;
  app.add_option("--address", o.address, "IPv4 address to bind")->capture_default_str();
  app.add_option("--port", o.port, "UDP port (0: OS-chosen)")->capture_default_str();
  app.add_option("--http-port", o.http_port, "TCP port of netftapi2.xml (0: OS-chosen)");
  app.add_option("--rate", o.output_rate_hz, "records per second (<= 7000)")->capture_default_str();
  app.add_option("--counts-per-force", o.calibration.counts_per_force)->capture_default_str();
  app.add_option("--counts-per-torque", o.calibration.counts_per_torque)->capture_default_str();
  app.add_option("--fz", fz_n, "constant Fz in N")->capture_default_str();
  app.add_option("--amplitude", amplitude_n, "sine amplitude added to Fz, N");
  app.add_option("--frequency", frequency_hz, "sine frequency, Hz")->capture_default_str();
  app.add_option("--drop", drop, "probability of dropping each packet");
  CLI11_PARSE(app, argc, argv);
  o.signal = [=](double t) {
    hc::rig::rdt::Wrench w;
    w.force_n[2] = fz_n + amplitude_n * std::sin(2 * std::numbers::pi * frequency_hz * t);
    return w;
  };
  auto server = hc::rig::sim::RdtServer::start(o);
  if (!server.ok()) {
    std::cerr << "hardcopy-netft-sim: " << server.status().to_string() << "\n";
    return 2;
  }
  if (drop > 0)
    (*server)->set_faults(
        {.stalled = false, .drop_probability = drop, .reorder = false, .status_word = 0});
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  std::cout << "rdt_port " << (*server)->port() << "\nhttp_port " << (*server)->http_port()
            << std::endl;
  while (!g_stop) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  const auto s = (*server)->stats();
  std::cout << "records_sent " << s.records_sent << "\npackets_dropped " << s.packets_dropped
            << std::endl;
  return 0;
}
