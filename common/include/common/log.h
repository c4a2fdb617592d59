// Logging through spdlog, one named logger per module ("mesh", "fem", "rig", ...), all to stderr.
// Levels come from the environment: HARDCOPY_LOG="warn" sets every module, and
// HARDCOPY_LOG="info,mesh=debug,rig=trace" sets a default plus per-module levels.
#pragma once

#include <spdlog/spdlog.h>

#include <memory>
#include <string_view>

#include "common/status.h"

namespace hc::log {

inline constexpr const char* kEnvVar = "HARDCOPY_LOG";

// The logger for `module`, created on first use with the level the spec gives it.
std::shared_ptr<spdlog::logger> get(std::string_view module);

// Applies a level spec (the HARDCOPY_LOG syntax above) to existing and future loggers.
// Unknown level names give kInvalidArgument naming the bad entry; nothing is changed then.
Status configure(std::string_view spec);

// configure(getenv(HARDCOPY_LOG)) if set; otherwise leaves the default level ("info").
Status configure_from_env();

// Sends every module's output, from existing and future loggers, to `sink` (with the Hardcopy
// pattern: time, level, module) instead of stderr; nullptr restores stderr. Tests capture log
// output this way, and a daemon can route its log lines into a recording.
void set_sink(spdlog::sink_ptr sink);

}  // namespace hc::log
