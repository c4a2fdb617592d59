// The scene of `hardcopy simulate SCENE.json` (contract in issue 3):
//   {"specimen": {"box_m": [x, y, z], "max_tet_volume_m3": v}          TetGen box [0,x]x[0,y]x[0,z]
//              | {"box_m": [x, y, z], "cells": [nx, ny, nz]}            structured (Kuhn) box
//              | {"mesh": PATH, "scale_to_m": s, "max_tet_volume_m3": v} closed surface -> TetGen
//              (without mesh keys: "contact_elements_per_radius": n, optional, default 4)
//    "material": {"linear": {"youngs_pa": E, "poisson": nu}}            co-rotational FEM
//              | {"neo_hookean": {"youngs_pa": E, "poisson": nu, "stiffening": b}}  hyperelastic
//              reference model (b >= 0 optional, default 0: see hyperelastic/neo_hookean.h)
//              | [{"z_m": [z0, z1], "linear" | "neo_hookean": {...}}, ...]  layers (all of
//              one kind) | {"file": MATERIAL.json}                                data-driven (RBF)
//              material
//    "fixed": "bottom" | [node, ...],
//    "probe": {"shape": "sphere" | "flat" | "mesh", "radius_m": r, "position_m": [x, y, z],
//              "direction": [dx, dy, dz], "mesh": PATH, "scale_to_m": s},
//    "load": {"depth_m": d} | {"force_n": f},
//    "steps": n}                                                         optional, default 10
// Relative paths are resolved against the scene file's folder. Units are SI throughout.
// Without "cells" or "max_tet_volume_m3" the specimen is meshed for the scene's contact: TetGen
// with a size field graded from the probe's expected contact patch to a coarse far field
// (contact_meshing.h); the mesh keys, when given, win. "contact_elements_per_radius" refines that
// mesh: elements of a/n at a contact of radius a (4: a sphere's force within 5 % of Sneddon's for
// 0.25 <= nu <= 0.45, +8.7 % at nu 0; the linear tets' stiffness falls about as 1/n).
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/progress.h"
#include "common/status.h"
#include "common/tet_mesh.h"
#include "processing/fem/contact.h"
#include "processing/fem/incremental.h"
#include "processing/fem/material_model.h"
#include "processing/fem/probe.h"

namespace hc::scene {

struct SpecimenSpec {
  enum class Kind { kBox, kMesh };
  Kind kind = Kind::kBox;
  Eigen::Vector3d box_m = Eigen::Vector3d::Zero();
  double max_tet_volume_m3 = 0;          // 0: TetGen's default sizing
  std::optional<Eigen::Vector3i> cells;  // structured box instead of TetGen
  // Contact-adaptive mesh (no cells, no max_tet_volume_m3): elements per contact radius at the
  // patch; 0 = ContactMeshingOptions' default.
  double contact_elements_per_radius = 0;
  std::filesystem::path mesh;  // kMesh
  double scale_to_m = 1;
};

enum class MaterialKind { kLinear, kNeoHookean, kLayered, kFile };

struct LayerSpec {
  double z_min_m = 0;
  double z_max_m = 0;
  bool neo_hookean = false;
  double youngs_pa = 0;
  double poisson = 0;
  double stiffening = 0;  // neo-Hookean strain stiffening β (dimensionless; 0 for linear)
};

struct MaterialSpec {
  MaterialKind kind = MaterialKind::kLinear;
  double youngs_pa = 0;
  double poisson = 0;
  double stiffening = 0;          // kNeoHookean: strain stiffening β (dimensionless)
  std::vector<LayerSpec> layers;  // kLayered
  std::filesystem::path file;     // kFile
};

struct ProbeSpec {
  enum class Shape { kSphere, kFlat, kMesh };
  Shape shape = Shape::kSphere;
  double radius_m = 0;
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction = -Eigen::Vector3d::UnitZ();
  std::filesystem::path mesh;  // kMesh
  double scale_to_m = 1;
};

struct Scene {
  SpecimenSpec specimen;
  MaterialSpec material;
  bool fixed_bottom = true;
  std::vector<int> fixed_nodes;  // when !fixed_bottom
  ProbeSpec probe;
  fem::Load load;
  int steps = 10;
};

// Parses and validates a scene (missing/unknown keys, wrong types, non-finite or out-of-range
// numbers are invalid_argument naming the key). `base_dir` resolves relative paths.
Result<Scene> parse_scene(std::string_view text, std::string_view name,
                          const std::filesystem::path& base_dir);
Result<Scene> read_scene(const std::filesystem::path& path);

// The specimen's tet mesh (box or surface via processing/meshing) without a contact in view: the
// mesh keys as given, TetGen's quality mesh without a size bound otherwise.
Result<TetMesh> build_specimen(const SpecimenSpec& spec);

// The scene's probe at its start pose (a mesh probe's file is read and scaled to metres).
Result<std::unique_ptr<fem::Probe>> build_probe(const ProbeSpec& probe);

// How a scene's specimen was meshed (`simulate --json` reports it).
struct MeshReport {
  std::string method;  // "structured" (cells), "tetgen" (max_tet_volume_m3), "contact_adaptive"
  long nodes = 0;
  long tets = 0;
  double min_edge_m = 0;
  double max_edge_m = 0;
  // contact_adaptive: the expected patch and the size field graded from it.
  Eigen::Vector3d focus_m = Eigen::Vector3d::Zero();
  double patch_radius_m = 0;
  double fine_size_m = 0;
  double coarse_size_m = 0;
  double growth = 0;
  double elements_per_radius = 0;  // asked for (the fine size is coarser when over the budget)
  double time_s = 0;
};

// The scene's specimen mesh: its mesh keys when given, else graded for the scene's probe and load
// (contact_meshing.h).
Result<TetMesh> build_specimen(const Scene& scene, MeshReport* report = nullptr);

// The nodes the scene holds fixed on `mesh`: "bottom" (the nodes at the lowest z) or the listed
// ones (invalid_argument when one is out of range). Sorted, unique.
Result<std::vector<int>> fixed_nodes(const Scene& scene, const TetMesh& mesh);

struct SimulationResult {
  std::string model;  // "corotational_linear", "corotational_data_driven", "neo_hookean"
  double force_n = 0;
  double depth_m = 0;
  double max_displacement_m = 0;
  std::vector<fem::LoadStep> steps;
  TetMesh mesh;
  MeshReport mesh_report;
  MatrixX3d positions;  // deformed
  double time_s = 0;
  // What makes the answer less trustworthy than the model's usual accuracy (simulate prints them).
  std::vector<std::string> warnings;
};

// A scene whose material is this close to incompressible (largest Poisson's ratio of its linear,
// neo-Hookean or layered material) is warned about: linear tetrahedra lock as ν → ½ and answer too
// stiff. A sphere on the default contact-adaptive mesh (E 0.8 MPa, R 8 mm, d 0.3 mm, half-space
// block) gave +15.7 % at ν 0.49 against Sneddon's closed form, +3.3 % at 0.45 (E 1 MPa, R 5 mm).
inline constexpr double kLockingPoisson = 0.47;

// Builds the material of a {"file": ...} scene material for the specimen's mesh. Rooms above
// processing pass one for their own files (e.g. a composite design, fabrication/composite).
using MaterialLoader = std::function<Result<std::unique_ptr<fem::MaterialModel>>(
    const std::filesystem::path& file, const TetMesh& specimen)>;

// Builds the specimen, the material and the probe and runs the incremental load. A "file" material
// is read as a processing/material file unless `loader` is given. Errors: bad input
// (invalid_argument: inverted/degenerate elements, unreachable probe, fixed node out of range,
// material for a different mesh) or no equilibrium (failed_precondition).
Result<SimulationResult> simulate(const Scene& scene, ProgressReporter* progress = nullptr,
                                  const MaterialLoader& loader = {});

}  // namespace hc::scene
