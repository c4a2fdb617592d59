// The simulated world shared by every simulated device ("sim" backends): a virtual specimen, a
// probe on a virtual 4-DOF arm, a trigger timeline that simulated cameras and FSRs follow, seeded
// noise and drift, injectable faults, and ground truth on a separate channel.
//
// Everything is a function of time on the world's Clock: the arm's pose is evaluated from the
// commands it received and their times, forces from the pose, trigger edges from the pulse trains.
// With a SimulatedClock the whole world is deterministic; each device draws noise from its own
// generator seeded with (world seed, device name), so interleaving reads of several devices does
// not change any device's samples. Thread-safe.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/config.h"
#include "common/status.h"
#include "rig_daemon/devices/clock.h"
#include "rig_daemon/devices/types.h"
#include "rig_daemon/session/session_records.h"
#include "rig_daemon/simulation/hyperelastic_specimen.h"
#include "rig_daemon/simulation/sim_dots.h"
#include "rig_daemon/simulation/sim_scene.h"
#include "rig_daemon/simulation/specimen.h"

namespace hc::devices::sim {

struct WorldOptions {
  std::uint64_t seed = 1;
  double probe_radius_m = 0.005;  // spherical probe tip
  ArmLimits arm_limits;
  ArmPose home{0.0, 0.0, 0.15, 0.0};
  double arm_speed_m_s = 0.02;  // initial Cartesian speed
  double arm_yaw_speed_rad_s = 1.0;
  HertzSpecimen::Options specimen;  // the analytic specimen (when no other Specimen is given)
  // "hertz" (analytic) or "hyperelastic" (FEM, processing/hyperelastic; hyperelastic_specimen.h).
  std::string specimen_model = "hertz";
  HyperelasticSpecimenOptions hyperelastic;  // shares the specimen keys; see read()
  ProbeLook probe;                           // how the cameras see the probe (sim_scene.h)

  // Keys: seed, probe_radius_m, home_m [x, y, z], arm_speed_m_s, workspace_min_m, workspace_max_m,
  // max_speed_m_s, specimen {model: hertz|hyperelastic, youngs_modulus_pa, poisson_ratio,
  // stiffening, top_z_m, center_m, size_m, marker_spacing_m, marker_radius_m; hyperelastic only:
  // height_m, layers, max_depth_m, depth_steps, material_layers [{thickness_m, youngs_modulus_pa,
  // poisson_ratio, stiffening}, ...] bottom first}, probe {visible, shaft_radius_m, shaft_length_m,
  // marker_distances_m, marker_radius_m, grey, marker_grey} (sim_scene.h ProbeLook).
  Status read(ConfigNode node);
  Status validate() const;
};

// An injected fault, active for host time [start_ns, end_ns) on the named device ("" = every
// simulated device).
struct Fault {
  enum class Kind : std::uint8_t {
    kStall,       // the device stops delivering (its counters keep running: a gap = lost items);
                  // the arm freezes and reports ArmMotion::kFault
    kDropout,     // each item is lost with `probability` (seeded)
    kSpike,       // force devices add `magnitude` N to the true force
    kDelay,       // items arrive `magnitude` s late (counted as late past the backend's bound)
    kDisconnect,  // reads/writes fail with kUnavailable; reset() fails until end_ns
  };
  Kind kind = Kind::kStall;
  std::string device;
  std::int64_t start_ns = 0;
  std::int64_t end_ns = INT64_MAX;
  double probability = 1.0;
  double magnitude = 0.0;
};
std::string_view to_string(Fault::Kind kind);

// A calibration board shown to the cameras (World::show_board): while it is shown the specimen
// and the probe are not rendered (a calibration capture has no specimen). A frame with a trigger
// index k shows poses[(k - first_trigger_index) mod N]; a frame without one (free-run or software
// triggered cameras) poses[floor((t - start_ns) / dwell_ns) mod N].
struct BoardShow {
  BoardSpec spec;
  std::vector<BoardPose> poses;
  std::uint64_t first_trigger_index = 0;
  std::int64_t start_ns = 0;
  std::int64_t dwell_ns = 500'000'000;
};

// What one camera sees of the specimen's markers at an instant (indices into markers_m).
struct CameraTruth {
  std::string camera;
  // Markers the probe hides at least partly: the ray from the camera centre to the marker centre
  // meets the probe (every part grown by the marker's radius plus 1.5 px at the marker's depth)
  // in front of the marker. Conservative: no probe pixel touches any other marker's dot.
  std::vector<std::uint32_t> occluded;
  // Markers whose dot is not entirely inside the image (or behind the camera).
  std::vector<std::uint32_t> out_of_view;
  bool board_visible = false;  // whole board in view and facing the camera (board_visible())
};

// The truth behind one instant (a frame's exposure start, or any time asked for).
//
// Recorded on the session's /sim/ground_truth channel as session::GroundTruthRecord
// (rig_daemon/session/session_records.h; board frame as in sim_scene.h).
struct GroundTruth {
  std::int64_t host_ns = 0;
  std::optional<std::uint64_t> trigger_index;
  ArmPose probe;                           // tool tip = lowest point of the probe sphere
  double indentation_m = 0.0;              // <= 0: no contact
  double force_n = 0.0;                    // true contact force (no noise, drift or fault)
  std::vector<Eigen::Vector3d> markers_m;  // deformed marker centres, world frame (empty while a
                                           // board is shown)
  ProbeGeometry probe_geometry;            // tip, axis, shaft markers
  bool probe_shown = true;                 // rendered (probe.visible and no board shown)
  std::optional<std::size_t> board_pose_index;  // set while a board is shown
  BoardSpec board_spec;
  BoardPose board_pose;
  std::vector<CameraTruth> cameras;  // every registered camera, in registration order

  // As recorded on /sim/ground_truth.
  session::GroundTruthRecord record() const;
};

// A simulated camera as the world knows it (for occlusion truth and the session's metadata).
struct CameraRecord {
  std::string name;
  CameraModel camera;
};

class World {
 public:
  // `specimen` null: the specimen options.specimen_model names (a hyperelastic one that cannot be
  // built falls back to the Hertz specimen; specimen_status() says why). Check
  // options.validate() first.
  World(WorldOptions options, std::shared_ptr<Clock> clock,
        std::shared_ptr<const Specimen> specimen = nullptr);

  const WorldOptions& options() const { return options_; }
  Clock& clock() const { return *clock_; }
  const std::shared_ptr<Clock>& clock_ptr() const { return clock_; }
  const Specimen& specimen() const { return *specimen_; }
  // OK, or why the configured specimen model could not be built.
  const Status& specimen_status() const { return specimen_status_; }
  // Seed for a device's own generator: a hash of the world seed and the device name.
  std::uint64_t device_seed(std::string_view device) const;

  // ---- Arm and probe ----
  // Applies a command at time t_ns. kFailedPrecondition for a move before homing or while the arm
  // is in fault; kInvalidArgument for a target outside the limits or a speed <= 0 or above max.
  Status arm_command(const ArmCommand& command, std::int64_t t_ns);
  void arm_stop(std::int64_t t_ns);
  ArmState arm_state(std::int64_t t_ns);
  ArmPose probe_pose(std::int64_t t_ns);

  // ---- Contact ----
  Indentation indentation(std::int64_t t_ns);
  double true_force_n(std::int64_t t_ns);
  // `per_camera`: also fill GroundTruth::cameras (occlusion per registered camera).
  GroundTruth ground_truth(std::int64_t t_ns, std::optional<std::uint64_t> trigger_index = {},
                           bool per_camera = true);
  // Called (from the thread of the device that rendered it) with the truth of every distinct
  // frame time, once per time even when several cameras render it. Must not call back into the
  // world. Set before devices are active.
  void set_ground_truth_callback(std::function<void(const GroundTruth&)> callback);
  // Simulated cameras call this for every frame they render; it runs the callback once per time.
  void publish_ground_truth(std::int64_t t_ns, std::optional<std::uint64_t> trigger_index);

  // ---- Scene: cameras and calibration board ----
  // Simulated cameras register their true calibration when configured (a name registered again
  // replaces the earlier record).
  void register_camera(const std::string& name, const CameraModel& camera);
  std::vector<CameraRecord> cameras() const;
  void show_board(BoardShow board);
  void hide_board();
  std::optional<BoardShow> board() const;
  // The board pose index a frame at t_ns with `trigger_index` shows, or nullopt (no board).
  std::optional<std::size_t> board_pose_index(std::int64_t t_ns,
                                              std::optional<std::uint64_t> trigger_index) const;

  // ---- Trigger timeline (driven by the simulated trigger; followed by hardware-triggered
  // simulated cameras and triggered FSRs) ----
  Status trigger_start(const PulseTrain& train, std::int64_t t_ns);
  void trigger_stop(std::int64_t t_ns);
  Status trigger_fire(double pulse_width_s, std::int64_t t_ns);
  bool trigger_running(std::int64_t t_ns) const;
  // Time of the rising edge of pulse `index` if it has happened by t_ns.
  std::optional<std::int64_t> rising_edge_ns(std::uint64_t index, std::int64_t t_ns) const;
  std::int64_t pulse_width_ns(std::uint64_t index) const;
  // Pulses fired by t_ns.
  std::uint64_t pulses_by(std::int64_t t_ns) const;

  // ---- Faults ----
  void inject(Fault fault);
  void clear_faults();
  // The active fault of `kind` on `device` at t_ns (the first injected), if any.
  std::optional<Fault> fault(std::string_view device, Fault::Kind kind, std::int64_t t_ns) const;

 private:
  struct Segment {  // one arm motion
    std::int64_t start_ns = 0;
    ArmPose from, to;
    std::int64_t duration_ns = 0;
    bool homing = false;
    bool stopped = false;
  };
  struct Program {  // one pulse train (or a single pulse)
    std::int64_t start_ns = 0;
    std::int64_t period_ns = 0;
    std::int64_t width_ns = 0;
    std::uint64_t count = 0;  // 0 = until stop
    std::int64_t stop_ns = INT64_MAX;
    std::uint64_t first_index = 0;
  };
  ArmPose pose_at_locked(std::int64_t t_ns) const;
  std::uint64_t program_pulses_by(const Program& p, std::int64_t t_ns) const;
  const Program* program_of(std::uint64_t index) const;

  WorldOptions options_;
  std::shared_ptr<Clock> clock_;
  std::shared_ptr<const Specimen> specimen_;
  Status specimen_status_;
  mutable std::mutex mutex_;
  Segment segment_;
  bool homed_ = false;
  std::int64_t homed_ns_ = INT64_MAX;  // when the homing segment ends
  double speed_m_s_;
  std::uint64_t command_sequence_ = 0;
  std::uint64_t state_sequence_ = 0;
  std::vector<Program> programs_;
  std::vector<Fault> faults_;
  std::function<void(const GroundTruth&)> truth_callback_;
  std::vector<CameraRecord> cameras_;
  std::optional<BoardShow> board_;
  std::int64_t last_truth_ns_ = INT64_MIN;
};

}  // namespace hc::devices::sim
