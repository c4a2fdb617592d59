#include "rig_daemon/simulators/modbus_arm_server.h"
#include "common/clock.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <modbus.h>
#include <netinet/in.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <ctime>
#include <vector>

namespace hc::rig::sim {
namespace {

modbus_t* as_ctx(void* p) { return static_cast<modbus_t*>(p); }
modbus_mapping_t* as_map(void* p) { return static_cast<modbus_mapping_t*>(p); }

bool inside(const ArmPoseSi& p, const ArmPoseSi& lo, const ArmPoseSi& hi) {
  return p.x_m >= lo.x_m && p.x_m <= hi.x_m && p.y_m >= lo.y_m && p.y_m <= hi.y_m &&
         p.z_m >= lo.z_m && p.z_m <= hi.z_m && p.yaw_rad >= lo.yaw_rad && p.yaw_rad <= hi.yaw_rad;
}

}  // namespace

Status ModbusArmServerOptions::validate() const {
  if (!(speed_m_s > 0 && speed_m_s <= max_speed_m_s))
    return invalid_argument("speed_m_s: expected (0, max_speed_m_s]");
  if (!(yaw_speed_rad_s > 0)) return invalid_argument("yaw_speed_rad_s: expected > 0");
  if (!(home_speed_m_s > 0)) return invalid_argument("home_speed_m_s: expected > 0");
  if (!(cycle_s > 0 && cycle_s <= 0.1)) return invalid_argument("cycle_s: expected (0, 0.1]");
  if (!inside(home_pose, workspace_min, workspace_max))
    return invalid_argument("home_pose: outside the workspace");
  return {};
}

ModbusArmServer::ModbusArmServer(ModbusArmServerOptions options)
    : options_(std::move(options)),
      pose_(options_.start_pose),
      target_(options_.start_pose),
      speed_m_s_(options_.speed_m_s),
      yaw_speed_rad_s_(options_.yaw_speed_rad_s) {}

Result<std::unique_ptr<ModbusArmServer>> ModbusArmServer::start(ModbusArmServerOptions options) {
  HC_RETURN_IF_ERROR(options.validate());
  std::unique_ptr<ModbusArmServer> s(new ModbusArmServer(std::move(options)));
  s->ctx_ = modbus_new_tcp(s->options_.address.c_str(), s->options_.port);
  if (s->ctx_ == nullptr) return io_error(std::string("modbus_new_tcp: ") + modbus_strerror(errno));
  s->mapping_ = modbus_mapping_new(0, 0, arm::kHoldingRegisters, arm::kInputRegisters);
  if (s->mapping_ == nullptr) return io_error("modbus_mapping_new failed");
  // select() said a request is there; never wait long for the rest of a broken one.
  modbus_set_indication_timeout(as_ctx(s->ctx_), 0, 500'000);
  if (::pipe2(s->wake_fd_, O_CLOEXEC | O_NONBLOCK) != 0)
    return io_error(std::string("pipe: ") + std::strerror(errno));
  s->epoch_ns_ = monotonic_ns();
  s->port_ = s->options_.port;
  {
    std::lock_guard lock(s->mutex_);
    HC_RETURN_IF_ERROR(s->listen_locked());
    s->publish_locked();
  }
  {
    std::lock_guard lock(s->mutex_);
    s->thread_running_ = true;
  }
  s->thread_ = std::thread([p = s.get()] { p->run(); });
  return s;
}

ModbusArmServer::~ModbusArmServer() {
  quit_ = true;
  if (wake_fd_[1] >= 0) (void)!::write(wake_fd_[1], "x", 1);
  if (thread_.joinable()) thread_.join();
  disappear();
  if (ctx_ != nullptr) {
    modbus_set_socket(as_ctx(ctx_), -1);
    modbus_free(as_ctx(ctx_));
  }
  if (mapping_ != nullptr) modbus_mapping_free(as_map(mapping_));
  for (int fd : wake_fd_)
    if (fd >= 0) ::close(fd);
}

// Our own socket/bind/listen rather than modbus_tcp_listen(): we need port 0 (OS-chosen) and to
// re-listen on the same port after disappear(); libmodbus is used for framing and replies only.
Status ModbusArmServer::listen_locked() {
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(port_);
  if (::inet_pton(AF_INET, options_.address.c_str(), &addr.sin_addr) != 1)
    return invalid_argument("'" + options_.address + "' is not an IPv4 address");
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return io_error(std::string("socket: ") + std::strerror(errno));
  const int one = 1;
  ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  if (::bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0 ||
      ::listen(fd, 8) != 0) {
    Status s = io_error("Modbus arm simulator: bind/listen " + options_.address + ":" +
                        std::to_string(port_) + ": " + std::strerror(errno));
    ::close(fd);
    return s;
  }
  socklen_t len = sizeof addr;
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
  port_ = ntohs(addr.sin_port);
  listen_fd_ = fd;
  online_ = true;
  return {};
}

void ModbusArmServer::close_all_locked() {
  if (listen_fd_ >= 0) ::close(listen_fd_);
  listen_fd_ = -1;
  for (int fd : clients_) {
    ::shutdown(fd, SHUT_RDWR);
    ::close(fd);
  }
  clients_.clear();
  online_ = false;
  if (motion_ == arm::Motion::kMoving || motion_ == arm::Motion::kHoming) {
    motion_ = arm::Motion::kStopped;  // the controller's link watchdog stops the axes
    target_ = pose_;
  }
}

void ModbusArmServer::disappear() {
  std::unique_lock lock(mutex_);
  if (!thread_running_) {
    close_all_locked();
    return;
  }
  offline_request_ = true;
  if (wake_fd_[1] >= 0) (void)!::write(wake_fd_[1], "x", 1);
  offline_cv_.wait(lock, [&] { return !offline_request_; });
}

Status ModbusArmServer::reappear() {
  std::lock_guard lock(mutex_);
  if (online_) return {};
  Status s = listen_locked();
  if (wake_fd_[1] >= 0) (void)!::write(wake_fd_[1], "x", 1);
  return s;
}

bool ModbusArmServer::online() const {
  std::lock_guard lock(mutex_);
  return online_;
}

void ModbusArmServer::inject_fault(arm::Fault fault) {
  std::lock_guard lock(mutex_);
  fault_ = static_cast<std::uint16_t>(fault);
  motion_ = arm::Motion::kFault;
  target_ = pose_;
  publish_locked();
}

ModbusArmServerStats ModbusArmServer::stats() const {
  std::lock_guard lock(mutex_);
  return stats_;
}

arm::StatusBlock ModbusArmServer::status() const {
  std::lock_guard lock(mutex_);
  arm::StatusBlock s;
  s.motion = motion_;
  s.fault = fault_;
  s.homed = homed_;
  s.in_motion = motion_ == arm::Motion::kMoving || motion_ == arm::Motion::kHoming;
  s.ack_sequence = ack_sequence_;
  s.x_m = pose_.x_m;
  s.y_m = pose_.y_m;
  s.z_m = pose_.z_m;
  s.yaw_rad = pose_.yaw_rad;
  s.speed_m_s = speed_m_s_;
  s.uptime_ms = static_cast<std::uint32_t>((monotonic_ns() - epoch_ns_) / 1'000'000);
  s.heartbeat = heartbeat_;
  return s;
}

void ModbusArmServer::publish_locked() {
  arm::StatusBlock s;
  s.motion = motion_;
  s.fault = fault_;
  s.homed = homed_;
  s.in_motion = motion_ == arm::Motion::kMoving || motion_ == arm::Motion::kHoming;
  s.ack_sequence = ack_sequence_;
  s.x_m = pose_.x_m;
  s.y_m = pose_.y_m;
  s.z_m = pose_.z_m;
  s.yaw_rad = pose_.yaw_rad;
  s.speed_m_s = speed_m_s_;
  s.uptime_ms = static_cast<std::uint32_t>((monotonic_ns() - epoch_ns_) / 1'000'000);
  s.heartbeat = heartbeat_;
  const auto regs = arm::encode_status(s);
  std::copy(regs.begin(), regs.end(), as_map(mapping_)->tab_input_registers);
}

void ModbusArmServer::execute(const arm::CommandBlock& c) {
  ++stats_.commands;
  ack_sequence_ = c.sequence;
  auto fault = [&](arm::Fault f) {
    fault_ = static_cast<std::uint16_t>(f);
    motion_ = arm::Motion::kFault;
    target_ = pose_;
  };
  if (motion_ == arm::Motion::kFault && c.opcode != arm::Opcode::kClearFault &&
      c.opcode != arm::Opcode::kStop)
    return;  // latched: only clear fault (or stop) is obeyed
  switch (c.opcode) {
    case arm::Opcode::kHome:
      target_ = options_.home_pose;
      motion_ = arm::Motion::kHoming;
      return;
    case arm::Opcode::kMoveTo: {
      if (!homed_) return fault(arm::Fault::kNotHomed);
      const ArmPoseSi t{c.x_m, c.y_m, c.z_m, c.yaw_rad};
      if (!inside(t, options_.workspace_min, options_.workspace_max))
        return fault(arm::Fault::kOutsideWorkspace);
      if (c.speed_m_s > options_.max_speed_m_s) return fault(arm::Fault::kSpeedOutOfRange);
      if (c.speed_m_s > 0) speed_m_s_ = c.speed_m_s;
      if (c.yaw_speed_rad_s > 0) yaw_speed_rad_s_ = c.yaw_speed_rad_s;
      target_ = t;
      motion_ = arm::Motion::kMoving;
      return;
    }
    case arm::Opcode::kSetSpeed:
      if (!(c.speed_m_s > 0) || c.speed_m_s > options_.max_speed_m_s)
        return fault(arm::Fault::kSpeedOutOfRange);
      speed_m_s_ = c.speed_m_s;
      if (c.yaw_speed_rad_s > 0) yaw_speed_rad_s_ = c.yaw_speed_rad_s;
      return;
    case arm::Opcode::kStop:
      ++stats_.stops;
      if (motion_ != arm::Motion::kFault) motion_ = arm::Motion::kStopped;
      target_ = pose_;
      return;
    case arm::Opcode::kClearFault:
      fault_ = 0;
      if (motion_ == arm::Motion::kFault) motion_ = arm::Motion::kIdle;
      return;
    case arm::Opcode::kNone:
      break;
  }
  fault(arm::Fault::kUnknownCommand);
}

void ModbusArmServer::step(double dt) {
  ++heartbeat_;
  const bool homing = motion_ == arm::Motion::kHoming;
  if (!homing && motion_ != arm::Motion::kMoving) return;
  const double lin = homing ? options_.home_speed_m_s : speed_m_s_;
  const double dx = target_.x_m - pose_.x_m, dy = target_.y_m - pose_.y_m,
               dz = target_.z_m - pose_.z_m;
  const double d = std::sqrt(dx * dx + dy * dy + dz * dz);
  const double step = lin * dt;
  if (d <= step) {
    pose_.x_m = target_.x_m;
    pose_.y_m = target_.y_m;
    pose_.z_m = target_.z_m;
  } else {
    pose_.x_m += dx * step / d;
    pose_.y_m += dy * step / d;
    pose_.z_m += dz * step / d;
  }
  const double dyaw = target_.yaw_rad - pose_.yaw_rad;
  const double ystep = yaw_speed_rad_s_ * dt;
  pose_.yaw_rad =
      std::abs(dyaw) <= ystep ? target_.yaw_rad : pose_.yaw_rad + std::copysign(ystep, dyaw);
  if (d <= step && std::abs(dyaw) <= ystep) {
    if (homing) homed_ = true;
    motion_ = arm::Motion::kHolding;
  }
}

void ModbusArmServer::run() {
  std::vector<std::uint8_t> query(MODBUS_TCP_MAX_ADU_LENGTH);
  std::int64_t last_ns = monotonic_ns();
  const auto cycle_us = static_cast<long>(options_.cycle_s * 1e6);
  while (!quit_) {
    fd_set readable;
    FD_ZERO(&readable);
    int max_fd = wake_fd_[0];
    FD_SET(wake_fd_[0], &readable);
    {
      std::lock_guard lock(mutex_);
      if (listen_fd_ >= 0) {
        FD_SET(listen_fd_, &readable);
        max_fd = std::max(max_fd, listen_fd_);
      }
      for (int fd : clients_) {
        FD_SET(fd, &readable);
        max_fd = std::max(max_fd, fd);
      }
    }
    timeval tv{0, cycle_us};
    const int rc = ::select(max_fd + 1, &readable, nullptr, nullptr, &tv);
    if (quit_) break;
    std::lock_guard lock(mutex_);
    if (offline_request_) {
      close_all_locked();
      offline_request_ = false;
      offline_cv_.notify_all();
      continue;
    }
    if (rc > 0 && FD_ISSET(wake_fd_[0], &readable)) {
      char drain[64];
      while (::read(wake_fd_[0], drain, sizeof drain) > 0) {
      }
      continue;  // the fd set may be stale (disappear/reappear)
    }
    if (rc > 0 && listen_fd_ >= 0 && FD_ISSET(listen_fd_, &readable)) {
      const int fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC);
      if (fd >= 0) {
        clients_.push_back(fd);
        ++stats_.connections;
      }
    }
    for (std::size_t i = 0; rc > 0 && i < clients_.size();) {
      const int fd = clients_[i];
      if (!FD_ISSET(fd, &readable)) {
        ++i;
        continue;
      }
      modbus_set_socket(as_ctx(ctx_), fd);
      const int n = modbus_receive(as_ctx(ctx_), query.data());
      if (n < 0) {  // closed by the client or garbage: drop the connection
        ::close(fd);
        clients_.erase(clients_.begin() + static_cast<std::ptrdiff_t>(i));
        continue;
      }
      if (n > 0) {
        publish_locked();
        std::uint16_t* hr = as_map(mapping_)->tab_registers;
        const std::uint16_t seq_before = hr[arm::kRegCommandSeq];
        modbus_reply(as_ctx(ctx_), query.data(), n, as_map(mapping_));
        ++stats_.requests;
        if (hr[arm::kRegStop] != 0) {
          hr[arm::kRegStop] = 0;
          ++stats_.stops;
          if (motion_ != arm::Motion::kFault) motion_ = arm::Motion::kStopped;
          target_ = pose_;
        }
        if (hr[arm::kRegCommandSeq] != seq_before) {
          auto command =
              arm::decode_command({hr, static_cast<std::size_t>(arm::kCommandRegisters)});
          if (command.ok()) execute(*command);
        }
        publish_locked();
      }
      ++i;
    }
    modbus_set_socket(as_ctx(ctx_), -1);
    const std::int64_t now = monotonic_ns();
    if (now - last_ns >= cycle_us * 1000) {
      step(static_cast<double>(now - last_ns) * 1e-9);
      last_ns = now;
      publish_locked();
    }
  }
  std::lock_guard lock(mutex_);
  thread_running_ = false;
  if (offline_request_) {
    close_all_locked();
    offline_request_ = false;
    offline_cv_.notify_all();
  }
}

}  // namespace hc::rig::sim
