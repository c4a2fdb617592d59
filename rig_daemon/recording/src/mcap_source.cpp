// The linear scan over a Source (mcap_source.h).
#include "mcap_source.h"

namespace hc::recording {

Result<LinearScanResult> scan_source(const Source& src,
                                     const std::function<Status(const LinearRecord&)>& on_record,
                                     std::uint64_t max_record_size) {
  Bytes buf;
  if (src.size() < kMagic.size())
    return invalid_argument(
        fmt::format("{}: {} bytes, too short for MCAP magic", src.name(), src.size()));
  HC_RETURN_IF_ERROR(src.read(0, kMagic.size(), buf));
  if (!is_magic(buf))
    return invalid_argument(fmt::format("{}: offset 0: not an MCAP file (bad magic)", src.name()));
  LinearScanResult res;
  std::uint64_t off = kMagic.size();
  res.end_offset = off;
  const std::uint64_t size = src.size();
  while (true) {
    if (size - off < kRecordPrefixSize) {
      res.truncated = true;
      res.stop_reason =
          fmt::format("offset {}: file ends {} bytes into a record prefix", off, size - off);
      if (size == off) res.stop_reason = fmt::format("offset {}: file ends before the Footer", off);
      return res;
    }
    Bytes prefix;
    HC_RETURN_IF_ERROR(src.read(off, kRecordPrefixSize, prefix));
    const std::uint8_t opcode = prefix[0];
    const std::uint64_t len = read_u64(prefix.data() + 1);
    if (opcode == 0) {
      res.stop_reason = fmt::format("offset {}: invalid opcode 0x00", off);
      return res;
    }
    if (len > size - off - kRecordPrefixSize) {
      res.truncated = true;
      res.truncated_opcode = opcode;
      res.stop_reason =
          fmt::format("offset {}: {} record of {} bytes cut off by the end of the file", off,
                      opcode_name(opcode), len);
      return res;
    }
    if (len > max_record_size) {
      res.stop_reason = fmt::format("offset {}: {} record length {} exceeds the limit {}", off,
                                    opcode_name(opcode), len, max_record_size);
      return res;
    }
    HC_RETURN_IF_ERROR(src.read(off + kRecordPrefixSize, len, buf));
    HC_RETURN_IF_ERROR(on_record(LinearRecord{off, opcode, ByteSpan(buf)}));
    off += kRecordPrefixSize + len;
    res.end_offset = off;
    if (opcode == static_cast<std::uint8_t>(Opcode::kFooter)) {
      if (size - off >= kMagic.size()) {
        Bytes magic;
        HC_RETURN_IF_ERROR(src.read(off, kMagic.size(), magic));
        if (is_magic(magic)) {
          res.reached_footer = true;
          return res;
        }
      }
      res.truncated = true;
      res.stop_reason = fmt::format("offset {}: Footer not followed by the closing magic", off);
      return res;
    }
  }
}

}  // namespace hc::recording
