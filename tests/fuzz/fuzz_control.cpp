// libFuzzer target for rigd's control-request decoder and rigctl's reply decoder: arbitrary bytes
// are decoded line by line. A request that decodes must re-encode to a request that decodes to the
// same thing. Errors are the expected outcome; crashes, hangs and sanitizer reports are bugs.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "rig_daemon/daemon/control_protocol.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::string_view text(reinterpret_cast<const char*>(data), size);
  while (true) {
    const std::size_t nl = text.find('\n');
    const std::string_view line = text.substr(0, nl);
    if (hc::Result<hc::rig::Request> r = hc::rig::decode_request(line); r.ok()) {
      hc::Result<hc::rig::Request> again = hc::rig::decode_request(hc::rig::encode_request(*r));
      if (!again.ok() || again->id != r->id || again->command != r->command ||
          again->plan != r->plan || again->plan_name != r->plan_name)
        __builtin_trap();
    }
    (void)hc::rig::decode_reply(line);
    if (nl == std::string_view::npos) break;
    text.remove_prefix(nl + 1);
  }
  return 0;
}
