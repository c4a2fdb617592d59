// libFuzzer target for the base-material reader (fabrication/composite): arbitrary bytes parsed as
// a base-material document; a successful parse must evaluate to feasible parameters (positive-
// definite elasticity) at a few strains and round-trip.
#include <Eigen/Eigenvalues>
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "fabrication/composite/library.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  hc::Result<hc::composite::BaseMaterialFile> f = hc::composite::parse_base_material(text, "fuzz.json");
  if (!f.ok()) return 0;
  hc::fem::Vector6d e;
  e << 0.01, -0.02, 0.03, 0.0, 0.1, -0.05;
  for (const double s : {0.0, 1.0, -3.0}) {
    const hc::fem::Matrix6d m = f->material.elasticity(s * e);
    // Huge values may overflow to inf; finite results must be positive definite.
    if (m.allFinite() &&
        Eigen::SelfAdjointEigenSolver<hc::fem::Matrix6d>(m).eigenvalues().minCoeff() <= 0)
      __builtin_trap();
  }
  const std::string again = hc::dump_json(hc::composite::base_material_to_json(*f));
  if (!hc::composite::parse_base_material(again, "again.json").ok()) __builtin_trap();
  return 0;
}
