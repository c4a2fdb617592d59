// A source of session records besides the devices, so that the scheduler sees device interfaces
// and this one interface, never the simulator. The simulated world is one (Rig makes it when a
// device is simulated): its ground truth is a stream it publishes while a session runs, like a
// device's; its opening metadata holds the true cameras and, for a calibration plan, the board
// and its poses; during a calibration it shows the board to the simulated cameras.
#pragma once

#include <cstdint>
#include <memory>
#include <set>
#include <string>

#include "common/status.h"
#include "rig_daemon/daemon/plan.h"
#include "rig_daemon/daemon/recorder.h"

namespace hc::devices::sim {
class World;
}

namespace hc::rig {

class SessionSource {
 public:
  virtual ~SessionSource() = default;
  // Adds the source's channels to `recorder`, which outlives every call below.
  virtual Status add_channels(Recorder& recorder) = 0;
  // Adds to the specimen metadata what the source knows of the specimen.
  virtual void describe_specimen(recording::StringMap& specimen) const = 0;
  // Writes the source's opening metadata for a session of `plan` recording `cameras`.
  virtual Status write_metadata(const Plan& plan, const std::set<std::string>& cameras) = 0;
  // Publishes the source's stream into the recorder until stop().
  virtual void start() = 0;
  // The calibration protocol's first board pose is next (at `now_ns`).
  virtual void begin_calibration(std::int64_t now_ns) = 0;
  // Stops publishing and undoes begin_calibration(); safe to call more than once.
  virtual void stop() = 0;
};

// The simulated world's source (rig_daemon/simulation/sim_world.h).
std::unique_ptr<SessionSource> simulated_world_source(std::shared_ptr<devices::sim::World> world);

}  // namespace hc::rig
