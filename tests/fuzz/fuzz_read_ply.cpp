// libFuzzer target: the PLY reader on arbitrary bytes (ascii, binary of either endianness, gzip by
// magic), and on the same bytes gzip-compressed.
// Beyond the sanitizers, it checks the contract of parse_mesh (see fuzz_mesh_reader.h).
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>

#include <zlib.h>

#include "fuzz_mesh_reader.h"

namespace {

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
  hc::testing::fuzz_mesh_reader(data, size, hc::MeshFormat::kPly);
  const std::string gz = gzip(hc::testing::fuzz_bytes(data, size));
  hc::testing::check_parse_contract(hc::parse_mesh(gz, hc::MeshFormat::kPly, "fuzz.ply.gz"));
  return 0;
}
