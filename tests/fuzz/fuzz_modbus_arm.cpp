// libFuzzer target for the arm's Modbus register-map decoding: arbitrary bytes become big-endian
// 16-bit registers (as they travel in a Modbus PDU) decoded as a status block (client side) and as
// a command block (arm side). Whatever decodes must re-encode to the same registers (status) or to
// registers that decode to the same command. Crashes, sanitizer reports and mismatches are bugs.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <vector>

#include "rig_daemon/backends/arm_register_map.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace arm = hc::rig::arm;
  std::vector<std::uint16_t> regs(size / 2);
  for (std::size_t i = 0; i < regs.size(); ++i)
    regs[i] = static_cast<std::uint16_t>((data[2 * i] << 8) | data[2 * i + 1]);
  auto status = arm::decode_status(regs);
  if (status.ok()) {
    const auto again = arm::encode_status(*status);
    for (std::size_t i = 0; i < again.size(); ++i)
      if (again[i] != regs[i]) std::abort();
    (void)arm::fault_text(status->fault);
  }
  auto command = arm::decode_command(regs);
  if (command.ok() && command->opcode != arm::Opcode::kNone) {
    auto encoded = arm::encode_command(*command);
    if (!encoded.ok()) std::abort();  // every decoded value fits its register again
    for (std::size_t i = 0; i < encoded->size(); ++i)
      if ((*encoded)[i] != regs[i]) std::abort();
  }
  return 0;
}
