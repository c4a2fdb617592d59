// The design file of `hardcopy design composite -o DESIGN.json` and its uses: the composite as a
// material for any simulation of the same specimen (`hardcopy simulate` with {"file": DESIGN.json})
// and the multi-material print file (fabrication/export).
//
// JSON (version 1; SI units):
//   {"format": "hardcopy.design", "version": 1,
//    "specimen": {"box_m": [[x0, y0, z0], [x1, y1, z1]]},   // the specimen it was designed on
//    "cells": {"x_m": [...], "y_m": [...], "z_m": [...]},    // cell boundaries per axis
//    "materials": [{"name": N, "printer_material": M, "colour": "#RRGGBB",
//                   "base": {hardcopy.base_material document}}, ...],
//    "design": [N, ...],          // material name per cell: x fastest, then y, then z (bottom first)
//    "report": {...}}             // optional: the search's report
// A design is self-contained: it embeds the base materials it uses.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "common/json.h"
#include "common/status.h"
#include "common/tet_mesh.h"
#include "fabrication/composite/composite.h"
#include "fabrication/composite/library.h"
#include "fabrication/export/multi_material_3mf.h"
#include "processing/fem/material_model.h"

namespace hc::composite {

inline constexpr std::string_view kDesignFormat = "hardcopy.design";
inline constexpr int kDesignVersion = 1;

struct DesignMaterial {
  std::string name;
  std::string printer_material;
  std::array<std::uint8_t, 3> colour{};
  BaseMaterialFile base;
};

struct DesignFile {
  CellGrid grid;
  std::vector<DesignMaterial> materials;
  std::vector<int> cells;  // index into materials, one per cell
  Json report;             // object or null
};

// The design of `cells` (indices into `library`) on `grid`; only the materials used are embedded.
DesignFile make_design_file(const CellGrid& grid, const Library& library,
                            const std::vector<int>& cells, Json report = nullptr);

Result<DesignFile> parse_design(std::string_view text, std::string_view name);
Result<DesignFile> read_design(const std::filesystem::path& path);
Json design_to_json(const DesignFile& design);
Status save_design(const std::filesystem::path& path, const DesignFile& design);
// True when the text is a design document (its "format"), for tools that accept several files.
bool is_design_document(std::string_view text);

// The design as a material for a mesh of its specimen (each element gets its cell's base
// material). invalid_argument when the mesh's box is not the design's specimen (within 1e-6 of
// its size): "a target on a different specimen".
Result<std::unique_ptr<fem::MaterialModel>> design_material(const DesignFile& design,
                                                            const TetMesh& mesh);

// The print model: one object, one box volume per cell with its printer material; printer
// materials (extruders) in the order they first appear in design.materials.
printfile::MultiMaterialModel design_print_model(const DesignFile& design,
                                                 std::string object_name = "composite");

}  // namespace hc::composite
