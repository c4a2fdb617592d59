// Base-material files and the base-material library (ARCHITECTURE.md, "materials: per material
// (base) the RBF centres in strain space and their parameters").
//
// A base material (`hardcopy fit base -o BASE.json`), SI units (Pa; strains dimensionless):
//   {"format": "hardcopy.base_material", "version": 1,
//    "name": "foam_soft",
//    "printer_material": "TPU 85A",                 // optional: what to load into the printer
//    "model": "isotropic" | "transverse",
//    "units": {"stress": "Pa"},                     // optional; if present exactly this
//    "centres": [[f1, f2, f3], ...],                // P centres: isotropic (I1, sqrt J2, cbrt J3),
//                                                   // transverse the strain 6-vector (Eq. 4.1)
//    "values": [[lambda, mu], ...]                  // P parameter vectors (Pa): isotropic
//            | [[E11, E12, E13, E33, E44], ...],    // or transverse (Eq. 5.6)
//    "limits": {"min_modulus_pa": f, "min_poisson": -0.9, "max_poisson": 0.49},
//    "fit": {...}}                                  // optional report, kept as written
//
// A library (`hardcopy design composite --library LIB.json`), paths relative to the library file:
//   {"materials": [{"name": "foam_soft", "file": "foam_soft.json", "printer_material": "TPU 85A",
//                   "colour": "#D04020"}, ...]}    // colour optional (#RRGGBB, opaque)
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/json.h"
#include "common/status.h"
#include "fabrication/composite/base_material.h"

namespace hc::composite {

inline constexpr std::string_view kBaseMaterialFormat = "hardcopy.base_material";
inline constexpr int kBaseMaterialVersion = 1;

struct BaseMaterialFile {
  std::string name;
  std::string printer_material;  // may be empty
  BaseMaterial material;
  Json fit;  // the fit report (object) or null
};

// `name` prefixes messages. invalid_argument naming the key for malformed JSON, a wrong format or
// version, unknown keys, units other than Pa, sizes that do not match the model, non-finite
// numbers, repeated centres or invalid limits.
Result<BaseMaterialFile> parse_base_material(std::string_view text, std::string_view name);
Result<BaseMaterialFile> read_base_material(const std::filesystem::path& path);
Json base_material_to_json(const BaseMaterialFile& file);
// Writes atomically (no half-written file on failure).
Status save_base_material(const std::filesystem::path& path, const BaseMaterialFile& file);

struct LibraryEntry {
  std::string name;
  std::string printer_material;  // defaults to the base file's, then to the name
  std::filesystem::path file;    // as resolved (relative paths against the library's folder)
  std::array<std::uint8_t, 3> colour{};  // opaque display colour (RGB)
  BaseMaterialFile base;
};

struct Library {
  std::vector<LibraryEntry> materials;
  std::vector<BaseMaterial> models() const;
  std::vector<std::string> names() const;
  // The index of a material by name, or nullopt.
  std::optional<int> find(std::string_view name) const;
};

// Reads the library and every base-material file it names. invalid_argument for an empty library
// ("the library lists no base materials"), repeated names, a missing or unreadable file (naming the
// entry), a bad colour.
Result<Library> parse_library(std::string_view text, std::string_view name,
                              const std::filesystem::path& base_dir);
Result<Library> read_library(const std::filesystem::path& path);

// A distinct opaque colour for material i of n when the library names none (evenly spaced hues).
std::array<std::uint8_t, 3> default_colour(int i, int n);

}  // namespace hc::composite
