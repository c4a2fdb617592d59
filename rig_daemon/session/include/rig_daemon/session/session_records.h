// The session's own records (topics.h says on which channel), as the daemon writes them and the
// offline rooms read them back through the codecs (codec.h) and read_session_records
// (session_reader.h):
//  * SyncRecord on /session/sync: one per rising trigger edge, the frames and force samples the
//    scheduler associated with it;
//  * StepRecord on /session/steps: the protocol's step markers;
//  * EventRecord on /session/events: safety trips, pauses, device errors, log lines;
//  * GroundTruthRecord on /sim/ground_truth: what a simulated rig really did at one frame time.
// SI units; world-frame positions in metres.
#pragma once

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "rig_daemon/session/records.h"

namespace hc::session {

struct SyncRecord {
  std::uint64_t trigger_index = 0;
  std::int64_t edge_host_ns = 0;                // host monotonic ns of the rising edge
  bool complete = false;                        // every camera delivered its frame
  std::map<std::string, std::uint64_t> frames;  // camera -> frame index
  std::vector<std::string> missing_cameras;
  // The F/T sample nearest the edge, when there is one.
  std::optional<std::uint64_t> ft_sequence;
  std::int64_t ft_error_ns = 0;        // F/T sample host time - edge host time
  std::array<double, 3> force_n{};     // Fx Fy Fz, sensor frame
  // The FSR sample of the edge, when there is one.
  std::optional<std::uint64_t> fsr_sequence;
  std::int64_t fsr_error_ns = 0;
  std::uint32_t fsr_raw = 0;
  double fsr_force_n = 0.0;
};

// One protocol step: the automated press (location, level, step, forces, depth, pose) or a
// calibration board pose (board_pose); trigger_indices are the edges fired for it.
struct StepRecord {
  std::int64_t host_ns = 0;
  int step = 0;
  std::vector<std::uint64_t> trigger_indices;
  std::optional<int> location;
  std::optional<int> level;
  std::optional<double> target_force_n;
  std::optional<double> force_n;
  std::optional<double> depth_m;
  std::optional<ArmPose> pose;
  std::optional<int> board_pose;  // calibration: index of the board pose
};

// A session event. Safety trips also carry when they were detected and the stop sent, and an
// over-force trip the sample that tripped it.
struct EventRecord {
  std::int64_t host_ns = 0;
  std::string kind;
  std::string message;
  std::optional<std::int64_t> detected_ns;
  std::optional<std::int64_t> stop_sent_ns;
  std::optional<std::int64_t> sample_host_ns;
  std::optional<double> force_n;
  std::optional<std::int64_t> latency_ns;
};

// What a simulated rig really did at one frame time (devices' sim::GroundTruth as recorded).
struct GroundTruthRecord {
  struct Camera {
    std::vector<std::uint32_t> occluded;     // marker indices hidden by the probe
    std::vector<std::uint32_t> out_of_view;  // marker indices not wholly in the image
    bool board_visible = false;
  };
  // A calibration board while shown: x_world = R x_board + t.
  struct Board {
    int pose_index = 0;
    int cols = 0;
    int rows = 0;
    double square_m = 0.0;
    Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
    Eigen::Vector3d t_m = Eigen::Vector3d::Zero();
  };

  std::int64_t host_ns = 0;
  std::optional<std::uint64_t> trigger_index;
  ArmPose probe;               // tool tip = lowest point of the probe sphere
  double indentation_m = 0.0;  // <= 0: no contact
  double force_n = 0.0;        // true contact force
  std::vector<Eigen::Vector3d> markers_m;  // deformed marker centres (empty while a board shows)
  Eigen::Vector3d probe_tip_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d probe_axis = Eigen::Vector3d::UnitZ();  // unit, from the tip up the shaft
  double probe_radius_m = 0.0;
  bool probe_shown = true;
  std::array<Eigen::Vector3d, 2> shaft_markers_m{};  // nearer the tip first
  double shaft_marker_radius_m = 0.0;
  std::map<std::string, Camera> cameras;
  std::optional<Board> board;
};

}  // namespace hc::session
