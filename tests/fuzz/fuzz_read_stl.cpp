// libFuzzer target: the STL reader on arbitrary bytes (binary when the size is 84 + 50n, ASCII
// otherwise), with and without welding.
// Beyond the sanitizers, it checks the contract of parse_mesh: an error is kInvalidArgument, and
// an accepted mesh has finite coordinates and every index in range.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "common/mesh_io.h"

namespace {

void check(const hc::Result<hc::TriangleMesh>& r) {
  if (!r.ok()) {
    if (r.status().code() != hc::StatusCode::kInvalidArgument) std::abort();
    return;
  }
  const hc::TriangleMesh& m = *r;
  if (!m.vertices.allFinite() || m.num_triangles() == 0) std::abort();
  if (m.triangles.minCoeff() < 0 || m.triangles.maxCoeff() >= m.num_vertices()) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  check(hc::parse_mesh(bytes, hc::MeshFormat::kStl, "fuzz.stl"));
  hc::MeshReadOptions soup;
  soup.weld_stl_vertices = false;
  check(hc::parse_mesh(bytes, hc::MeshFormat::kStl, "fuzz.stl", soup));
  return 0;
}
