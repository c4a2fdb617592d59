// Force–displacement samples (ARCHITECTURE.md, "Data between the offline tools"): the input of the
// material fitter. One file holds a tetrahedral mesh and a list of examples; each example is one
// static deformation of that mesh under known forces (thesis Sec. 4.3.1: probing region with known
// forces, attached region with zero displacement, free region with zero force).
//
// JSON layout (version 1; SI units: metres and newtons):
//   {
//     "format": "hardcopy.samples", "version": 1,
//     "units": {"length": "m", "force": "N"},           // optional; if present must be exactly
//     this "mesh": {"nodes": [[x,y,z], ...], "tets": [[a,b,c,d], ...]}     // inline, zero-based,
//     or "mesh": {"node_file": "block.node", "ele_file": "block.ele"}   // TetGen files, paths
//     relative
//                                                                    // to the samples file
//     "examples": [
//       {
//         "name": "ex0",                                             // optional
//         "probe": {"shape": "sphere"|"flat"|"mesh"|"none", "radius_m": r,
//                   "position_m": [x,y,z], "direction": [dx,dy,dz], "mesh": "probe.obj"},
//         "forces": [{"node": i, "force_n": [fx,fy,fz]}, ...],       // applied nodal forces
//         "positions_m": [[x,y,z], ...],                             // #N measured positions
//         "visible": [1, 0, ...],                                    // optional, #N; default all 1
//         "fixed_nodes": [i, ...]                                    // held at rest positions
//       }, ...
//     ]
//   }
// Positions of invisible nodes are stored (e.g. the simulated value, or the rest position) but
// never used as measurements. Fixed nodes are held at their rest positions regardless of
// "positions_m".
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "common/json.h"
#include "common/status.h"
#include "common/tet_mesh.h"

namespace hc::material {

inline constexpr std::string_view kSamplesFormat = "hardcopy.samples";
inline constexpr int kSamplesVersion = 1;

// The contact probe that produced an example (kept for provenance and re-simulation; the fitter
// uses only the nodal forces).
struct ProbePose {
  std::string shape = "none";  // "sphere", "flat" (flat-ended cylinder), "mesh" or "none"
  double radius_m = 0;         // sphere / disk radius; 0 for "mesh" and "none"
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();   // sphere centre / disk centre at contact
  Eigen::Vector3d direction = Eigen::Vector3d(0, 0, -1);  // unit push direction
  std::string mesh;  // probe surface mesh file for "mesh" (relative to the samples file)
};

struct NodalForce {
  int node = 0;
  Eigen::Vector3d force_n = Eigen::Vector3d::Zero();
};

struct Example {
  std::string name;
  ProbePose probe;
  std::vector<NodalForce> forces;     // applied forces (N) on nodes; a node may appear once
  MatrixX3d positions_m;              // #N by 3 measured (deformed) node positions
  std::vector<std::uint8_t> visible;  // #N; 1 = position measured, 0 = occluded
  std::vector<int> fixed_nodes;       // sorted, unique; held at rest positions

  // Stacked 3N force vector (N).
  Eigen::VectorXd force_vector(Eigen::Index num_nodes) const;
};

struct Samples {
  TetMesh mesh;
  // When the mesh came from TetGen files: their paths as written in the file (relative to the
  // samples file). Empty: the mesh is stored inline.
  std::string node_file;
  std::string ele_file;
  std::vector<Example> examples;

  // Largest displacement |x̄ − x0| (m) over the visible, non-fixed nodes of example `i`.
  double max_displacement_m(std::size_t i) const;
  // Largest of max_displacement_m over all examples.
  double max_displacement_m() const;
};

// Checks everything a reader checks (mesh indices and orientation-independent non-degeneracy,
// finite coordinates and forces, sizes #N, node indices in range, unique force nodes, sorted unique
// fixed nodes, unit probe direction, known probe shape, at least one example). Messages name the
// example and entry: "examples[3].forces[2].node: 1207 is out of range (mesh has 1200 nodes)".
Status validate_samples(const Samples& samples);

// Parses a samples document. `name` prefixes error messages (usually the path); TetGen mesh files
// are resolved against `base_dir`. Fails with kInvalidArgument on malformed JSON, a wrong format or
// unknown version, missing keys, wrong sizes, NaN/infinite numbers, or out-of-range indices.
Result<Samples> parse_samples(std::string_view text, std::string_view name,
                              const std::filesystem::path& base_dir);
// Reads and parses the file (adds kNotFound / kIoError).
Result<Samples> load_samples(const std::filesystem::path& path);

// The JSON document (always with the mesh inline unless node_file/ele_file are set).
Json samples_to_json(const Samples& samples);
// Validates, then writes atomically (no half-written file on failure).
Status save_samples(const std::filesystem::path& path, const Samples& samples);

}  // namespace hc::material
