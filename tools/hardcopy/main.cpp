// hardcopy — the offline toolkit: git-style subcommands over the Hardcopy libraries.
#include <fmt/format.h>

#include <algorithm>
#include <utility>

#include <CLI/CLI.hpp>

#include "command.h"
#include "common/log.h"

namespace hc::cli {

Context::Context(const GlobalOptions& global)
    : progress_(
          make_console_progress(global.quiet ? ProgressStyle::kQuiet : ProgressStyle::kAuto)) {}

int Context::fail(std::string_view command, const Status& status) const {
  fmt::print(stderr, "hardcopy {}: {}\n", command, status.to_string());
  switch (status.code()) {
    case StatusCode::kFailedPrecondition:
      return kExitNo;
    default:
      return kExitBadInput;
  }
}

namespace {
std::vector<std::pair<int, CommandAdder>>& registry() {
  static std::vector<std::pair<int, CommandAdder>> adders;
  return adders;
}
}  // namespace

CommandRegistration::CommandRegistration(int order, CommandAdder adder) {
  registry().emplace_back(order, adder);
}

std::vector<CommandAdder> registered_commands() {
  auto entries = registry();
  std::stable_sort(entries.begin(), entries.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<CommandAdder> adders;
  for (const auto& [order, adder] : entries) adders.push_back(adder);
  return adders;
}

}  // namespace hc::cli

int main(int argc, char** argv) {
  using namespace hc::cli;
  if (hc::Status s = hc::log::configure_from_env(); !s.ok())
    fmt::print(stderr, "hardcopy: ignoring {}: {}\n", hc::log::kEnvVar, s.message());

  CLI::App app{"hardcopy — computational 3D manufacturing toolkit"};
  app.set_version_flag("--version", "hardcopy " HARDCOPY_VERSION);
  app.require_subcommand(1);
  GlobalOptions global;
  app.add_flag("-q,--quiet", global.quiet, "Print no progress");
  int exit_code = kExitYes;
  for (CommandAdder add : registered_commands()) add(app, global, &exit_code);

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);  // prints the message and the usage hint
    return kExitBadInput;
  }
  return exit_code;
}
