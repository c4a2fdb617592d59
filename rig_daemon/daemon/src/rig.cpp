#include "rig_daemon/daemon/rig.h"

#include <optional>

#include "rig_daemon/backends/hardware_backends.h"
#include "rig_daemon/simulation/sim_backends.h"

namespace hc::rig {

Json stats_json(const devices::DeviceStats& s) {
  return Json{{"received", s.received},     {"lost", s.lost},     {"late", s.late},
              {"incomplete", s.incomplete}, {"errors", s.errors}, {"last_host_ns", s.last_host_ns}};
}

Result<std::unique_ptr<Rig>> Rig::create(Options options) {
  std::unique_ptr<Rig> rig(new Rig());
  rig->config_ = std::move(options.config);
  rig->clock_ = options.clock ? options.clock : devices::monotonic_clock();
  HC_RETURN_IF_ERROR(register_hardware_backends(rig->registry_));
  if (options.replay) {
    rig->replay_ = options.replay;
    HC_RETURN_IF_ERROR(devices::register_replay_backends(rig->registry_, rig->replay_));
    rig->config_.devices.clear();
    for (const devices::ReplaySession::Stream& s : rig->replay_->streams()) {
      if (rig->config_.find(s.device) != nullptr) continue;  // one device per name
      devices::DeviceContext ctx;
      ctx.name = s.device;
      ctx.backend = "replay";
      ctx.clock = rig->clock_;
      HC_ASSIGN_OR_RETURN(std::unique_ptr<devices::Device> d, rig->registry_.create(s.kind, ctx));
      HC_RETURN_IF_ERROR(devices::configure_from_yaml(*d, "", "replay of " + s.device));
      rig->config_.devices.push_back(DeviceConfig{s.device, s.kind, "replay"});
      rig->devices_.push_back(std::move(d));
    }
    if (rig->devices_.empty())
      return invalid_argument("the replayed session has no device streams");
    return rig;
  }
  if (!rig->config_.document) return internal_error("rig config has no parsed document");

  bool any_sim = false;
  for (const DeviceConfig& d : rig->config_.devices) any_sim = any_sim || d.backend == "sim";

  // Second pass over the document: the world's options, then each device's own map, read by its
  // backend (unknown keys are reported by read_config, naming file, line and key).
  std::vector<Status> device_errors;
  Status read = read_config(*rig->config_.document, [&](ConfigNode root) {
    root.allow_unknown_keys();
    devices::sim::WorldOptions world_options;
    world_options.seed = rig->config_.seed;
    if (std::optional<ConfigNode> w = root.find("world")) w->get(world_options);
    if (!root.status().ok()) return root.status();
    // The simulated world exists when a device is simulated; the "sim" backends and the firmware
    // board's simulated ADC get it at registration, the devices never see it.
    devices::SimulatedBoardInput board;
    if (any_sim) {
      rig->world_ = std::make_shared<devices::sim::World>(world_options, rig->clock_);
      HC_RETURN_IF_ERROR(devices::register_sim_backends(rig->registry_, rig->world_));
      board = devices::sim::board_input(rig->world_);
    }
    HC_RETURN_IF_ERROR(devices::register_firmware_backends(rig->registry_, std::move(board)));
    std::optional<ConfigNode> devs = root.find("devices");
    if (!devs) return root.status();
    auto entries = devs->entries();
    if (!entries) return root.status();
    for (auto& [name, node] : *entries) {
      const DeviceConfig* cfg = rig->config_.find(name);
      if (cfg == nullptr) continue;
      devices::DeviceContext ctx;
      ctx.name = name;
      ctx.backend = cfg->backend;
      ctx.clock = rig->clock_;
      Result<std::unique_ptr<devices::Device>> made = rig->registry_.create(cfg->kind, ctx);
      if (!made.ok()) {
        node.error("backend", made.status().message());
        continue;
      }
      std::string ignored;
      node.optional("kind", ignored);
      node.optional("backend", ignored);
      Status configured = (*made)->configure(node);
      if (!configured.ok()) {
        // Config-reading errors are already recorded at their line; others (a device that
        // refuses) are reported with the device's name.
        if (node.status().ok())
          device_errors.push_back(configured.with_context("device '" + name + "'"));
        continue;
      }
      rig->devices_.push_back(std::move(made).value());
    }
    return root.status();
  });
  HC_RETURN_IF_ERROR(read);
  for (const Status& s : device_errors) return s;
  return rig;
}

Rig::~Rig() {
  for (auto& d : devices_) {
    if (d->state() == devices::DeviceState::kActive || d->state() == devices::DeviceState::kError)
      (void)d->deactivate();
  }
}

devices::Device* Rig::find(std::string_view name) const {
  for (const auto& d : devices_)
    if (d->name() == name) return d.get();
  return nullptr;
}

Json Rig::devices_json() const {
  Json out = Json::array();
  for (const auto& d : devices_) {
    const devices::DeviceInfo info = d->info();
    Json details = Json::object();
    for (const auto& [k, v] : info.details) details[k] = v;
    Json j{{"name", info.name},       {"kind", devices::to_string(info.kind)},
           {"backend", info.backend}, {"state", devices::to_string(info.state)},
           {"model", info.model},     {"serial", info.serial},
           {"details", details},      {"stats", stats_json(d->stats())}};
    if (Status e = d->error(); !e.ok()) j["error"] = e.message();
    out.push_back(std::move(j));
  }
  return out;
}

}  // namespace hc::rig
