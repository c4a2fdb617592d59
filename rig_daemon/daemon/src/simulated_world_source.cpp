// The simulated world as a session source (session_source.h): its ground-truth channel, the
// sim_cameras and sim_board metadata (rig_daemon/session/topics.h) and the board it shows during
// a calibration.
#include <algorithm>
#include <cmath>
#include <optional>

#include "camera/camera_model.h"
#include "common/json.h"
#include "rig_daemon/daemon/session_source.h"
#include "rig_daemon/session/codec.h"
#include "rig_daemon/session/topics.h"
#include "rig_daemon/simulation/sim_scene.h"
#include "rig_daemon/simulation/sim_world.h"

namespace hc::rig {

namespace {

namespace sim = devices::sim;

// The board and its poses a calibration plan shows on the specimen's top face.
sim::BoardShow board_show(const CalibrationPlan& p, const sim::Specimen& spec) {
  sim::BoardShow show;
  show.spec.cols = p.board_cols;
  show.spec.rows = p.board_rows;
  show.spec.square_m = p.square_m;
  show.spec.margin_squares = p.margin_squares;
  sim::BoardMotion motion;
  motion.poses = p.poses;
  motion.seed = p.seed;
  motion.max_tilt_deg = p.max_tilt_deg;
  const Eigen::Vector2d c = spec.footprint().center();
  show.poses = sim::board_poses(show.spec, motion, Eigen::Vector3d(c.x(), c.y(), spec.top_z_m()));
  show.dwell_ns = std::max<std::int64_t>(1, std::llround(p.dwell_s * 1e9));
  return show;
}

class SimulatedWorldSource final : public SessionSource {
 public:
  explicit SimulatedWorldSource(std::shared_ptr<sim::World> world) : world_(std::move(world)) {}
  ~SimulatedWorldSource() override { stop(); }

  Status add_channels(Recorder& recorder) override {
    recorder_ = &recorder;
    const session::MessageSchema schema = session::ground_truth_schema();
    HC_ASSIGN_OR_RETURN(
        channel_, recorder.add_json_channel(
                      session::kGroundTruthTopic, schema.name, schema.json_schema,
                      {{"device", "world"}, {"kind", "ground_truth"}, {"backend", "sim"}}));
    return {};
  }

  void describe_specimen(recording::StringMap& specimen) const override {
    specimen["simulated_specimen"] = world_->specimen().name();
  }

  Status write_metadata(const Plan& plan, const std::set<std::string>& cameras) override {
    cameras_ = cameras;
    Json sim_cams = Json::object();
    for (const sim::CameraRecord& r : world_->cameras()) {
      if (cameras_.count(r.name)) sim_cams[r.name] = camera_to_json(r.camera);
    }
    HC_RETURN_IF_ERROR(
        recorder_->write_metadata_now(session::kMetadataSimCameras, {{"json", sim_cams.dump()}}));
    if (plan.protocol != Protocol::kCalibration) return {};
    const CalibrationPlan& p = plan.calibration;
    board_ = board_show(p, world_->specimen());
    Json poses = Json::array();
    for (const sim::BoardPose& b : board_->poses)
      poses.push_back({{"R", eigen_to_json(b.R)}, {"t_m", eigen_to_json(b.t)}});
    const Json board{{"cols", p.board_cols},   {"rows", p.board_rows},
                     {"square_m", p.square_m}, {"margin_squares", p.margin_squares},
                     {"seed", p.seed},         {"poses", std::move(poses)}};
    return recorder_->write_metadata_now(session::kMetadataSimBoard, {{"json", board.dump()}});
  }

  void start() override {
    publishing_ = true;
    world_->set_ground_truth_callback([this](const sim::GroundTruth& t) {
      session::GroundTruthRecord r = t.record();
      std::erase_if(r.cameras, [&](const auto& c) { return !cameras_.count(c.first); });
      recorder_->write(channel_, t.host_ns, t.host_ns,
                       static_cast<std::uint32_t>(t.trigger_index.value_or(0)),
                       recording::to_bytes(session::to_json(r)));
    });
  }

  void begin_calibration(std::int64_t now_ns) override {
    if (!board_) return;
    board_->first_trigger_index = world_->pulses_by(now_ns);
    board_->start_ns = now_ns;
    world_->show_board(*board_);
    showing_ = true;
  }

  void stop() override {
    if (publishing_) world_->set_ground_truth_callback(nullptr);
    if (showing_) world_->hide_board();
    publishing_ = showing_ = false;
  }

 private:
  std::shared_ptr<sim::World> world_;
  Recorder* recorder_ = nullptr;
  std::uint16_t channel_ = 0;
  std::set<std::string> cameras_;
  std::optional<sim::BoardShow> board_;
  bool publishing_ = false;
  bool showing_ = false;
};

}  // namespace

std::unique_ptr<SessionSource> simulated_world_source(std::shared_ptr<sim::World> world) {
  if (!world) return nullptr;
  return std::make_unique<SimulatedWorldSource>(std::move(world));
}

}  // namespace hc::rig
