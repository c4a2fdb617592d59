#include "rig_daemon/backends/modbus_arm_client.h"

#include <arpa/inet.h>
#include <modbus.h>

#include <cerrno>
#include <cmath>
#include <cstring>

namespace hc::rig {
namespace {

void set_timeout(modbus_t* ctx, double seconds, bool response) {
  const auto sec = static_cast<std::uint32_t>(seconds);
  const auto usec = static_cast<std::uint32_t>(std::lround((seconds - sec) * 1e6));
  if (response)
    modbus_set_response_timeout(ctx, sec, usec);
  else
    modbus_set_byte_timeout(ctx, sec, usec);
}

// libmodbus reports protocol exceptions as errno EMBX* (>= MODBUS_ENOBASE); everything else is the
// OS telling us the link is gone or timed out.
bool link_error(int err) { return err < MODBUS_ENOBASE || err == EMBBADCRC; }

}  // namespace

Status ModbusArmOptions::read(ConfigNode node) {
  node.optional("transport", transport, {"tcp", "rtu"});
  node.optional("host", host);
  node.optional("port", port);
  node.optional("device", device);
  node.optional("baud", baud, Bounds::between(300, 4'000'000));
  node.optional("parity", parity, {"N", "E", "O"});
  node.optional("data_bits", data_bits, Bounds::between(5, 8));
  node.optional("stop_bits", stop_bits, Bounds::between(1, 2));
  node.optional("slave_id", slave_id, Bounds::between(0, 247));
  node.optional("response_timeout_s", response_timeout_s, Bounds::between(0.001, 10));
  node.optional("connect_timeout_s", connect_timeout_s, Bounds::between(0.001, 30));
  return node.status();
}

Status ModbusArmOptions::validate() const {
  if (transport == "tcp") {
    in_addr a{};
    if (::inet_pton(AF_INET, host.c_str(), &a) != 1)
      return invalid_argument("host: '" + host + "' is not an IPv4 address");
    if (port == 0) return invalid_argument("port: expected 1..65535, got 0");
  } else if (transport == "rtu") {
    if (device.empty()) return invalid_argument("device: empty serial device path");
    if (parity != "N" && parity != "E" && parity != "O")
      return invalid_argument("parity: expected N, E or O, got '" + parity + "'");
    if (data_bits < 5 || data_bits > 8) return invalid_argument("data_bits: expected 5..8");
    if (stop_bits < 1 || stop_bits > 2) return invalid_argument("stop_bits: expected 1 or 2");
    if (baud <= 0) return invalid_argument("baud: expected > 0");
  } else {
    return invalid_argument("transport: expected 'tcp' or 'rtu', got '" + transport + "'");
  }
  if (slave_id < 0 || slave_id > 247) return invalid_argument("slave_id: expected 0..247");
  if (!(response_timeout_s > 0)) return invalid_argument("response_timeout_s: expected > 0");
  return {};
}

std::string ModbusArmOptions::describe() const {
  if (transport == "tcp")
    return "tcp://" + host + ":" + std::to_string(port) + " unit " + std::to_string(slave_id);
  return "rtu:" + device + " " + std::to_string(baud) + " " + std::to_string(data_bits) + parity +
         std::to_string(stop_bits) + " slave " + std::to_string(slave_id);
}

Result<std::unique_ptr<ModbusArmClient>> ModbusArmClient::create(const ModbusArmOptions& options) {
  HC_RETURN_IF_ERROR(options.validate());
  std::unique_ptr<ModbusArmClient> c(new ModbusArmClient(options));
  if (options.transport == "tcp")
    c->ctx_ = modbus_new_tcp(options.host.c_str(), options.port);
  else
    c->ctx_ = modbus_new_rtu(options.device.c_str(), options.baud, options.parity[0],
                             options.data_bits, options.stop_bits);
  if (c->ctx_ == nullptr)
    return invalid_argument("Modbus " + options.describe() + ": " + modbus_strerror(errno));
  if (modbus_set_slave(c->ctx_, options.slave_id) != 0)
    return invalid_argument("Modbus slave_id " + std::to_string(options.slave_id) + ": " +
                            modbus_strerror(errno));
  set_timeout(c->ctx_, options.response_timeout_s, true);
  return c;
}

ModbusArmClient::~ModbusArmClient() {
  if (ctx_ != nullptr) {
    if (connected_) modbus_close(ctx_);
    modbus_free(ctx_);
  }
}

Status ModbusArmClient::connect() {
  std::lock_guard lock(mutex_);
  return connect_locked();
}

Status ModbusArmClient::connect_locked() {
  if (connected_) {
    modbus_close(ctx_);
    connected_ = false;
  }
  // libmodbus's TCP connect waits up to the response timeout; use the connect timeout for it.
  set_timeout(ctx_, options_.connect_timeout_s, true);
  const int rc = modbus_connect(ctx_);
  set_timeout(ctx_, options_.response_timeout_s, true);
  if (rc != 0)
    return Status(StatusCode::kUnavailable,
                  "Modbus arm " + options_.describe() + ": connect: " + modbus_strerror(errno));
  connected_ = true;
  std::uint16_t version = 0;
  ++stats_.transactions;
  if (modbus_read_input_registers(ctx_, arm::kInMapVersion, 1, &version) != 1) {
    ++stats_.failures;
    Status s =
        Status(StatusCode::kUnavailable, "Modbus arm " + options_.describe() +
                                             ": reading MAP_VERSION: " + modbus_strerror(errno));
    modbus_close(ctx_);
    connected_ = false;
    return s;
  }
  if ((version >> 8) != (arm::kMapVersion >> 8)) {
    modbus_close(ctx_);
    connected_ = false;
    return failed_precondition("Modbus arm " + options_.describe() + ": register map version " +
                               std::to_string(version >> 8) + "." + std::to_string(version & 0xFF) +
                               ", expected 1.x");
  }
  ++stats_.connects;
  return {};
}

void ModbusArmClient::close() {
  std::lock_guard lock(mutex_);
  if (connected_) modbus_close(ctx_);
  connected_ = false;
}

bool ModbusArmClient::connected() const {
  std::lock_guard lock(mutex_);
  return connected_;
}

Status ModbusArmClient::ensure_connected_locked() {
  if (connected_) return {};
  return connect_locked();
}

Status ModbusArmClient::transaction_error_locked(const std::string& what) {
  const int err = errno;
  ++stats_.failures;
  const std::string text =
      "Modbus arm " + options_.describe() + ": " + what + ": " + modbus_strerror(err);
  if (link_error(err)) {
    // Drop the link (and any half-read answer); the next call reconnects.
    modbus_close(ctx_);
    connected_ = false;
    return Status(err == ETIMEDOUT ? StatusCode::kDeadlineExceeded : StatusCode::kUnavailable,
                  text);
  }
  return io_error(text);  // the arm answered with a Modbus exception
}

Status ModbusArmClient::send(const arm::CommandBlock& command) {
  HC_ASSIGN_OR_RETURN(auto regs, arm::encode_command(command));
  std::lock_guard lock(mutex_);
  HC_RETURN_IF_ERROR(ensure_connected_locked());
  ++stats_.transactions;
  if (modbus_write_registers(ctx_, arm::kRegCommand, arm::kCommandRegisters, regs.data()) !=
      arm::kCommandRegisters)
    return transaction_error_locked("writing command");
  return {};
}

Status ModbusArmClient::stop() {
  std::lock_guard lock(mutex_);
  HC_RETURN_IF_ERROR(ensure_connected_locked());
  ++stats_.transactions;
  if (modbus_write_register(ctx_, arm::kRegStop, 1) != 1)
    return transaction_error_locked("writing STOP");
  return {};
}

Result<arm::StatusBlock> ModbusArmClient::read_status() {
  std::array<std::uint16_t, arm::kInputRegisters> regs{};
  {
    std::lock_guard lock(mutex_);
    HC_RETURN_IF_ERROR(ensure_connected_locked());
    ++stats_.transactions;
    if (modbus_read_input_registers(ctx_, 0, arm::kInputRegisters, regs.data()) !=
        arm::kInputRegisters)
      return transaction_error_locked("reading status");
  }
  auto status = arm::decode_status(regs);
  if (!status.ok()) return status.status().with_context("Modbus arm " + options_.describe());
  return status;
}

Result<std::vector<std::uint16_t>> ModbusArmClient::read_holding(int address, int count) {
  if (count < 1 || count > MODBUS_MAX_READ_REGISTERS)
    return invalid_argument("read_holding: count must be 1..125");
  std::vector<std::uint16_t> regs(static_cast<std::size_t>(count));
  std::lock_guard lock(mutex_);
  HC_RETURN_IF_ERROR(ensure_connected_locked());
  ++stats_.transactions;
  if (modbus_read_registers(ctx_, address, count, regs.data()) != count)
    return transaction_error_locked("reading holding registers");
  return regs;
}

ModbusArmStats ModbusArmClient::stats() const {
  std::lock_guard lock(mutex_);
  return stats_;
}

}  // namespace hc::rig
