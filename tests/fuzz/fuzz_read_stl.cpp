// libFuzzer target: the STL reader on arbitrary bytes (binary when the size is 84 + 50n, ASCII
// otherwise), with and without welding.
// Beyond the sanitizers, it checks the contract of parse_mesh (see fuzz_mesh_reader.h).
#include <cstddef>
#include <cstdint>

#include "fuzz_mesh_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  hc::testing::fuzz_mesh_reader(data, size, hc::MeshFormat::kStl);
  hc::MeshReadOptions soup;
  soup.weld_stl_vertices = false;
  return hc::testing::fuzz_mesh_reader(data, size, hc::MeshFormat::kStl, soup);
}
