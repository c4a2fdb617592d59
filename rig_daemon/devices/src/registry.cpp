#include "rig_daemon/devices/registry.h"

namespace hc::devices {

Status BackendRegistry::add_any(DeviceKind kind, std::string backend, AnyFactory factory,
                                std::string description) {
  if (backend.empty()) return invalid_argument("backend name is empty");
  auto key = std::make_pair(kind, backend);
  if (entries_.count(key))
    return invalid_argument(std::string(to_string(kind)) + " backend '" + backend +
                            "' is already registered");
  entries_.emplace(std::move(key), Entry{std::move(factory), std::move(description)});
  return {};
}

Result<std::unique_ptr<Device>> BackendRegistry::create(DeviceKind kind,
                                                        const DeviceContext& ctx) const {
  auto it = entries_.find(std::make_pair(kind, ctx.backend));
  if (it == entries_.end()) {
    std::string known;
    for (const std::string& b : backends(kind)) known += (known.empty() ? "" : ", ") + b;
    return not_found("device '" + ctx.name + "': unknown " + std::string(to_string(kind)) +
                     " backend '" + ctx.backend + "' (known: " + (known.empty() ? "none" : known) +
                     ")");
  }
  DeviceContext with_clock = ctx;
  if (!with_clock.clock) with_clock.clock = monotonic_clock();
  Result<std::unique_ptr<Device>> made = it->second.factory(with_clock);
  if (!made.ok()) return made.status().with_context("device '" + ctx.name + "'");
  return made;
}

bool BackendRegistry::has(DeviceKind kind, std::string_view backend) const {
  return entries_.count(std::make_pair(kind, std::string(backend))) > 0;
}

std::vector<std::string> BackendRegistry::backends(DeviceKind kind) const {
  std::vector<std::string> out;
  for (const auto& [key, entry] : entries_)
    if (key.first == kind) out.push_back(key.second);
  return out;  // map order = sorted by name within a kind
}

std::string BackendRegistry::description(DeviceKind kind, std::string_view backend) const {
  auto it = entries_.find(std::make_pair(kind, std::string(backend)));
  return it == entries_.end() ? std::string() : it->second.description;
}

}  // namespace hc::devices
