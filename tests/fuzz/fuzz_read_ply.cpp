// libFuzzer target: the PLY reader on arbitrary bytes (ascii, binary of either endianness, gzip by
// magic), and on the same bytes gzip-compressed.
// Beyond the sanitizers, it checks the contract of parse_mesh: an error is kInvalidArgument, and
// an accepted mesh has finite coordinates and every index in range.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>

#include <zlib.h>

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

// The input gzip-compressed, so the fuzzer's mutations of a PLY also reach the inflate path with a
// valid stream (raw fuzz bytes starting 1f 8b only exercise zlib's error handling).
std::string gzip(std::string_view plain) {
  z_stream zs{};
  if (deflateInit2(&zs, Z_BEST_SPEED, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK)
    std::abort();
  std::string out(deflateBound(&zs, static_cast<uLong>(plain.size())) + 64, '\0');
  zs.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(plain.data()));
  zs.avail_in = static_cast<uInt>(plain.size());
  zs.next_out = reinterpret_cast<Bytef*>(out.data());
  zs.avail_out = static_cast<uInt>(out.size());
  if (deflate(&zs, Z_FINISH) != Z_STREAM_END) std::abort();
  out.resize(zs.total_out);
  deflateEnd(&zs);
  return out;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  check(hc::parse_mesh(bytes, hc::MeshFormat::kPly, "fuzz.ply"));
  check(hc::parse_mesh(gzip(bytes), hc::MeshFormat::kPly, "fuzz.ply.gz"));
  return 0;
}
