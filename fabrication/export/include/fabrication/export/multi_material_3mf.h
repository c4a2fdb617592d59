// Multi-material print files: one 3MF (millimetres) that multi-extruder slicers of both families
// read with a material per part.
//
// * The core model and the Materials extension are written by lib3mf: one <basematerials> group
//   whose entries are the printer materials (opaque display colours: lib3mf's default alpha is
//   transparent), one mesh object per Object holding all of its volumes' triangles in volume
//   order, each triangle carrying its volume's base material (pid/pindex), one build item per
//   object, unit millimetre.
// * PrusaSlicer ignores pid/pindex; it reads Metadata/Slic3r_PE_model.config, which splits each
//   object's triangles into volumes (firstid/lastid) with a name, volume_type ModelPart and the
//   extruder (1-based: the material's index + 1).
// * Bambu Studio and OrcaSlicer read Metadata/model_settings.config: the same ranges as <part>
//   entries (subtype normal_part) with a name and the extruder.
// Both metadata files are added to the package as lib3mf attachments.
//
// Volumes of one object may touch (e.g. stacked layers); slicers split the object's regions per
// volume. Geometry is given in metres (SI inside) and converted to millimetres here.
#pragma once

#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "common/mesh.h"
#include "common/status.h"

namespace hc::printfile {

// A printer material (filament): its name and opaque display colour. Extruder = index + 1.
struct PrintMaterial {
  std::string name;
  std::array<std::uint8_t, 3> rgb{128, 128, 128};
};

struct PrintVolume {
  std::string name;
  TriangleMesh mesh;  // metres, closed, outward oriented
  int material = 0;   // index into MultiMaterialModel::materials
};

struct PrintObject {
  std::string name;
  std::vector<PrintVolume> volumes;
};

struct MultiMaterialModel {
  std::vector<PrintMaterial> materials;
  std::vector<PrintObject> objects;
};

// invalid_argument (naming the object / volume / material) for no materials or objects, an object
// without volumes, a volume without triangles, out-of-range vertex or material indices, non-finite
// coordinates, empty names or names with control characters.
Status validate(const MultiMaterialModel& model);

// Validates, then writes the 3MF atomically (nothing half-written on failure; lib3mf's errors are
// returned as io_error / internal with its message).
Status write_multi_material_3mf(const std::filesystem::path& path, const MultiMaterialModel& model);

// The two slicer metadata documents (exposed for tests and for other writers).
std::string slic3r_model_config(const MultiMaterialModel& model);
std::string bambu_model_settings(const MultiMaterialModel& model);

// A closed, outward-oriented box (8 vertices, 12 triangles) in the box's units.
TriangleMesh box_triangles(const Eigen::AlignedBox3d& box);

}  // namespace hc::printfile
