// hardcopy — the offline toolkit: git-style subcommands over the Hardcopy libraries.
#include <fmt/format.h>

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
  add_mesh_commands(app, global, &exit_code);
  add_demo_command(app, global, &exit_code);

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
