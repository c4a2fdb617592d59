// From a recorded session to force-displacement samples (`hardcopy track`): marker detection in
// every camera frame of every deformation step, tracking through the steps, registration to the
// template mesh, occlusion filling, forces from the F/T channel (thesis Sec. 4.4.2, 5.6).
//
// The template is a TetGen tet mesh (.node/.ele) of the specimen in the world frame (the frame of
// RigCalibration::world_from_rig; for a simulated rig the world frame of the rig config). Its
// surface nodes at the painted markers are the measured nodes: every tracked marker is registered
// to the template node nearest to it after a rigid ICP (Horn's closed form per iteration) of the
// first step's markers onto the template nodes, starting from world_from_rig; markers with no node
// within `template_match_distance_m` (e.g. the probe's shaft markers) are not part of the output.
// A node is "visible" in an example when its marker was triangulated in that step; all other
// nodes (occluded markers, interior and unpainted nodes) get positions from a smooth deformation
// (3-D biharmonic RBF of the measured displacements) constrained by the probe sphere: its cap
// over the Hertz contact patch (radius sqrt(R d) at indentation d) and every filled point that
// would lie inside it are put on the sphere, and visible = 0.
//
// The probe's pose per step comes from its two shaft markers (thesis 4.4: "two markers on the
// white shaft"): dots several times larger than the specimen's are shaft-marker candidates,
// matched and triangulated across the cameras; the tip is marker 0 minus its distance from the
// tip along the shaft axis (distances from the session's rig config or SessionTrackOptions).
// Steps where they are not both seen fall back to the arm's reported pose (counted).
//
// Session layout read (rig_daemon/session/topics.h): /<camera>/image (foxglove.RawImage
// mono8 or rgb8), /session/sync (trigger index, edge time, F/T force), /session/steps (one per
// deformation step: trigger_indices, pose of the probe tip, location/level/step), and on simulated
// rigs /sim/ground_truth (markers_m per trigger index). Without /session/steps every sync record
// is a step. A step's frame from a camera is the frame logged between the step's trigger edge and
// the next edge.
//
// Forces: the F/T sample associated with the step's trigger (SyncRecord force_n, sensor axes =
// world axes) is the force on the probe; the specimen receives its negative, distributed over the
// template nodes under the probe sphere (weights = how far each node is inside the sphere grown
// by contact_tolerance_m), or all on the node nearest the tip when none is. Fixed nodes: the
// template's bottom (min z within fixed_tolerance_m).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "camera/camera_model.h"
#include "common/progress.h"
#include "common/status.h"
#include "common/tet_mesh.h"
#include "processing/markers/dots.h"
#include "processing/material/samples.h"
#include "processing/tracking/tracker.h"

namespace hc::tracking {

// One deformation step as the session records it.
struct SessionStep {
  std::uint64_t trigger_index = 0;
  std::int64_t edge_host_ns = 0;
  int location = -1, level = -1, step = -1;              // -1: not an automated-plan step
  Eigen::Vector3d ft_force_n = Eigen::Vector3d::Zero();  // F/T reading (force on the probe)
  bool has_force = false;
  std::optional<Eigen::Vector3d> probe_tip_m;    // world frame, from the step's pose
  FrameDetections detections;                    // [camera in calibration order][dot]
  FrameDetections shaft_detections;              // probe shaft-marker candidates, same layout
  std::vector<int> frames_found;                 // per camera: 1 when a frame was found
  std::vector<Eigen::Vector3d> truth_markers_m;  // /sim/ground_truth markers_m (world); empty: none
  // /sim/ground_truth cameras.NAME.occluded, in calibration camera order (empty when absent).
  std::vector<std::vector<std::uint32_t>> truth_occluded;
  // /sim/ground_truth probe_tip_m, probe_axis and shaft_markers_m (world), when present.
  std::optional<Eigen::Vector3d> truth_probe_tip_m;
  std::optional<Eigen::Vector3d> truth_probe_axis;
  std::vector<Eigen::Vector3d> truth_shaft_markers_m;
};

// Wall-clock seconds per stage, except detection_s: frames are detected on worker threads while
// the next ones are decoded, so it is the sum of the per-frame detection times (CPU-seconds).
struct StageTimes {
  double decode_s = 0;        // reading + decompressing + decoding frames (and the JSON channels):
                              // this thread's time, detection overlapping it
  double detection_s = 0;     // dot detection, summed over frames
  double frames_s = 0;        // wall time of the whole frame pass (decode + detection)
  double matching_s = 0;      // correspondences, association and triangulation
  double registration_s = 0;  // ICP, node assignment, filling, forces
  double total_s = 0;
};

struct SessionDetections {
  std::vector<CameraModel> cameras;  // calibration order, only cameras of the session
  std::vector<SessionStep> steps;
  bool has_truth = false;
  // The probe's shaft-marker distances from the tip along the shaft (m; nearer the tip first) as
  // the session's rig config gives them: world.probe.marker_distances_m of a simulated rig, else
  // the simulator's default probe (0.06, 0.11) when the rig is simulated (a `world` section or a
  // `backend: sim` device); unset for other rigs (SessionTrackOptions can give them).
  std::optional<std::array<double, 2>> shaft_marker_distances_m;
  // The probe's tip sphere radius (m) from the session's rig config: world.probe_radius_m of a
  // simulated rig, the simulator's default 5 mm when it has none; unset for other rigs.
  std::optional<double> probe_radius_m;
  StageTimes times;
};

// The probe's geometry from a session's rig config (its rig_config metadata, YAML): for a
// simulated rig (a `world` section or a `backend: sim` device) world.probe_radius_m and
// world.probe.marker_distances_m, each defaulting to the simulator's (5 mm; 0.06, 0.11 m) when
// absent or invalid; for other rigs unset. Read leniently: a rig config the daemon accepted is not
// re-validated; unreadable YAML gives nothing.
struct RigProbe {
  std::optional<std::array<double, 2>> shaft_marker_distances_m;
  std::optional<double> radius_m;
};
RigProbe probe_of_rig_config(const std::string& yaml);

struct SessionReadOptions {
  markers::BlobOptions blobs;
  // Coloured dots (thesis 4.4.2: per-colour thresholds in CIE Lab) instead of the blob detector:
  // detect_color_dots with these options on every frame (frames must be rgb8); the shaft markers
  // (painted in a dot colour too) are split off as above, by color->max_area_px.
  std::optional<markers::ColorDotOptions> color;
  // The probe's shaft markers are balls several times wider than the specimen's dots: a dot whose
  // area exceeds blobs.max_area_px (up to shaft_marker_max_area_px), or shaft_marker_area_ratio
  // times the median dot area of its frame (frames with >= 10 dots), goes to
  // SessionStep::shaft_detections instead of the specimen's detections.
  double shaft_marker_area_ratio = 6.0;
  double shaft_marker_max_area_px = 60000.0;
  std::size_t max_steps = 0;             // 0: all
  int threads = 0;                       // detection threads (0: TBB's default)
  ProgressReporter* progress = nullptr;  // frames detected (null: none)
};

// Reads a session's steps and detects the dots of every step frame. Errors (kInvalidArgument):
// unreadable file, no camera channel, a session camera missing from the calibration or a
// calibration camera missing from the session, image sizes that differ from the calibration, no
// steps / sync records, frames that are not mono8 / rgb8.
Result<SessionDetections> read_session_detections(const std::filesystem::path& session,
                                                  const RigCalibration& calibration,
                                                  const SessionReadOptions& options = {});

// The probe's pose in one step (world frame).
struct ProbePose {
  Eigen::Vector3d tip_m = Eigen::Vector3d::Zero();  // lowest point of the tip sphere
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  // unit, from the tip up the shaft
  bool from_markers = false;  // from the shaft markers (else the arm's reported pose, axis +z)
  // Triangulated shaft markers (when from_markers).
  std::array<Eigen::Vector3d, 2> markers_m{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
};

struct ProbePoseOptions {
  // Shaft-marker distances from the tip (nearer first); unset: the session's
  // (SessionDetections::shaft_marker_distances_m). Neither: the arm pose is used.
  std::optional<std::array<double, 2>> shaft_marker_distances_m;
  // The two triangulated markers must be (d1 - d0) apart within this.
  double distance_tolerance_m = 1.5e-3;
  MatchOptions match{
      .epipolar_tolerance_px = 2.0, .support_tolerance_px = 2.0, .min_views = 2, .max_rms_px = 1.5};
};

// The probe's pose from its two shaft markers (thesis 4.4: "two markers on the white shaft"):
// the candidates of every camera (rig-frame cameras, distorted pixels) are matched across views
// (match_views), the pair of triangulated points whose distance is nearest d1 - d0 (within the
// tolerance) is taken, marker 0 being the one nearer `specimen_world` (the specimen's measured
// markers; the tip end of the shaft); axis = (m1 - m0) / |m1 - m0|, tip = m0 - d0 axis. nullopt
// when fewer than two markers are found or no pair fits the shaft.
std::optional<ProbePose> probe_pose_from_shaft_markers(
    const std::vector<CameraModel>& cameras, const FrameDetections& shaft_detections,
    const Eigen::Isometry3d& world_from_rig, const std::array<double, 2>& distances_m,
    const std::vector<Eigen::Vector3d>& specimen_world, const ProbePoseOptions& options = {});

struct SessionTrackOptions {
  TrackOptions track;
  ProbePoseOptions probe;
  // The probe's pose per step from its shaft markers (the arm's reported pose where they are not
  // both seen, or no shaft geometry is known); false: always the arm's pose.
  bool probe_from_shaft_markers = true;
  double template_match_distance_m = 1.0e-3;
  // The template's nodes must be where the markers are: a measured node's displacement is its
  // marker's position minus the node's rest position, so a marker beside its node adds that offset
  // to every displacement. Tracking stops with the cause when the first step's registration RMS
  // exceeds this (a tenth of the thesis's 3 mm marker spacing).
  double max_registration_rms_m = 0.3e-3;
  double fixed_tolerance_m = 1.0e-6;
  // Sphere radius of the probe's tip (m); unset: the session's (SessionDetections::probe_radius_m),
  // else 5 mm (the simulator's default).
  std::optional<double> probe_radius_m;
  double contact_tolerance_m = 0.3e-3;
  double fill_regularization_m = 0.0;
  // The probe sphere constrains the fill: filled nodes inside it and surface nodes within its
  // contact patch are put on it, and the patch itself is a constraint (occlusion_fill.cpp
  // fill_with_probe_contact).
  bool probe_constraint = true;
  // Measured markers used as RBF centres per step: the ones nearest the unmeasured markers and
  // the probe (0: all). The solve is cubic in this number.
  std::size_t max_fill_centres = 120;
};

struct TrackSummary {
  std::size_t markers = 0;  // tracked markers registered to template nodes
  std::size_t steps = 0;
  double matched_fraction = 0;             // measured (marker, step) pairs / (markers x steps)
  double detections_matched_fraction = 0;  // dots assigned to a tracked marker / all dots
  double reprojection_rms_px = 0;          // over all measured markers' views
  double registration_rms_m = 0;           // ICP residual of the first step
  // Ground truth (simulated sessions only).
  bool has_truth = false;
  double truth_rms_error_m = 0;  // measured markers vs truth over all steps (world frame)
  double truth_max_error_m = 0;
  double truth_matched_fraction = 0;  // measured / truth-visible (in >= 2 images, not occluded)
  std::size_t filled = 0;             // (marker, step) pairs filled
  double filled_truth_rms_error_m = 0;
  double filled_truth_max_error_m = 0;
  // Probe pose: steps whose pose came from the shaft markers, steps that fell back to the arm's
  // pose (fewer than two shaft markers seen, or no shaft geometry), steps with neither, and a
  // sentence saying which (for the CLI).
  std::size_t probe_from_markers = 0;
  std::size_t probe_fallbacks = 0;
  std::size_t probe_missing = 0;
  std::string probe_source;
  // Tip of the marker-derived poses vs the simulator's probe_tip_m (when both exist).
  bool has_probe_truth = false;
  double probe_truth_rms_error_m = 0;
  double probe_truth_max_error_m = 0;
  double probe_axis_truth_max_error_rad = 0;
  StageTimes times;
};

struct TrackedSession {
  material::Samples samples;
  TrackSummary summary;
  std::vector<int> marker_node;                 // per registered marker: template node
  std::vector<std::optional<ProbePose>> probe;  // per step (nullopt: no pose at all)
};

// Tracks the detections, registers them to the template and builds the samples (one example per
// step). kFailedPrecondition when the first step has too few markers or the registration fails.
Result<TrackedSession> track_detections(const SessionDetections& detections,
                                        const RigCalibration& calibration,
                                        const TetMesh& template_mesh,
                                        const SessionTrackOptions& options = {});

}  // namespace hc::tracking
