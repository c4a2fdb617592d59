// Figures of a recorded session (rigd's MCAP): the force–displacement curve of every probe location
// of an automated plan, from the session's step markers (/session/steps: location, level, step, the
// probe's depth along the press direction from the location's start point, the force measured
// there; rig_daemon/session/topics.h), and the session's headline numbers.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "common/status.h"
#include "figures/figure.h"

namespace hc::figures {

struct SessionStepPoint {
  int location = 0, level = 0, step = 0;
  double depth_m = 0;  // probe travel from the location's start point along the press direction
  double force_n = 0;  // measured force magnitude at the step (F/T, averaged by rigd)
  double target_force_n = 0;
  std::int64_t host_ns = 0;
};

struct SessionCurves {
  std::string plan;
  std::vector<std::array<double, 3>> locations_m;  // the plan's probe start points (when recorded)
  std::vector<SessionStepPoint> steps;             // in recording order
};

// Reads the step markers of an automated session. kInvalidArgument when the file is not a session
// MCAP, a step record is malformed (naming it), or the session has no automated-press steps.
Result<SessionCurves> read_session_curves(const std::filesystem::path& session);

// Per location a chart (one series per force level) and one chart of every location's last level;
// numbers: state, plan, duration, messages, steps, locations, peak force.
Result<FigureSet> session_figures(const std::filesystem::path& session);

}  // namespace hc::figures
