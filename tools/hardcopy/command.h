// Shared plumbing of the `hardcopy` subcommands: exit codes, global flags, error printing.
#pragma once

#include <CLI/CLI.hpp>

#include <cmath>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "common/progress.h"
#include "common/status.h"

namespace hc::cli {

// The exit-code contract of every hardcopy subcommand (ARCHITECTURE.md, "Executables").
enum ExitCode : int {
  kExitYes = 0,       // success; the answer is "yes"
  kExitNo = 1,        // the input was read, but the result is "no" (e.g. not printable)
  kExitBadInput = 2,  // unreadable input or bad usage
};

// Options every subcommand shares; filled by main() before a subcommand runs.
struct GlobalOptions {
  bool quiet = false;  // no progress output
};

class Context {
 public:
  explicit Context(const GlobalOptions& global);
  ProgressReporter* progress() const { return progress_.get(); }
  // Prints "hardcopy <command>: <status>" to stderr and returns the exit code it maps to.
  int fail(std::string_view command, const Status& status) const;

 private:
  std::unique_ptr<ProgressReporter> progress_;
};

// Number checks with readable messages ("--probe-radius: must be > 0, got -2"); CLI11's
// PositiveNumber prints its range up to DBL_MAX in full.
inline CLI::Validator zero_bound_check(bool strict) {
  const std::string name = strict ? "POSITIVE" : "NONNEGATIVE";
  return CLI::Validator(
      [strict](std::string& value) -> std::string {
        double v = 0;
        if (!CLI::detail::lexical_cast(value, v) || !std::isfinite(v))
          return "must be a finite number, got " + value;
        const bool ok = strict ? v > 0 : v >= 0;
        return ok ? std::string()
                  : std::string(strict ? "must be > 0" : "must be >= 0") + ", got " + value;
      },
      name, name);
}
inline const CLI::Validator kPositive = zero_bound_check(true);
inline const CLI::Validator kNonNegative = zero_bound_check(false);

// Each family (one file, e.g. mesh_command.cpp) adds its subcommands to the app; a subcommand's
// callback stores its exit code in *exit_code. Families register themselves at
// static-initialisation time: `HC_REGISTER_COMMANDS(add_mesh_commands);` at namespace scope in the
// family's file.
using CommandAdder = void (*)(CLI::App& app, const GlobalOptions& global, int* exit_code);
struct CommandRegistration {
  CommandRegistration(int order, CommandAdder adder);
};
// The registered families sorted by `order` (the order of `hardcopy --help`).
std::vector<CommandAdder> registered_commands();

#define HC_REGISTER_COMMANDS_ORDERED(order, adder) \
  static const ::hc::cli::CommandRegistration hc_command_registration_##adder { order, adder }
#define HC_REGISTER_COMMANDS(adder) HC_REGISTER_COMMANDS_ORDERED(100, adder)

}  // namespace hc::cli
