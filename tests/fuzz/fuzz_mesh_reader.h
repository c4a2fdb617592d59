// What the mesh-reader fuzz targets share: parse the fuzzer's bytes and check the contract of
// parse_mesh beyond the sanitizers: an error is kInvalidArgument, and an accepted mesh has at
// least one triangle, finite coordinates and every index in range. A broken contract aborts, which
// libFuzzer reports as a crash. No GoogleTest here: fuzz targets do not link it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>

#include "common/mesh_io.h"

namespace hc::testing {

// Aborts unless `r` keeps the contract above.
inline void check_parse_contract(const Result<TriangleMesh>& r) {
  if (!r.ok()) {
    if (r.status().code() != StatusCode::kInvalidArgument) std::abort();
    return;
  }
  const TriangleMesh& m = *r;
  if (!m.vertices.allFinite() || m.num_triangles() == 0) std::abort();
  if (m.triangles.minCoeff() < 0 || m.triangles.maxCoeff() >= m.num_vertices()) std::abort();
}

// The fuzzer's input as the bytes parse_mesh reads.
inline std::string_view fuzz_bytes(const std::uint8_t* data, std::size_t size) {
  return {reinterpret_cast<const char*>(data), size};
}

// One libFuzzer input through the `format` reader, checked as above. Returns 0, what
// LLVMFuzzerTestOneInput returns for an input it has finished with.
inline int fuzz_mesh_reader(const std::uint8_t* data, std::size_t size, MeshFormat format,
                            const MeshReadOptions& options = {}) {
  // Named "fuzz.obj", "fuzz.stl", ... in parse_mesh's messages.
  const std::string name = "fuzz." + std::string(to_string(format));
  check_parse_contract(parse_mesh(fuzz_bytes(data, size), format, name, options));
  return 0;
}

}  // namespace hc::testing
