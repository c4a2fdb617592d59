// libFuzzer target for the base-material library reader (fabrication/composite): arbitrary bytes
// parsed as a library in a scratch folder holding one valid base material ("base.json"); a
// successful parse lists at least one material with a name and a printer material.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string_view>

#include "common/file_io.h"
#include "fabrication/composite/library.h"

namespace {

const std::filesystem::path& scratch() {
  static const std::filesystem::path dir = [] {
    const auto d = std::filesystem::temp_directory_path() /
                   ("hc_fuzz_library_" + std::to_string(::getpid()));
    std::filesystem::create_directories(d);
    (void)hc::write_file_atomic(
        d / "base.json",
        R"({"format": "hardcopy.base_material", "version": 1, "name": "b", "model": "isotropic",
            "centres": [[0, 0, 0]], "values": [[1e5, 5e4]], "limits": {"min_modulus_pa": 1}})");
    return d;
  }();
  return dir;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  hc::Result<hc::composite::Library> lib = hc::composite::parse_library(text, "fuzz.json", scratch());
  if (!lib.ok()) return 0;
  if (lib->materials.empty()) __builtin_trap();
  for (const auto& m : lib->materials)
    if (m.name.empty() || m.printer_material.empty()) __builtin_trap();
  return 0;
}
