// rigctl — the technician's client for rigd: status, devices, start PLAN.yaml, pause, resume,
// stop, estop, reset (after a safety stop), and a progress display of a running capture (`start
// --wait`, `watch`). Exit codes: 0 done; 1 rigd refused, is unreachable, or the capture did not
// complete; 2 bad usage or a bad plan.
#include <unistd.h>
#include <CLI/CLI.hpp>

#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <string>

#include "common/file_io.h"
#include "common/json.h"
#include "rig_daemon/daemon/control_socket.h"
#include "rig_daemon/daemon/plan.h"
#include "rig_daemon/daemon/rig_config.h"

namespace {

using hc::Json;
using hc::rig::Command;

int report(const hc::Status& s) {
  std::fprintf(stderr, "rigctl: %s\n", s.to_string().c_str());
  return s.code() == hc::StatusCode::kInvalidArgument ? 2 : 1;
}

std::string socket_default() {
  if (const char* env = std::getenv("HARDCOPY_RIGD_SOCKET"); env != nullptr && *env != '\0')
    return env;
  hc::Result<hc::rig::RigConfig> def = hc::rig::embedded_default_rig_config();
  return def.ok() ? hc::rig::default_socket_path(*def).string() : "sessions/rigd.sock";
}

std::string fmt_double(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", digits, v);
  return buf;
}

// One progress line, rewritten in place on a terminal.
void print_progress(const Json& p, bool tty) {
  const std::int64_t done = p.value("done", std::int64_t{0});
  const std::int64_t total = p.value("total", std::int64_t{0});
  const int pct = total > 0 ? static_cast<int>(100 * done / total) : 0;
  std::string line = "[" + p.value("state", std::string("?")) + "] " + std::to_string(done) + "/" +
                     std::to_string(total) + " triggers (" + std::to_string(pct) + "%)  " +
                     p.value("step", std::string()) +
                     "  F=" + fmt_double(p.value("force_n", 0.0), 2) +
                     " N  t=" + fmt_double(p.value("elapsed_s", 0.0), 1) + " s";
  if (tty)
    std::fprintf(stderr, "\r\033[K%s", line.c_str());
  else
    std::fprintf(stderr, "%s\n", line.c_str());
}

void print_summary(const Json& s) {
  std::printf("session   %s\n", s.value("session", std::string("?")).c_str());
  std::printf("state     %s (%s)\n", s.value("state", std::string("?")).c_str(),
              s.value("reason", std::string()).c_str());
  if (s.contains("duration_s"))
    std::printf("duration  %s s\n", fmt_double(s["duration_s"].get<double>(), 2).c_str());
  if (s.contains("association")) {
    const Json& a = s["association"];
    std::printf("triggers  %s edges, %s complete; frames %s/%s associated\n",
                a["edges"].dump().c_str(), a["edges_complete"].dump().c_str(),
                a["frames_associated"].dump().c_str(), a["frames"].dump().c_str());
    if (a.value("edges_with_ft", 0) > 0)
      std::printf("F/T sync  max |error| %s us, mean %s us\n",
                  fmt_double(a["max_abs_ft_error_ns"].get<double>() * 1e-3, 1).c_str(),
                  fmt_double(a["mean_abs_ft_error_ns"].get<double>() * 1e-3, 1).c_str());
  }
  if (s.contains("trip")) std::printf("SAFETY    %s\n", s["trip"].dump().c_str());
  if (s.contains("retract")) std::printf("retract   %s\n", s["retract"].dump().c_str());
  if (s.contains("devices"))
    for (const auto& [name, st] : s["devices"].items())
      std::printf("  %-10s received %s, lost %s, late %s\n", name.c_str(),
                  st["received"].dump().c_str(), st["lost"].dump().c_str(),
                  st["late"].dump().c_str());
}

// Follows events until the session finishes; returns its summary.
hc::Result<Json> follow(hc::rig::ControlClient& client, bool json_out) {
  hc::rig::Request sub;
  sub.command = Command::kSubscribe;
  HC_RETURN_IF_ERROR(client.call(sub).status());
  const bool tty = ::isatty(2) != 0 && !json_out;
  while (true) {
    hc::Result<hc::rig::Reply> ev = client.next_event(3'600'000);
    if (!ev.ok()) return ev.status();
    if (ev->event == "progress") {
      if (!json_out) print_progress(ev->body, tty);
    } else if (ev->event == "safety") {
      if (!json_out)
        std::fprintf(stderr, "\nrigctl: SAFETY STOP: %s\n",
                     ev->body.value("message", std::string()).c_str());
    } else if (ev->event == "finished") {
      if (tty) std::fprintf(stderr, "\n");
      return ev->body;
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"rigctl: control rigd (the Hardcopy capture-rig daemon)"};
  app.require_subcommand(1);
  std::string socket = socket_default();
  app.add_option("--socket", socket, "rigd's control socket (env HARDCOPY_RIGD_SOCKET)")
      ->capture_default_str();
  bool json_out = false;
  auto* status = app.add_subcommand("status", "the daemon's state and the running session");
  status->add_flag("--json", json_out, "one JSON document");
  auto* devices = app.add_subcommand("devices", "every device: kind, backend, state, counters");
  devices->add_flag("--json", json_out, "one JSON document");
  std::string plan_path;
  bool wait = false;
  auto* start = app.add_subcommand("start", "start a capture plan");
  start->add_option("PLAN", plan_path, "plan YAML")->required();
  start->add_flag("--wait", wait, "show progress until the capture ends, then its summary");
  start->add_flag("--json", json_out, "one JSON document");
  app.add_subcommand("pause", "pause the running capture at its next step");
  app.add_subcommand("resume", "resume a paused capture");
  app.add_subcommand("stop", "stop the running capture (the session file is closed cleanly)");
  app.add_subcommand("estop", "emergency stop: halt the arm now and abort the capture");
  app.add_subcommand("reset",
                     "after a safety stop or estop (once the rig is safe): clear the arm's fault "
                     "and devices in error, and allow captures again");
  auto* watch =
      app.add_subcommand("watch", "show the progress of the running capture until it ends");
  watch->add_flag("--json", json_out, "print the final summary as JSON");
  app.add_subcommand("shutdown", "stop rigd");
  CLI11_PARSE(app, argc, argv);

  const std::string cmd = app.get_subcommands().front()->get_name();
  hc::rig::Request req;
  if (cmd == "start") {
    hc::Result<std::string> text = hc::read_file(plan_path, hc::kMaxConfigBytes);
    if (!text.ok()) return report(text.status());
    // Check locally first: the same reader rigd uses, so errors name the user's file.
    hc::Result<hc::rig::Plan> plan = hc::rig::parse_plan(*text, plan_path);
    if (!plan.ok()) return report(plan.status());
    req.command = Command::kStart;
    req.plan = *text;
    req.plan_name = plan_path;
  } else if (cmd == "watch") {
    req.command = Command::kStatus;
  } else {
    req.command = *hc::rig::command_from_string(cmd);
  }

  hc::Result<hc::rig::ControlClient> client = hc::rig::ControlClient::connect(socket);
  if (!client.ok()) return report(client.status());
  hc::Result<Json> result = client->call(req);
  if (!result.ok()) return report(result.status());

  if (cmd == "status") {
    if (json_out) return hc::print_json(*result).ok() ? 0 : 1;
    const Json& r = *result;
    std::printf("rigd %s, state %s, config %s, sessions in %s\n",
                r.value("version", std::string("?")).c_str(),
                r.value("state", std::string("?")).c_str(),
                r.value("config", std::string("?")).c_str(),
                r.value("sessions_dir", std::string("?")).c_str());
    if (r.contains("session") && r.value("state", std::string()) != "idle")
      print_progress(r["session"], false);
    if (r.contains("safety_stop"))
      std::printf("SAFETY STOP (%s: %s): captures are refused until `rigctl reset`\n",
                  r["safety_stop"].value("kind", std::string()).c_str(),
                  r["safety_stop"].value("message", std::string()).c_str());
    if (r.contains("last_session")) {
      std::printf("last session:\n");
      print_summary(r["last_session"]);
    }
    return 0;
  }
  if (cmd == "devices") {
    if (json_out) return hc::print_json(*result).ok() ? 0 : 1;
    std::printf("%-10s %-13s %-8s %-12s %-28s %10s %6s %6s\n", "NAME", "KIND", "BACKEND", "STATE",
                "MODEL", "RECEIVED", "LOST", "LATE");
    for (const Json& d : (*result)["devices"]) {
      std::printf("%-10s %-13s %-8s %-12s %-28s %10s %6s %6s\n",
                  d["name"].get<std::string>().c_str(), d["kind"].get<std::string>().c_str(),
                  d["backend"].get<std::string>().c_str(), d["state"].get<std::string>().c_str(),
                  d["model"].get<std::string>().c_str(), d["stats"]["received"].dump().c_str(),
                  d["stats"]["lost"].dump().c_str(), d["stats"]["late"].dump().c_str());
      if (d.contains("error")) std::printf("  error: %s\n", d["error"].get<std::string>().c_str());
    }
    return 0;
  }
  if (cmd == "start" || cmd == "watch") {
    if (cmd == "start" && !wait) {
      if (json_out) return hc::print_json(*result).ok() ? 0 : 1;
      std::printf("started %s\n", (*result)["session"].get<std::string>().c_str());
      return 0;
    }
    if (cmd == "watch" && result->value("state", std::string("idle")) == "idle") {
      std::fprintf(stderr, "rigctl: no capture is running\n");
      return 1;
    }
    hc::Result<Json> summary = follow(*client, json_out);
    if (!summary.ok()) return report(summary.status());
    if (json_out) {
      if (!hc::print_json(*summary).ok()) return 1;
    } else {
      print_summary(*summary);
    }
    return summary->value("state", std::string()) == "finished" ? 0 : 1;
  }
  if (cmd == "estop" && !json_out) {
    std::printf(
        "estop: arms stopped %s; session aborted: %s; `rigctl reset` once the rig is safe\n",
        (*result)["arms"].dump().c_str(),
        (*result)["session_aborted"].get<bool>() ? "yes" : "no (none running)");
    return 0;
  }
  std::printf("%s: ok\n", cmd.c_str());
  return 0;
}
