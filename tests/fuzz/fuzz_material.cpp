// libFuzzer target for the material reader: arbitrary bytes are parsed as a material document; a
// successful parse must validate, evaluate to physically valid (lambda, alpha) for every element
// at a few strains, and round-trip.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "processing/material/material.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  hc::Result<hc::material::Material> m = hc::material::parse_material(text, "fuzz.json");
  if (!m.ok()) return 0;
  if (!m->validate().ok()) __builtin_trap();
  hc::material::RbfMaterial model(*m);
  const Eigen::Index n =
      model.num_elements() < 0 ? 3 : std::min<Eigen::Index>(model.num_elements(), 64);
  hc::fem::Vector6d e;
  e << 0.01, -0.02, 0.03, 0.0, 0.1, -0.05;
  for (Eigen::Index i = 0; i < n; ++i) {
    const hc::fem::LambdaAlpha p = model.params(i, e);
    // Huge weights may overflow to inf; finite results must be valid.
    if (std::isfinite(p.lambda) && std::isfinite(p.alpha) &&
        !(p.lambda > 0 && p.alpha >= 0 && p.alpha <= 0.5 * p.lambda))
      __builtin_trap();
  }
  const std::string again = hc::dump_json(hc::material::material_to_json(*m));
  if (!hc::material::parse_material(again, "again.json").ok()) __builtin_trap();
  return 0;
}
