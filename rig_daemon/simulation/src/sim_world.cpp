#include "rig_daemon/simulation/sim_world.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <string>

namespace hc::devices::sim {

namespace {

// Seconds → ns (rounded), for durations computed in double.
std::int64_t to_ns(double s) { return static_cast<std::int64_t>(std::llround(s * 1e9)); }

ArmPose lerp(const ArmPose& a, const ArmPose& b, double u) {
  return {a.x_m + (b.x_m - a.x_m) * u, a.y_m + (b.y_m - a.y_m) * u, a.z_m + (b.z_m - a.z_m) * u,
          a.yaw_rad + (b.yaw_rad - a.yaw_rad) * u};
}

// 64-bit FNV-1a then splitmix64: a stable hash (std::hash is not stable across libraries).
std::uint64_t stable_hash(std::uint64_t seed, std::string_view text) {
  std::uint64_t h = 1469598103934665603ULL ^ seed;
  for (unsigned char c : text) {
    h ^= c;
    h *= 1099511628211ULL;
  }
  h += 0x9E3779B97F4A7C15ULL;
  h = (h ^ (h >> 30)) * 0xBF58476D1CE4E5B9ULL;
  h = (h ^ (h >> 27)) * 0x94D049BB133111EBULL;
  return h ^ (h >> 31);
}

}  // namespace

std::string_view to_string(Fault::Kind kind) {
  switch (kind) {
    case Fault::Kind::kStall:
      return "stall";
    case Fault::Kind::kDropout:
      return "dropout";
    case Fault::Kind::kSpike:
      return "spike";
    case Fault::Kind::kDelay:
      return "delay";
    case Fault::Kind::kDisconnect:
      return "disconnect";
  }
  return "unknown";
}

Status WorldOptions::read(ConfigNode node) {
  node.optional("seed", seed);
  node.optional("probe_radius_m", probe_radius_m, Bounds::positive());
  std::array<double, 3> h{home.x_m, home.y_m, home.z_m};
  if (node.optional("home_m", h)) home = {h[0], h[1], h[2], 0.0};
  node.optional("arm_speed_m_s", arm_speed_m_s, Bounds::positive());
  std::array<double, 3> lo{arm_limits.min.x_m, arm_limits.min.y_m, arm_limits.min.z_m};
  std::array<double, 3> hi{arm_limits.max.x_m, arm_limits.max.y_m, arm_limits.max.z_m};
  if (node.optional("workspace_min_m", lo)) {
    arm_limits.min.x_m = lo[0];
    arm_limits.min.y_m = lo[1];
    arm_limits.min.z_m = lo[2];
  }
  if (node.optional("workspace_max_m", hi)) {
    arm_limits.max.x_m = hi[0];
    arm_limits.max.y_m = hi[1];
    arm_limits.max.z_m = hi[2];
  }
  node.optional("max_speed_m_s", arm_limits.max_speed_m_s, Bounds::positive());
  node.optional("probe", probe);
  if (std::optional<ConfigNode> s = node.find("specimen")) {
    s->optional("model", specimen_model, {"hertz", "hyperelastic"});
    s->optional("height_m", hyperelastic.height_m, Bounds::positive());
    s->optional("layers", hyperelastic.layers, Bounds::between(1, 64));
    s->optional("max_depth_m", hyperelastic.max_depth_m, Bounds::positive());
    s->optional("depth_steps", hyperelastic.depth_steps, Bounds::between(1, 200));
    s->optional("material_layers", hyperelastic.material_layers);
    std::array<double, 2> c{specimen.center_m.x(), specimen.center_m.y()};
    std::array<double, 2> sz{specimen.size_m.x(), specimen.size_m.y()};
    s->optional("youngs_modulus_pa", specimen.youngs_modulus_pa, Bounds::positive());
    s->optional("poisson_ratio", specimen.poisson_ratio, Bounds{0.0, 0.5, false, true});
    s->optional("stiffening", specimen.stiffening, Bounds::non_negative());
    s->optional("top_z_m", specimen.top_z_m);
    if (s->optional("center_m", c)) specimen.center_m = {c[0], c[1]};
    if (s->optional("size_m", sz, Bounds::positive())) specimen.size_m = {sz[0], sz[1]};
    s->optional("marker_spacing_m", specimen.marker_spacing_m, Bounds::positive());
    s->optional("marker_radius_m", specimen.marker_radius_m, Bounds::positive());
  }
  // The shared specimen keys feed both models.
  hyperelastic.youngs_modulus_pa = specimen.youngs_modulus_pa;
  hyperelastic.poisson_ratio = specimen.poisson_ratio;
  hyperelastic.stiffening = specimen.stiffening;
  hyperelastic.top_z_m = specimen.top_z_m;
  hyperelastic.center_m = specimen.center_m;
  hyperelastic.size_m = specimen.size_m;
  hyperelastic.marker_spacing_m = specimen.marker_spacing_m;
  hyperelastic.marker_radius_m = specimen.marker_radius_m;
  hyperelastic.probe_radius_m = probe_radius_m;
  return node.status();
}

Status WorldOptions::validate() const {
  HC_RETURN_IF_ERROR(specimen.validate());
  if (specimen_model == "hyperelastic") HC_RETURN_IF_ERROR(hyperelastic.validate());
  if (!(probe_radius_m > 0.0)) return invalid_argument("world: probe_radius_m must be > 0");
  HC_RETURN_IF_ERROR(probe.validate());
  if (!arm_limits.contains(home)) return invalid_argument("world: home_m is outside the workspace");
  if (!(arm_speed_m_s > 0.0 && arm_speed_m_s <= arm_limits.max_speed_m_s))
    return invalid_argument("world: arm_speed_m_s must be in (0, max_speed_m_s]");
  return {};
}

World::World(WorldOptions options, std::shared_ptr<Clock> clock,
             std::shared_ptr<const Specimen> specimen)
    : options_(std::move(options)),
      clock_(clock ? std::move(clock) : monotonic_clock()),
      specimen_(std::move(specimen)),
      speed_m_s_(options_.arm_speed_m_s) {
  if (!specimen_ && options_.specimen_model == "hyperelastic") {
    Result<std::shared_ptr<HyperelasticSpecimen>> fem =
        HyperelasticSpecimen::create(options_.hyperelastic);
    if (fem.ok())
      specimen_ = std::move(fem).value();
    else
      specimen_status_ = fem.status();
  }
  if (!specimen_) specimen_ = std::make_shared<HertzSpecimen>(options_.specimen);
  segment_.start_ns = clock_->now_ns();
  segment_.from = segment_.to = options_.home;
}

std::uint64_t World::device_seed(std::string_view device) const {
  return stable_hash(options_.seed, device);
}

// ---- Arm ----

ArmPose World::pose_at_locked(std::int64_t t_ns) const {
  std::int64_t t = t_ns;
  for (const Fault& f : faults_)  // a stalled arm freezes where the stall caught it
    if (f.kind == Fault::Kind::kStall && (f.device.empty() || f.device == "arm") &&
        t_ns >= f.start_ns && t_ns < f.end_ns)
      t = std::min(t, f.start_ns);
  if (segment_.duration_ns <= 0 || t >= segment_.start_ns + segment_.duration_ns)
    return t < segment_.start_ns ? segment_.from : segment_.to;
  if (t <= segment_.start_ns) return segment_.from;
  const double u =
      static_cast<double>(t - segment_.start_ns) / static_cast<double>(segment_.duration_ns);
  return lerp(segment_.from, segment_.to, u);
}

Status World::arm_command(const ArmCommand& c, std::int64_t t_ns) {
  std::lock_guard lock(mutex_);
  const bool stalled = std::any_of(faults_.begin(), faults_.end(), [&](const Fault& f) {
    return f.kind == Fault::Kind::kStall && (f.device.empty() || f.device == "arm") &&
           t_ns >= f.start_ns && t_ns < f.end_ns;
  });
  if (!homed_ && segment_.homing && t_ns >= homed_ns_) homed_ = true;
  const ArmPose here = pose_at_locked(t_ns);
  auto start_motion = [&](const ArmPose& to, bool homing) {
    const double dist = std::sqrt((to.x_m - here.x_m) * (to.x_m - here.x_m) +
                                  (to.y_m - here.y_m) * (to.y_m - here.y_m) +
                                  (to.z_m - here.z_m) * (to.z_m - here.z_m));
    const double turn = std::abs(to.yaw_rad - here.yaw_rad);
    const double secs = std::max(dist / speed_m_s_, turn / options_.arm_yaw_speed_rad_s);
    segment_ = Segment{t_ns, here, to, to_ns(secs), homing, false};
    if (homing) homed_ns_ = t_ns + segment_.duration_ns;
  };
  switch (c.type) {
    case ArmCommand::Type::kClearFault:
      break;
    case ArmCommand::Type::kStop:
      segment_ = Segment{t_ns, here, here, 0, false, true};
      break;
    case ArmCommand::Type::kSetSpeed:
      if (!(c.speed_m_s > 0.0 && c.speed_m_s <= options_.arm_limits.max_speed_m_s))
        return invalid_argument("arm: speed must be in (0, " +
                                std::to_string(options_.arm_limits.max_speed_m_s) + "] m/s");
      speed_m_s_ = c.speed_m_s;
      break;
    case ArmCommand::Type::kHome:
      if (stalled) return failed_precondition("arm: in fault (stall); clear it first");
      homed_ = false;
      start_motion(options_.home, true);
      break;
    case ArmCommand::Type::kMoveTo:
      if (stalled) return failed_precondition("arm: in fault (stall); clear it first");
      if (!homed_) return failed_precondition("arm: not homed; send home first");
      if (!options_.arm_limits.contains(c.target))
        return invalid_argument("arm: target outside the workspace");
      if (c.speed_m_s > 0.0) {
        if (c.speed_m_s > options_.arm_limits.max_speed_m_s)
          return invalid_argument("arm: speed above max_speed_m_s");
        speed_m_s_ = c.speed_m_s;
      }
      start_motion(c.target, false);
      break;
  }
  command_sequence_ = c.sequence;
  return {};
}

void World::arm_stop(std::int64_t t_ns) {
  std::lock_guard lock(mutex_);
  const ArmPose here = pose_at_locked(t_ns);
  segment_ = Segment{t_ns, here, here, 0, false, true};
}

ArmState World::arm_state(std::int64_t t_ns) {
  std::lock_guard lock(mutex_);
  if (!homed_ && segment_.homing && t_ns >= homed_ns_) homed_ = true;
  ArmState s;
  s.pose = pose_at_locked(t_ns);
  s.target = segment_.to;
  s.joints = {s.pose.x_m, s.pose.y_m, s.pose.z_m, s.pose.yaw_rad};  // Cartesian-axis arm
  s.speed_m_s = speed_m_s_;
  s.homed = homed_;
  const bool done = t_ns >= segment_.start_ns + segment_.duration_ns;
  if (segment_.stopped)
    s.motion = ArmMotion::kStopped;
  else if (!done)
    s.motion = segment_.homing ? ArmMotion::kHoming : ArmMotion::kMoving;
  else
    s.motion = homed_ ? ArmMotion::kHolding : ArmMotion::kIdle;
  for (const Fault& f : faults_)
    if (f.kind == Fault::Kind::kStall && (f.device.empty() || f.device == "arm") &&
        t_ns >= f.start_ns && t_ns < f.end_ns) {
      s.motion = ArmMotion::kFault;
      s.fault_code = 2;
      s.fault = "stall: axes do not follow the command";
    }
  s.command_sequence = command_sequence_;
  s.sequence = state_sequence_++;
  s.host_ns = t_ns;
  return s;
}

ArmPose World::probe_pose(std::int64_t t_ns) {
  std::lock_guard lock(mutex_);
  return pose_at_locked(t_ns);
}

// ---- Contact ----

Indentation World::indentation(std::int64_t t_ns) {
  const ArmPose p = probe_pose(t_ns);
  Indentation ind;
  ind.center_x_m = p.x_m;
  ind.center_y_m = p.y_m;
  ind.depth_m = specimen_->top_z_m() - p.z_m;
  ind.probe_radius_m = options_.probe_radius_m;
  return ind;
}

double World::true_force_n(std::int64_t t_ns) { return specimen_->force_n(indentation(t_ns)); }

GroundTruth World::ground_truth(std::int64_t t_ns, std::optional<std::uint64_t> trigger_index,
                                bool per_camera) {
  GroundTruth g;
  g.host_ns = t_ns;
  g.trigger_index = trigger_index;
  g.probe = probe_pose(t_ns);
  const Indentation ind = indentation(t_ns);
  g.indentation_m = ind.depth_m;
  g.force_n = specimen_->force_n(ind);
  g.probe_geometry = ProbeGeometry::at(g.probe, options_.probe_radius_m, options_.probe);
  std::optional<BoardShow> shown;
  std::vector<CameraRecord> cams;
  {
    std::lock_guard lock(mutex_);
    shown = board_;
    if (per_camera) cams = cameras_;
  }
  g.board_pose_index = board_pose_index(t_ns, trigger_index);
  g.probe_shown = options_.probe.visible && !g.board_pose_index;
  if (g.board_pose_index && shown) {
    g.board_spec = shown->spec;
    g.board_pose = shown->poses[*g.board_pose_index];
  } else {
    const auto& rest = specimen_->rest_markers();
    g.markers_m.reserve(rest.size());
    for (const Eigen::Vector3d& m : rest)
      g.markers_m.push_back(m + specimen_->displacement(m, ind));
  }
  const double marker_r = specimen_->marker_radius_m();
  for (const CameraRecord& rec : cams) {
    CameraTruth ct;
    ct.camera = rec.name;
    const CameraModel& cam = rec.camera;
    const Eigen::Vector3d origin = cam.center_m();
    for (std::size_t i = 0; i < g.markers_m.size(); ++i) {
      const Eigen::Vector3d& m = g.markers_m[i];
      const auto index = static_cast<std::uint32_t>(i);
      const std::optional<Eigen::Vector2d> uv = cam.project(m);
      const double z = cam.depth_m(m);
      const double r_px = uv ? cam.fx * marker_r / z + 1.0 : 0.0;
      if (!uv || uv->x() - r_px < -0.5 || uv->y() - r_px < -0.5 ||
          uv->x() + r_px > cam.width - 0.5 || uv->y() + r_px > cam.height - 0.5)
        ct.out_of_view.push_back(index);
      if (!g.probe_shown) continue;
      const Eigen::Vector3d d = m - origin;
      const double dist = d.norm();
      // Grown by the dot's radius plus 1.5 px (the anti-aliased edges of dot and probe).
      const double s = g.probe_geometry.ray_hit(origin, d / dist, marker_r + 1.5 * z / cam.fx);
      if (s < dist - marker_r) ct.occluded.push_back(index);
    }
    if (g.board_pose_index) ct.board_visible = board_visible(cam, g.board_spec, g.board_pose);
    g.cameras.push_back(std::move(ct));
  }
  return g;
}

// ---- Scene ----

void World::register_camera(const std::string& name, const CameraModel& camera) {
  std::lock_guard lock(mutex_);
  for (CameraRecord& c : cameras_)
    if (c.name == name) {
      c.camera = camera;
      return;
    }
  cameras_.push_back(CameraRecord{name, camera});
}

std::vector<CameraRecord> World::cameras() const {
  std::lock_guard lock(mutex_);
  return cameras_;
}

void World::show_board(BoardShow board) {
  std::lock_guard lock(mutex_);
  board_ = std::move(board);
}

void World::hide_board() {
  std::lock_guard lock(mutex_);
  board_.reset();
}

std::optional<BoardShow> World::board() const {
  std::lock_guard lock(mutex_);
  return board_;
}

std::optional<std::size_t> World::board_pose_index(
    std::int64_t t_ns, std::optional<std::uint64_t> trigger_index) const {
  std::lock_guard lock(mutex_);
  if (!board_ || board_->poses.empty()) return std::nullopt;
  const std::uint64_t n = board_->poses.size();
  if (trigger_index) {
    if (*trigger_index < board_->first_trigger_index) return std::nullopt;  // before the capture
    return static_cast<std::size_t>((*trigger_index - board_->first_trigger_index) % n);
  }
  if (t_ns < board_->start_ns) return std::nullopt;
  const std::int64_t k = (t_ns - board_->start_ns) / std::max<std::int64_t>(1, board_->dwell_ns);
  return static_cast<std::size_t>(static_cast<std::uint64_t>(k) % n);
}

void World::set_ground_truth_callback(std::function<void(const GroundTruth&)> callback) {
  std::lock_guard lock(mutex_);
  truth_callback_ = std::move(callback);
}

void World::publish_ground_truth(std::int64_t t_ns, std::optional<std::uint64_t> trigger_index) {
  std::function<void(const GroundTruth&)> callback;
  {
    std::lock_guard lock(mutex_);
    if (!truth_callback_ || t_ns <= last_truth_ns_) return;  // once per frame time, in order
    last_truth_ns_ = t_ns;
    callback = truth_callback_;
  }
  callback(ground_truth(t_ns, trigger_index, true));
}

// ---- Trigger timeline ----

std::uint64_t World::program_pulses_by(const Program& p, std::int64_t t_ns) const {
  if (t_ns < p.start_ns) return 0;
  const std::int64_t end = std::min(t_ns, p.stop_ns - 1);
  if (end < p.start_ns) return 0;
  const std::uint64_t n =
      static_cast<std::uint64_t>((end - p.start_ns) / std::max<std::int64_t>(p.period_ns, 1)) + 1;
  return p.count ? std::min(n, p.count) : n;
}

Status World::trigger_start(const PulseTrain& train, std::int64_t t_ns) {
  std::lock_guard lock(mutex_);
  Program p;
  p.start_ns = t_ns;
  p.period_ns = to_ns(1.0 / train.rate_hz);
  p.width_ns = to_ns(train.pulse_width_s);
  p.count = train.count;
  if (!programs_.empty()) {
    // The new train replaces the running one: pulses of the old train from t_ns on never fire.
    Program& last = programs_.back();
    last.stop_ns = std::min(last.stop_ns, t_ns);
    p.first_index = last.first_index + program_pulses_by(last, t_ns);
  }
  programs_.push_back(p);
  return {};
}

void World::trigger_stop(std::int64_t t_ns) {
  std::lock_guard lock(mutex_);
  if (!programs_.empty()) programs_.back().stop_ns = std::min(programs_.back().stop_ns, t_ns + 1);
}

Status World::trigger_fire(double pulse_width_s, std::int64_t t_ns) {
  PulseTrain one;
  one.rate_hz = 1.0;
  one.pulse_width_s = std::min(pulse_width_s, 0.5);
  one.count = 1;
  return trigger_start(one, t_ns);
}

bool World::trigger_running(std::int64_t t_ns) const {
  std::lock_guard lock(mutex_);
  if (programs_.empty()) return false;
  const Program& p = programs_.back();
  if (t_ns >= p.stop_ns) return false;
  return p.count == 0 || program_pulses_by(p, t_ns) < p.count ||
         t_ns < p.start_ns + static_cast<std::int64_t>(p.count - 1) * p.period_ns + p.width_ns;
}

const World::Program* World::program_of(std::uint64_t index) const {
  for (auto it = programs_.rbegin(); it != programs_.rend(); ++it)
    if (index >= it->first_index) return &*it;
  return nullptr;
}

std::optional<std::int64_t> World::rising_edge_ns(std::uint64_t index, std::int64_t t_ns) const {
  std::lock_guard lock(mutex_);
  const Program* p = program_of(index);
  if (!p) return std::nullopt;
  const std::uint64_t k = index - p->first_index;
  if (k >= program_pulses_by(*p, t_ns)) return std::nullopt;
  return p->start_ns + static_cast<std::int64_t>(k) * p->period_ns;
}

std::int64_t World::pulse_width_ns(std::uint64_t index) const {
  std::lock_guard lock(mutex_);
  const Program* p = program_of(index);
  return p ? p->width_ns : 0;
}

std::uint64_t World::pulses_by(std::int64_t t_ns) const {
  std::lock_guard lock(mutex_);
  if (programs_.empty()) return 0;
  const Program& p = programs_.back();
  return p.first_index + program_pulses_by(p, t_ns);
}

// ---- Faults ----

void World::inject(Fault fault) {
  std::lock_guard lock(mutex_);
  faults_.push_back(std::move(fault));
}

void World::clear_faults() {
  std::lock_guard lock(mutex_);
  faults_.clear();
}

std::optional<Fault> World::fault(std::string_view device, Fault::Kind kind,
                                  std::int64_t t_ns) const {
  std::lock_guard lock(mutex_);
  for (const Fault& f : faults_)
    if (f.kind == kind && (f.device.empty() || f.device == device) && t_ns >= f.start_ns &&
        t_ns < f.end_ns)
      return f;
  return std::nullopt;
}

session::GroundTruthRecord GroundTruth::record() const {
  session::GroundTruthRecord r;
  r.host_ns = host_ns;
  r.trigger_index = trigger_index;
  r.probe = probe;
  r.indentation_m = indentation_m;
  r.force_n = force_n;
  r.markers_m = markers_m;
  r.probe_tip_m = probe_geometry.tip_m;
  r.probe_axis = probe_geometry.axis;
  r.probe_radius_m = probe_geometry.radius_m;
  r.probe_shown = probe_shown;
  r.shaft_markers_m = probe_geometry.markers_m;
  r.shaft_marker_radius_m = probe_geometry.marker_radius_m;
  for (const CameraTruth& c : cameras)
    r.cameras[c.camera] = {c.occluded, c.out_of_view, c.board_visible};
  if (board_pose_index)
    r.board = session::GroundTruthRecord::Board{static_cast<int>(*board_pose_index),
                                                board_spec.cols,
                                                board_spec.rows,
                                                board_spec.square_m,
                                                board_pose.R,
                                                board_pose.t};
  return r;
}

}  // namespace hc::devices::sim
