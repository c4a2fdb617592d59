#include "rig_daemon/daemon/daemon.h"

#include <chrono>
#include <ctime>

#include "rig_daemon/devices/arm.h"

namespace hc::rig {

namespace {

// Clears an arm's fault (activating it for the purpose when a session left it inactive). The arm
// does not move.
Status clear_arm_fault(devices::Arm& arm, Json& report) {
  const bool was_inactive = arm.state() == devices::DeviceState::kInactive;
  if (was_inactive) HC_RETURN_IF_ERROR(arm.activate());
  Status status;
  Result<devices::ArmState> st = arm.read();
  if (st.ok() && st->motion == devices::ArmMotion::kFault) {
    devices::ArmCommand clear;
    clear.type = devices::ArmCommand::Type::kClearFault;
    status = arm.write(clear);
    if (status.ok()) st = arm.read();
    if (status.ok() && st.ok() && st->motion == devices::ArmMotion::kFault)
      status =
          failed_precondition("arm '" + arm.name() + "' is still in fault after clear_fault (" +
                              st->fault + "); the safety stop stays");
    report.push_back(Json{{"device", arm.name()}, {"action", "clear_fault"}, {"ok", status.ok()}});
  }
  if (!st.ok() && status.ok()) status = st.status();
  if (was_inactive) (void)arm.deactivate();
  return status;
}

}  // namespace

Result<std::unique_ptr<Daemon>> Daemon::create(Options options) {
  std::unique_ptr<Daemon> d(new Daemon(std::move(options)));
  Rig::Options ro{d->options_.config, d->options_.clock, nullptr};
  if (!d->options_.replay.empty()) {
    devices::ReplaySession::Options rso;
    rso.speed = d->options_.replay_speed;
    HC_ASSIGN_OR_RETURN(ro.replay, devices::ReplaySession::open(d->options_.replay, rso));
  }
  HC_ASSIGN_OR_RETURN(d->rig_, Rig::create(ro));
  std::error_code ec;
  std::filesystem::create_directories(d->options_.config.sessions_dir, ec);
  if (ec)
    return io_error("cannot create the sessions directory " +
                    d->options_.config.sessions_dir.string() + ": " + ec.message());
  return d;
}

Daemon::~Daemon() {
  {
    std::lock_guard lock(mutex_);
    if (session_) session_->stop();
  }
  if (thread_.joinable()) thread_.join();
}

std::filesystem::path Daemon::next_session_path(const Plan& plan) const {
  // <sessions_dir>/<plan>-<UTC time>[-N].mcap: sortable, never overwriting an earlier session.
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char stamp[32];
  std::strftime(stamp, sizeof(stamp), "%Y%m%dT%H%M%SZ", &tm);
  const std::filesystem::path dir = options_.config.sessions_dir;
  std::filesystem::path p = dir / (plan.name + "-" + stamp + ".mcap");
  for (int i = 2; std::filesystem::exists(p); ++i)
    p = dir / (plan.name + "-" + stamp + "-" + std::to_string(i) + ".mcap");
  return p;
}

Result<Json> Daemon::start(const Plan& plan) {
  std::lock_guard lock(mutex_);
  if (running_)
    return failed_precondition("a session is already running (" +
                               std::string(to_string(session_->state())) + "); stop it first");
  if (!safety_stop_.is_null())
    return failed_precondition(
        "the rig is in a safety stop (" + safety_stop_.value("kind", std::string()) + ": " +
        safety_stop_.value("message", std::string()) + "); make it safe, then `rigctl reset`");
  HC_RETURN_IF_ERROR(Session::validate(*rig_, plan));
  if (thread_.joinable()) thread_.join();
  SessionOptions so;
  so.path = next_session_path(plan);
  so.plan = plan;
  so.software_version = options_.software_version;
  so.on_event = options_.on_event;
  so.recorder.compression = options_.config.compression == "lz4"    ? recording::Compression::kLz4
                            : options_.config.compression == "none" ? recording::Compression::kNone
                                                                    : recording::Compression::kZstd;
  const std::filesystem::path path = so.path;
  session_ = std::make_unique<Session>(*rig_, std::move(so));
  running_ = true;
  ++sessions_started_;
  thread_ = std::thread([this, s = session_.get()] {
    Result<Json> summary = s->run();
    std::lock_guard l(mutex_);
    if (summary.ok()) {
      last_summary_ = *summary;
      if (summary->contains("trip"))
        safety_stop_ = Json{{"kind", (*summary)["trip"].value("kind", std::string())},
                            {"message", (*summary)["trip"].value("message", std::string())},
                            {"session", summary->value("session", std::string())}};
    } else {
      last_summary_ = Json{{"state", "failed"}, {"reason", summary.status().message()}};
      if (options_.on_event) options_.on_event("finished", last_summary_);
    }
    running_ = false;
    idle_cv_.notify_all();
  });
  return Json{{"session", path.string()}, {"expected_triggers", plan.expected_triggers()}};
}

Status Daemon::pause() {
  std::lock_guard lock(mutex_);
  if (!running_) return failed_precondition("no session is running");
  session_->pause();
  return {};
}

Status Daemon::resume() {
  std::lock_guard lock(mutex_);
  if (!running_) return failed_precondition("no session is running");
  session_->resume();
  return {};
}

Status Daemon::stop() {
  std::lock_guard lock(mutex_);
  if (!running_) return failed_precondition("no session is running");
  session_->stop();
  return {};
}

Json Daemon::estop() {
  // Stop every arm first, without waiting for any lock a busy session might hold for long.
  Json stopped = Json::array();
  for (const auto& d : rig_->devices()) {
    if (d->kind() != DeviceKind::kArm) continue;
    Status s = static_cast<devices::Arm*>(d.get())->stop();
    stopped.push_back(Json{{"device", d->name()}, {"ok", s.ok()}, {"message", s.message()}});
  }
  std::lock_guard lock(mutex_);
  if (running_) session_->estop();
  safety_stop_ = Json{{"kind", "estop"}, {"message", "emergency stop requested"}};
  return Json{{"arms", stopped}, {"session_aborted", running_}};
}

Result<Json> Daemon::reset() {
  std::lock_guard lock(mutex_);
  if (running_) return failed_precondition("a session is running; stop it first");
  Json actions = Json::array();
  for (const auto& d : rig_->devices()) {
    if (d->state() != devices::DeviceState::kError) continue;
    const Status s = d->reset();
    actions.push_back(Json{{"device", d->name()}, {"action", "reset"}, {"ok", s.ok()}});
    if (!s.ok())
      return Status(s.code(), "device '" + d->name() + "' stays in error: " + s.message() +
                                  "; the safety stop stays");
  }
  if (options_.replay.empty()) {  // a replayed arm takes no commands
    for (const auto& d : rig_->devices()) {
      if (d->kind() != DeviceKind::kArm) continue;
      HC_RETURN_IF_ERROR(clear_arm_fault(*static_cast<devices::Arm*>(d.get()), actions));
    }
  }
  Json cleared = std::move(safety_stop_);
  safety_stop_ = nullptr;
  return Json{{"cleared", cleared}, {"actions", actions}};
}

Json Daemon::safety_stop() const {
  std::lock_guard lock(mutex_);
  return safety_stop_;
}

bool Daemon::wait_idle(int timeout_ms) {
  std::unique_lock lock(mutex_);
  return idle_cv_.wait_for(lock, std::chrono::milliseconds(timeout_ms), [&] { return !running_; });
}

Json Daemon::last_summary() const {
  std::lock_guard lock(mutex_);
  return last_summary_;
}

Json Daemon::status() const {
  std::lock_guard lock(mutex_);
  Json j{{"daemon", "rigd"},
         {"version", options_.software_version},
         {"protocol_version", kControlProtocolVersion},
         {"config", options_.config.source_name},
         {"replay", options_.replay.string()},
         {"sessions_dir", options_.config.sessions_dir.string()},
         {"sessions_started", sessions_started_},
         {"state", running_ ? std::string(to_string(session_->state())) : std::string("idle")}};
  if (session_) j["session"] = session_->progress();
  if (!last_summary_.is_null()) j["last_session"] = last_summary_;
  if (!safety_stop_.is_null()) j["safety_stop"] = safety_stop_;
  return j;
}

Json Daemon::devices() const { return rig_->devices_json(); }

Json Daemon::handle(const Request& request, Status& error) {
  switch (request.command) {
    case Command::kStatus:
      return status();
    case Command::kDevices:
      return Json{{"devices", devices()}};
    case Command::kStart: {
      Result<Plan> plan = parse_plan(request.plan, request.plan_name);
      if (!plan.ok()) {
        error = plan.status();
        return {};
      }
      Result<Json> started = start(*plan);
      if (!started.ok()) {
        error = started.status();
        return {};
      }
      return *started;
    }
    case Command::kPause:
      error = pause();
      return Json{{"state", "pausing"}};
    case Command::kResume:
      error = resume();
      return Json{{"state", "running"}};
    case Command::kStop:
      error = stop();
      return Json{{"state", "stopping"}};
    case Command::kEstop:
      return estop();
    case Command::kReset: {
      Result<Json> r = reset();
      if (!r.ok()) {
        error = r.status();
        return {};
      }
      return *r;
    }
    case Command::kSubscribe:
      return Json{{"subscribed", true}};
    case Command::kShutdown:
      if (options_.on_shutdown) options_.on_shutdown();
      return Json{{"shutting_down", true}};
  }
  error = internal_error("unhandled command");
  return {};
}

}  // namespace hc::rig
