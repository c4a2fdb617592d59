// gzip for .ply.gz, through zlib, with a cap on the inflated size against zip bombs.
#include <zlib.h>

#include "mesh_io_internal.h"

namespace hc::mesh_io {
namespace {

constexpr int kGzipWindowBits = 15 + 16;  // 2^15 window, gzip wrapper (zlib manual, deflateInit2)
constexpr int kMemLevel = 8;              // zlib's default
constexpr std::size_t kInflateChunk = std::size_t{1} << 20;
// First output buffer: a few times the input (mesh text compresses 3-5x), at least 64 KiB.
constexpr std::size_t kMinOutputGuess = std::size_t{64} << 10;
constexpr std::size_t kOutputGuessRatio = 4;

}  // namespace

Result<std::string> gzip_compress(std::string_view bytes) {
  z_stream zs{};
  if (deflateInit2(&zs, Z_DEFAULT_COMPRESSION, Z_DEFLATED, kGzipWindowBits, kMemLevel,
                   Z_DEFAULT_STRATEGY) != Z_OK)
    return internal_error("zlib deflateInit2 failed");
  std::string out;
  out.resize(
      deflateBound(&zs, static_cast<uLong>(std::min<std::size_t>(bytes.size(), UINT32_MAX))) + 64);
  zs.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(bytes.data()));
  std::size_t in_left = bytes.size();
  std::size_t produced = 0;
  int rc = Z_OK;
  while (rc != Z_STREAM_END) {
    // zlib counts in uInt: feed inputs over 4 GiB in pieces.
    if (zs.avail_in == 0 && in_left > 0) {
      const auto take = static_cast<uInt>(std::min<std::size_t>(in_left, UINT32_MAX / 2));
      zs.avail_in = take;
      in_left -= take;
    }
    if (produced == out.size()) out.resize(out.size() * 2);
    zs.next_out = reinterpret_cast<Bytef*>(out.data() + produced);
    const auto room =
        static_cast<uInt>(std::min<std::size_t>(out.size() - produced, UINT32_MAX / 2));
    zs.avail_out = room;
    rc = deflate(&zs, in_left == 0 ? Z_FINISH : Z_NO_FLUSH);
    produced += room - zs.avail_out;
    if (rc != Z_OK && rc != Z_STREAM_END && rc != Z_BUF_ERROR) {
      deflateEnd(&zs);
      return internal_error(fmt::format("zlib deflate failed ({})", rc));
    }
  }
  deflateEnd(&zs);
  out.resize(produced);
  return out;
}

Result<std::string> gzip_inflate(std::string_view bytes, std::string_view name, InflateCap& cap) {
  z_stream zs{};
  if (inflateInit2(&zs, kGzipWindowBits) != Z_OK) return internal_error("zlib inflateInit2 failed");
  struct End {
    z_stream* zs;
    ~End() { inflateEnd(zs); }
  } end{&zs};

  // Grown geometrically from a guess, so a small file does not pay for a large buffer.
  std::string out;
  const std::size_t guess = std::max(kMinOutputGuess, kOutputGuessRatio * bytes.size());
  std::size_t produced = 0;
  std::size_t in_used = 0;
  for (;;) {
    HC_ASSIGN_OR_RETURN(const std::size_t limit, cap.cap(std::string_view(out.data(), produced)));
    if (produced > limit)
      return error_at(
          name, 0,
          fmt::format("gzip data inflates to more than {} bytes, the most a mesh within "
                      "MeshReadOptions::max_elements can need (a zip bomb?)",
                      limit));
    // One byte past the cap, so that output of exactly `limit` bytes can still reach its end.
    if (produced == out.size())
      out.resize(std::min(limit + 1, out.empty() ? guess : 2 * out.size()));
    const std::size_t want = std::min({kInflateChunk, out.size() - produced, limit + 1 - produced});
    zs.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(bytes.data() + in_used));
    zs.avail_in = static_cast<uInt>(std::min<std::size_t>(bytes.size() - in_used, kInflateChunk));
    const uInt in_before = zs.avail_in;
    zs.next_out = reinterpret_cast<Bytef*>(out.data() + produced);
    zs.avail_out = static_cast<uInt>(want);
    const int rc = inflate(&zs, Z_NO_FLUSH);
    produced += want - zs.avail_out;
    in_used += in_before - zs.avail_in;
    if (rc == Z_STREAM_END) {
      // Concatenated gzip members form one stream (RFC 1952 §2.2).
      if (in_used == bytes.size()) break;
      if (bytes.size() - in_used >= 2 && is_gzip(bytes.substr(in_used))) {
        inflateReset(&zs);
        continue;
      }
      return error_at(
          name, 0,
          fmt::format("byte {}: unexpected data after the end of the gzip stream", in_used));
    }
    if (rc == Z_BUF_ERROR && in_used == bytes.size() && zs.avail_out != 0)
      return error_at(name, 0,
                      fmt::format("gzip data is truncated: it ends after {} compressed bytes "
                                  "without the end-of-stream marker",
                                  bytes.size()));
    if (rc != Z_OK && rc != Z_BUF_ERROR)
      return error_at(name, 0,
                      fmt::format("byte {}: corrupt gzip data ({})", in_used,
                                  zs.msg != nullptr ? zs.msg : "zlib error"));
  }
  out.resize(produced);
  return out;
}

}  // namespace hc::mesh_io
