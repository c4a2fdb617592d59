#include "common/log.h"

#include <fmt/format.h>
#include <spdlog/sinks/dist_sink.h>
#include <spdlog/sinks/stdout_color_sinks.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cstdlib>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace hc::log {
namespace {

// Date and milliseconds because the rig daemon runs for hours and its logs are compared with
// recorded sample stamps; the module name because every room logs to the same stream.
constexpr const char* kPattern = "[%Y-%m-%d %H:%M:%S.%e] [%^%l%$] [%n] %v";
constexpr spdlog::level::level_enum kDefaultLevel = spdlog::level::info;

struct LevelName {
  std::string_view name;
  spdlog::level::level_enum level;
};
// spdlog's own names, plus "warning" because spdlog prints that name in every log line.
constexpr std::array<LevelName, 8> kLevels{{
    {"trace", spdlog::level::trace},
    {"debug", spdlog::level::debug},
    {"info", spdlog::level::info},
    {"warn", spdlog::level::warn},
    {"warning", spdlog::level::warn},
    {"error", spdlog::level::err},
    {"critical", spdlog::level::critical},
    {"off", spdlog::level::off},
}};
constexpr const char* kValidLevels = "trace, debug, info, warn, error, critical, off";

struct LevelSpec {
  spdlog::level::level_enum default_level = kDefaultLevel;
  std::map<std::string, spdlog::level::level_enum, std::less<>> modules;

  spdlog::level::level_enum level_for(std::string_view module) const {
    const auto it = modules.find(module);
    return it == modules.end() ? default_level : it->second;
  }
};

std::string_view trim(std::string_view s) {
  const auto is_space = [](char c) { return std::isspace(static_cast<unsigned char>(c)) != 0; };
  while (!s.empty() && is_space(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_space(s.back())) s.remove_suffix(1);
  return s;
}

std::optional<spdlog::level::level_enum> level_from_name(std::string_view name) {
  std::string lower(name);
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  for (const auto& [n, level] : kLevels)
    if (n == lower) return level;
  return std::nullopt;
}

// Parses the whole spec before anything is applied, so a typo leaves the current levels intact.
Result<LevelSpec> parse_spec(std::string_view spec) {
  LevelSpec out;
  std::size_t start = 0;
  while (start <= spec.size()) {
    const std::size_t comma = std::min(spec.find(',', start), spec.size());
    const std::string_view entry = trim(spec.substr(start, comma - start));
    start = comma + 1;
    if (entry.empty()) continue;  // "info," or ",," are harmless
    const std::size_t eq = entry.find('=');
    if (eq == std::string_view::npos) {
      const auto level = level_from_name(entry);
      if (!level)
        return invalid_argument(fmt::format("{} entry '{}': unknown level (valid levels: {})",
                                            kEnvVar, entry, kValidLevels));
      out.default_level = *level;
      continue;
    }
    const std::string_view module = trim(entry.substr(0, eq));
    const std::string_view level_name = trim(entry.substr(eq + 1));
    if (module.empty())
      return invalid_argument(
          fmt::format("{} entry '{}': missing module name before '='", kEnvVar, entry));
    const auto level = level_from_name(level_name);
    if (!level)
      return invalid_argument(fmt::format("{} entry '{}': unknown level '{}' (valid levels: {})",
                                          kEnvVar, entry, level_name, kValidLevels));
    out.modules[std::string(module)] = *level;
  }
  return out;
}

std::shared_ptr<spdlog::sinks::sink> make_stderr_sink() {
  auto sink = std::make_shared<spdlog::sinks::stderr_color_sink_mt>();
  sink->set_pattern(kPattern);
  return sink;
}

class Registry {
 public:
  Registry() : sink_(std::make_shared<spdlog::sinks::dist_sink_mt>()) {
    sink_->set_sinks({make_stderr_sink()});
  }

  std::shared_ptr<spdlog::logger> get(std::string_view module) {
    std::lock_guard lock(mutex_);
    const auto it = loggers_.find(module);
    if (it != loggers_.end()) return it->second;
    auto logger = std::make_shared<spdlog::logger>(std::string(module), sink_);
    logger->set_level(spec_.level_for(module));
    // Warnings and errors reach a file sink at once, in case the process dies right after.
    logger->flush_on(spdlog::level::warn);
    loggers_.emplace(std::string(module), logger);
    return logger;
  }

  void apply(LevelSpec spec) {
    std::lock_guard lock(mutex_);
    spec_ = std::move(spec);
    for (auto& [name, logger] : loggers_) logger->set_level(spec_.level_for(name));
  }

  // The loggers all hold the one distributing sink, so swapping its target is safe while other
  // threads log (dist_sink locks around both).
  void set_sink(spdlog::sink_ptr sink) {
    if (!sink) {
      sink = make_stderr_sink();
    } else {
      sink->set_pattern(kPattern);
    }
    sink_->set_sinks({std::move(sink)});
  }

 private:
  std::mutex mutex_;
  std::shared_ptr<spdlog::sinks::dist_sink_mt> sink_;
  LevelSpec spec_;
  std::map<std::string, std::shared_ptr<spdlog::logger>, std::less<>> loggers_;
};

Registry& registry() {
  // Never destroyed: code running in static destructors (or detached threads at exit) may still
  // log, and must not find the registry gone.
  static Registry* const instance = new Registry();
  return *instance;
}

}  // namespace

std::shared_ptr<spdlog::logger> get(std::string_view module) { return registry().get(module); }

Status configure(std::string_view spec) {
  HC_ASSIGN_OR_RETURN(LevelSpec parsed, parse_spec(spec));
  registry().apply(std::move(parsed));
  return {};
}

Status configure_from_env() {
  const char* spec = std::getenv(kEnvVar);
  if (spec == nullptr) return {};
  return configure(spec);
}

void set_sink(spdlog::sink_ptr sink) { registry().set_sink(std::move(sink)); }

}  // namespace hc::log
