// Shared plumbing of the `hardcopy` subcommands: exit codes, global flags, error printing.
#pragma once

#include <CLI/CLI.hpp>
#include <memory>
#include <string_view>

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

// Each family registers its subcommands; a subcommand's callback stores its exit code in
// *exit_code.
void add_mesh_commands(CLI::App& app, const GlobalOptions& global, int* exit_code);
void add_demo_command(CLI::App& app, const GlobalOptions& global, int* exit_code);

}  // namespace hc::cli
