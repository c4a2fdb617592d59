// libFuzzer target: the SVG outline reader (expat + path grammar + transforms + arcs) on
// arbitrary bytes. Beyond the sanitizers it checks parse_svg's contract: either an error, or a
// polygon that passes validate() (closed loops of >= 3 finite points with an area).
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "fabrication/abstraction/svg.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  auto p = hc::abstraction::parse_svg(text, "fuzz");
  if (p.ok() && !hc::abstraction::validate(*p, "fuzz").ok()) std::abort();
  return 0;
}
