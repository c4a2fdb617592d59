// libFuzzer target for rigd's control-request decoder, its line framer and rigctl's reply decoder.
// The input is fed to RequestFramer in chunks whose sizes come from the input itself, then
// end-of-file: the lines it yields must be the input's lines (every complete line, plus the
// unterminated rest at end-of-file, blank ones skipped) however the bytes were split, unless a
// line grew past the limit. Each line is decoded as a request (one that decodes must re-encode to
// the same request) and as a reply. Errors are the expected outcome; crashes, hangs and sanitizer
// reports are bugs.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "rig_daemon/daemon/control_protocol.h"

namespace {

// The framer's small limit lets the fuzzer reach the overlong path with short inputs.
constexpr std::size_t kFuzzMaxLine = 4096;

std::vector<std::string> reference_lines(std::string_view text) {
  std::vector<std::string> out;
  while (!text.empty()) {
    const std::size_t nl = text.find('\n');
    const std::string_view line = text.substr(0, nl);
    if (!line.empty() && line != "\r") out.emplace_back(line);
    if (nl == std::string_view::npos) break;
    text.remove_prefix(nl + 1);
  }
  return out;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  hc::rig::RequestFramer framer(kFuzzMaxLine);
  std::vector<std::string> lines;
  std::size_t at = 0;
  std::uint32_t state = size > 0 ? data[0] : 1;
  while (at < size) {
    state = state * 1103515245u + 12345u;
    const std::size_t n = std::min<std::size_t>(size - at, 1 + (state >> 16) % 97);
    framer.append(text.substr(at, n));
    at += n;
    while (std::optional<std::string> l = framer.next()) lines.push_back(std::move(*l));
  }
  framer.finish();
  while (std::optional<std::string> l = framer.next()) lines.push_back(std::move(*l));
  if (!framer.drained()) __builtin_trap();
  if (!framer.overlong() && lines != reference_lines(text)) __builtin_trap();

  for (const std::string& line : lines) {
    if (hc::Result<hc::rig::Request> r = hc::rig::decode_request(line); r.ok()) {
      hc::Result<hc::rig::Request> again = hc::rig::decode_request(hc::rig::encode_request(*r));
      if (!again.ok() || again->id != r->id || again->command != r->command ||
          again->plan != r->plan || again->plan_name != r->plan_name)
        __builtin_trap();
    }
    (void)hc::rig::decode_reply(line);
  }
  return 0;
}
