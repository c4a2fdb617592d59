// The live page's cost to the capture: rigd (embedded default, every device simulated, real time)
// runs the same automated press without the page (--no-http) and with 5 event-stream clients plus
// one fetching camera thumbnails like the page does; alternating runs, medians reported.
//
//   bench_live_page [--runs N] [--clients K]     (default 2 runs per mode, 5 clients)
//
// Reported per mode: the control cycle's period and busy time (p50 / p99 / max, from the session
// summary's "cycle"), rigd's CPU time (utime + stime from /proc) and its share of the wall time,
// and with the page, how far each pushed snapshot lags the newest recorded force sample when the
// client receives it (CLOCK_MONOTONIC on both sides: same machine). The issue's bars: page updates
// <= 100 ms behind the recorder, rigd's CPU <= 5 % more with the page open, cycle timing the same.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "common/json.h"
#include "rig_daemon/daemon/control_socket.h"
#include "test_data.h"
// After Eigen (through common/json.h): httplib.h includes <resolv.h>, whose `_res` macro breaks
// Eigen's headers when they come later.
#include <httplib.h>

namespace {

using hc::Json;

constexpr const char* kPlan = R"(protocol: automated
name: bench_live
locations:
  - {position_m: [0.0, 0.0, 0.062], direction: [0, 0, -1]}
  - {position_m: [0.015, 0.0, 0.062], direction: [0, 0, -1]}
force_levels_n: [25]
steps: 40
settle_s: 0.05
max_force_n: 40
workspace: {min_m: [-0.05, -0.05, 0.0], max_m: [0.05, 0.05, 0.12]}
cameras: [cam0, cam1, cam2, cam3, cam4, cam5, cam6]
)";

std::int64_t monotonic_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

double cpu_seconds(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // Fields after the ")" that ends the command name: state is field 3, utime 14, stime 15.
  std::istringstream rest(text.substr(text.rfind(')') + 2));
  std::string f;
  std::vector<std::string> fields;
  while (rest >> f) fields.push_back(f);
  const double ticks = static_cast<double>(::sysconf(_SC_CLK_TCK));
  return (std::stod(fields[11]) + std::stod(fields[12])) / ticks;
}

// Linear interpolation between order statistics (the median of two values is their mean).
double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const double pos = q * static_cast<double>(v.size() - 1);
  const auto i = static_cast<std::size_t>(pos);
  if (i + 1 >= v.size()) return v.back();
  return v[i] + (pos - static_cast<double>(i)) * (v[i + 1] - v[i]);
}

struct Run {
  double wall_s = 0, cpu_s = 0;
  Json cycle;
  std::vector<double> lag_ms;
  std::size_t events = 0;
  std::string state;
};

Run run_once(bool page, int clients) {
  hc::testing::ScratchDir dir;
  const std::string sock = (dir / "rigd.sock").string();
  const std::string log = (dir / "rigd.log").string();
  const pid_t pid = ::fork();
  if (pid == 0) {
    if (std::freopen(log.c_str(), "w", stderr) == nullptr) ::_exit(126);
    const std::string rigd = (hc::testing::bin_dir() / "rigd").string();
    const std::string sessions = (dir / "sessions").string();
    if (page)
      ::execl(rigd.c_str(), rigd.c_str(), "--sessions-dir", sessions.c_str(), "--socket",
              sock.c_str(), "--http", "127.0.0.1:0", static_cast<char*>(nullptr));
    else
      ::execl(rigd.c_str(), rigd.c_str(), "--sessions-dir", sessions.c_str(), "--socket",
              sock.c_str(), "--no-http", static_cast<char*>(nullptr));
    ::_exit(127);
  }
  Run run;
  int port = 0;
  for (int i = 0; i < 400; ++i) {
    std::ifstream in(log);
    std::stringstream ss;
    ss << in.rdbuf();
    std::smatch m;
    const std::string text = ss.str();
    if (text.find("control socket") != std::string::npos) {
      if (std::regex_search(text, m, std::regex(R"(http://127\.0\.0\.1:(\d+)/)"))) port = std::stoi(m[1]);
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  std::atomic<bool> stop{false};
  std::vector<std::thread> threads;
  std::mutex lag_mutex;
  if (page && port > 0) {
    for (int k = 0; k < clients; ++k)
      threads.emplace_back([&] {
        httplib::Client c("127.0.0.1", port);
        c.set_read_timeout(5, 0);
        std::string buf;
        c.Get("/api/events", [&](const char* d, std::size_t n) {
          buf.append(d, n);
          std::size_t end;
          while ((end = buf.find("\n\n")) != std::string::npos) {
            const std::string block = buf.substr(0, end);
            buf.erase(0, end + 2);
            if (block.rfind("data: ", 0) != 0) continue;
            const std::int64_t now = monotonic_ns();
            const Json j = Json::parse(block.substr(6), nullptr, false);
            std::lock_guard lock(lag_mutex);
            ++run.events;
            if (j.contains("force") && !j["force"].empty())
              run.lag_ms.push_back(double(now - j["force"].back()[0].get<std::int64_t>()) * 1e-6);
          }
          return !stop.load();
        });
      });
    threads.emplace_back([&] {  // the page's thumbnails and session list
      httplib::Client c("127.0.0.1", port);
      for (int i = 0; !stop.load(); ++i) {
        (void)c.Get("/api/frames/cam0.png");
        if (i % 10 == 0) (void)c.Get("/api/sessions");
        std::this_thread::sleep_for(std::chrono::milliseconds(500));
      }
    });
  }
  auto client = hc::rig::ControlClient::connect(sock);
  if (!client.ok()) {
    std::fprintf(stderr, "bench_live_page: %s\n", client.status().to_string().c_str());
    ::kill(pid, SIGKILL);
    ::waitpid(pid, nullptr, 0);
    std::exit(1);
  }
  const double cpu0 = cpu_seconds(pid);
  const auto t0 = std::chrono::steady_clock::now();
  hc::rig::Request start;
  start.command = hc::rig::Command::kStart;
  start.plan = kPlan;
  start.plan_name = "bench_live.yaml";
  if (auto r = client->call(start); !r.ok()) {
    std::fprintf(stderr, "bench_live_page: start: %s\n", r.status().to_string().c_str());
    std::exit(1);
  }
  Json status;
  for (int i = 0; i < 6000; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    auto s = client->call(hc::rig::Request{0, hc::rig::Command::kStatus, "", ""});
    if (s.ok() && (*s)["state"] == "idle" && s->contains("last_session")) {
      status = *s;
      break;
    }
  }
  run.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  run.cpu_s = cpu_seconds(pid) - cpu0;
  run.cycle = status["last_session"].value("cycle", Json::object());
  run.state = status["last_session"].value("state", std::string("?"));
  stop = true;
  ::kill(pid, SIGTERM);
  for (auto& t : threads) t.join();
  ::waitpid(pid, nullptr, 0);
  return run;
}

}  // namespace

int main(int argc, char** argv) {
  int runs = 2, clients = 5;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--runs") runs = std::stoi(argv[i + 1]);
    if (a == "--clients") clients = std::stoi(argv[i + 1]);
  }
  std::vector<Run> without, with;
  for (int r = 0; r < runs; ++r) {
    without.push_back(run_once(false, clients));
    with.push_back(run_once(true, clients));
    std::fprintf(stderr, "run %d: without %.1f s cpu %.2f s (%s); with %.1f s cpu %.2f s (%s)\n",
                 r + 1, without.back().wall_s, without.back().cpu_s, without.back().state.c_str(),
                 with.back().wall_s, with.back().cpu_s, with.back().state.c_str());
  }
  const auto med = [](const std::vector<Run>& v, auto f) {
    std::vector<double> x;
    for (const Run& r : v) x.push_back(f(r));
    return quantile(x, 0.5);
  };
  const auto cyc = [](const char* what, const char* q) {
    return [=](const Run& r) {
      return r.cycle.contains(what) ? r.cycle[what][q].get<double>() * 1e-3 : 0.0;
    };
  };
  std::printf("bench_live_page: automated press, 7 cameras, real time; %d run(s) per mode, %d event clients\n",
              runs, clients);
  std::printf("%-26s %14s %14s %8s\n", "", "no page", "page + clients", "ratio");
  const auto row = [&](const char* name, auto f) {
    const double a = med(without, f), b = med(with, f);
    std::printf("%-26s %14.2f %14.2f %8.3f\n", name, a, b, a > 0 ? b / a : 0.0);
  };
  row("cycle period p50 (us)", cyc("period_ns", "p50"));
  row("cycle period p99 (us)", cyc("period_ns", "p99"));
  row("cycle period max (us)", cyc("period_ns", "max"));
  row("cycle busy p50 (us)", cyc("busy_ns", "p50"));
  row("cycle busy p99 (us)", cyc("busy_ns", "p99"));
  row("rigd CPU (s)", [](const Run& r) { return r.cpu_s; });
  row("rigd CPU (% of wall)", [](const Run& r) { return 100.0 * r.cpu_s / r.wall_s; });
  row("capture wall time (s)", [](const Run& r) { return r.wall_s; });
  std::vector<double> lag;
  std::size_t events = 0;
  double wall = 0;
  for (const Run& r : with) {
    lag.insert(lag.end(), r.lag_ms.begin(), r.lag_ms.end());
    events += r.events;
    wall += r.wall_s;
  }
  std::printf("page lag behind the newest force sample: p50 %.1f ms, p95 %.1f ms, max %.1f ms (%zu snapshots)\n",
              quantile(lag, 0.5), quantile(lag, 0.95), quantile(lag, 1.0), lag.size());
  std::printf("snapshots per client per second: %.1f\n",
              wall > 0 ? double(events) / clients / wall : 0.0);
  return 0;
}
