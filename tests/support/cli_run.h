// Runs a command (or the hardcopy tool) through the shell and captures its stdout and exit code:
// the plumbing of every CLI test.
#pragma once

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

#include "test_data.h"

namespace hc::testing {

struct CliRun {
  int exit_code = -1;  // -1 when the command could not be started or did not exit normally
  std::string out;     // everything it wrote to stdout
};

// `cmd` through /bin/sh; append " 2>&1" to capture stderr too.
inline CliRun run_command(const std::string& cmd) {
  CliRun r;
  FILE* p = ::popen(cmd.c_str(), "r");
  if (p == nullptr) return r;
  std::array<char, 4096> buf{};
  std::size_t n;
  while ((n = std::fread(buf.data(), 1, buf.size(), p)) > 0) r.out.append(buf.data(), n);
  const int status = ::pclose(p);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

// `hardcopy --quiet ARGS` from the build's bin directory; stderr is discarded.
inline CliRun hardcopy(const std::string& args) {
  return run_command((bin_dir() / "hardcopy").string() + " --quiet " + args + " 2>/dev/null");
}

}  // namespace hc::testing
