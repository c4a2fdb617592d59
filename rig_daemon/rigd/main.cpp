// rigd — the rig daemon. `rigd` alone runs the embedded default rig (every device simulated,
// sessions under ./sessions/); `rigd --config RIG.yaml` a real one; `rigd --replay S.mcap` serves a
// recorded session's streams through the same device interfaces. It serves the control protocol
// on a Unix socket (owner-only) and the live page over HTTP (127.0.0.1:7878 unless --http or the
// config say otherwise; --no-http: none) until SIGINT/SIGTERM or a `shutdown` request. The page
// controls the rig only with the token rigd writes next to the control socket (rigd.token, 0600).
#include <signal.h>
#include <CLI/CLI.hpp>

#include <atomic>
#include <cstdio>
#include <iostream>
#include <memory>

#include "common/log.h"
#include "rig_daemon/daemon/control_socket.h"
#include "rig_daemon/daemon/daemon.h"
#include "rig_daemon/daemon/http_server.h"
#include "rig_daemon/daemon/rig_config.h"

namespace {

int fail(const hc::Status& s, int code) {
  std::fprintf(stderr, "rigd: %s\n", s.to_string().c_str());
  return code;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"rigd: the Hardcopy capture-rig daemon (control it with rigctl)"};
  std::string config_path, replay_path, socket_path, sessions_dir;
  bool simulated_time = false;
  double replay_speed = 1.0;
  app.add_option("--config", config_path,
                 "rig config YAML (default: the embedded, all-simulated rig)")
      ->check(CLI::ExistingFile);
  app.add_option("--replay", replay_path,
                 "serve the streams of a recorded session through the same device interfaces");
  app.add_option("--replay-speed", replay_speed, "replay pacing: 10 = ten times real time")
      ->check(CLI::PositiveNumber);
  app.add_option("--socket", socket_path, "control socket path (default: from the config)");
  app.add_option("--sessions-dir", sessions_dir,
                 "where sessions are written (default: from the config)");
  std::string http_listen;
  bool no_http = false;
  CLI::Option* http_opt = app.add_option(
      "--http", http_listen,
      "serve the live page on ADDR:PORT (default: the config's http.listen, 127.0.0.1:7878; "
      "port 0 picks a free one)");
  app.add_flag("--no-http", no_http, "do not serve the live page")->excludes(http_opt);
  app.add_flag("--simulated-time", simulated_time,
               "run simulated devices on simulated time, as fast as the CPU allows (tests)");
  app.set_version_flag("--version", std::string("rigd ") + HARDCOPY_VERSION);
  CLI11_PARSE(app, argc, argv);
  (void)hc::log::configure_from_env();

  hc::Result<hc::rig::RigConfig> config = config_path.empty()
                                              ? hc::rig::embedded_default_rig_config()
                                              : hc::rig::load_rig_config(config_path);
  if (!config.ok()) return fail(config.status(), 2);
  if (!sessions_dir.empty()) config->sessions_dir = sessions_dir;
  if (!socket_path.empty()) config->socket = socket_path;
  // Signals are taken synchronously by the main thread (sigwait), so block them before any
  // thread starts.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  std::atomic<bool> shutdown{false};
  std::shared_ptr<hc::rig::ControlServer> server_ref;  // set once serving
  std::mutex server_mutex;
  hc::rig::Daemon::Options options;
  options.config = *config;
  options.software_version = HARDCOPY_VERSION;
  options.replay = replay_path;
  options.replay_speed = replay_speed;
  if (simulated_time) options.clock = std::make_shared<hc::devices::SimulatedClock>();
  options.on_event = [&](std::string_view event, const hc::Json& fields) {
    std::lock_guard lock(server_mutex);
    if (server_ref) server_ref->broadcast(event, fields);
  };
  options.on_shutdown = [&] {
    shutdown = true;
    ::kill(::getpid(), SIGTERM);  // wakes the sigwait below
  };
  hc::Result<std::unique_ptr<hc::rig::Daemon>> daemon = hc::rig::Daemon::create(options);
  if (!daemon.ok()) return fail(daemon.status(), 2);

  const std::filesystem::path sock = hc::rig::default_socket_path(*config);
  hc::Result<std::unique_ptr<hc::rig::ControlServer>> server = hc::rig::ControlServer::start(
      sock,
      [&](const hc::rig::Request& r, hc::Status& error) { return (*daemon)->handle(r, error); });
  if (!server.ok()) return fail(server.status(), 1);
  {
    std::lock_guard lock(server_mutex);
    server_ref = std::move(server).value();
  }
  // The live page. A port given on the command line must be served; the default one may be taken
  // (another rigd on this machine), which only costs the page.
  std::unique_ptr<hc::rig::HttpServer> http;
  std::filesystem::path token_path;
  const auto stop_serving = [&](const hc::Status& s, int code) {
    {
      std::lock_guard lock(server_mutex);
      server_ref.reset();
    }
    std::error_code ec;
    if (!token_path.empty()) std::filesystem::remove(token_path, ec);
    return fail(s, code);
  };
  if (!no_http && (config->http.enabled || !http_listen.empty())) {
    hc::rig::HttpOptions ho;
    ho.allow_remote = config->http.allow_remote;
    const std::string listen = http_listen.empty() ? config->http.listen : http_listen;
    if (hc::Status s = hc::rig::parse_listen_address(listen, ho); !s.ok())
      return stop_serving(s.with_context("--http"), 2);
    hc::Result<std::string> token = hc::rig::make_token();
    if (!token.ok()) return stop_serving(token.status(), 1);
    ho.token = *token;
    if (hc::Status s = ho.validate(); !s.ok()) return stop_serving(s, 2);
    token_path = sock.parent_path() / "rigd.token";
    if (hc::Status s = hc::rig::write_token_file(token_path, *token); !s.ok()) {
      token_path.clear();
      return stop_serving(s, 1);
    }
    hc::Result<std::unique_ptr<hc::rig::HttpServer>> started =
        hc::rig::HttpServer::start(**daemon, ho);
    if (started.ok()) {
      http = std::move(started).value();
      std::fprintf(stderr, "rigd: live page %s?token=%s (token also in %s)\n", http->url().c_str(),
                   token->c_str(), token_path.c_str());
    } else if (!http_listen.empty()) {
      return stop_serving(started.status(), 1);
    } else {
      std::fprintf(stderr, "rigd: no live page: %s\n", started.status().message().c_str());
      std::error_code ec;
      std::filesystem::remove(token_path, ec);
      token_path.clear();
    }
  }
  std::fprintf(stderr, "rigd %s: %s rig (%s), sessions in %s, control socket %s\n",
               HARDCOPY_VERSION,
               !replay_path.empty()  ? "replayed"
               : config_path.empty() ? "embedded default"
                                     : "configured",
               config->source_name.c_str(), config->sessions_dir.c_str(), sock.c_str());
  std::fflush(stderr);

  int sig = 0;
  sigwait(&signals, &sig);
  std::fprintf(stderr, "rigd: %s, stopping\n", shutdown ? "shutdown requested" : strsignal(sig));
  http.reset();  // the page's threads read the daemon: they end first
  if (!token_path.empty()) {
    std::error_code ec;
    std::filesystem::remove(token_path, ec);
  }
  (void)(*daemon)->stop();
  (*daemon)->wait_idle(30000);
  {
    std::lock_guard lock(server_mutex);
    server_ref.reset();
  }
  daemon->reset();
  return 0;
}
