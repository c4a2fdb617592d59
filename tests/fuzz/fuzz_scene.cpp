// libFuzzer target for the SCENE.json reader of `hardcopy simulate`: arbitrary bytes are parsed as
// a scene; a scene that parses is checked for the invariants the simulator relies on (finite,
// positive sizes and loads, steps in range, a known material/probe kind). Nothing is meshed or
// simulated (that would make the target slow); errors are the expected outcome, crashes and
// sanitizer reports are bugs.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "processing/scene/scene.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const hc::Result<hc::scene::Scene> s = hc::scene::parse_scene(text, "fuzz.json", "/nonexistent");
  if (!s.ok()) return 0;
  const hc::scene::Scene& sc = *s;
  bool ok = sc.steps >= 1 && sc.steps <= 10000 && std::isfinite(sc.load.value) && sc.load.value > 0;
  if (sc.specimen.kind == hc::scene::SpecimenSpec::Kind::kBox) {
    ok = ok && sc.specimen.box_m.allFinite() && sc.specimen.box_m.minCoeff() > 0;
  }
  ok = ok && sc.probe.position_m.allFinite() && sc.probe.direction.norm() > 0;
  if (sc.probe.shape != hc::scene::ProbeSpec::Shape::kMesh) ok = ok && sc.probe.radius_m > 0;
  if (sc.material.kind == hc::scene::MaterialKind::kLinear ||
      sc.material.kind == hc::scene::MaterialKind::kNeoHookean) {
    ok = ok && sc.material.youngs_pa > 0 && sc.material.poisson > -1 && sc.material.poisson < 0.5;
  }
  for (const auto& l : sc.material.layers) ok = ok && l.z_max_m > l.z_min_m && l.youngs_pa > 0;
  if (!ok) std::abort();  // the reader accepted a scene the simulator cannot run
  return 0;
}
