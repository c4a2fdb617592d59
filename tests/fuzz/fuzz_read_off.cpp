// libFuzzer target: the OFF reader on arbitrary bytes.
// Beyond the sanitizers, it checks the contract of parse_mesh (see fuzz_mesh_reader.h).
#include <cstddef>
#include <cstdint>

#include "fuzz_mesh_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return hc::testing::fuzz_mesh_reader(data, size, hc::MeshFormat::kOff);
}
