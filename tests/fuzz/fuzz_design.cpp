// libFuzzer target for the design-file reader (fabrication/composite): arbitrary bytes parsed as a
// design; a successful parse has one valid material per cell, gives a print model that validates,
// and round-trips.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "fabrication/composite/design_file.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  hc::Result<hc::composite::DesignFile> d = hc::composite::parse_design(text, "fuzz.json");
  if (!d.ok()) return 0;
  if (static_cast<int>(d->cells.size()) != d->grid.num_cells()) __builtin_trap();
  for (int c : d->cells)
    if (c < 0 || c >= static_cast<int>(d->materials.size())) __builtin_trap();
  // Cell counts in fuzzed files can be large; the print model is checked on small ones.
  if (d->grid.num_cells() <= 64 &&
      !hc::printfile::validate(hc::composite::design_print_model(*d)).ok())
    __builtin_trap();
  const std::string again = hc::dump_json(hc::composite::design_to_json(*d));
  if (!hc::composite::parse_design(again, "again.json").ok()) __builtin_trap();
  return 0;
}
