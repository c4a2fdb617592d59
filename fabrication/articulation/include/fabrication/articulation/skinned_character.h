// A skinned character as the articulation pipeline sees it (thesis Sec. 6.2.1): a rest-pose
// triangle mesh, linear-blend-skinning weights per vertex over a tree of bones, and the
// animation clips of the file, all in one model frame in metres (+Y up), scaled to the height the
// user asked for. Decoders (skinned_reader.h) fill it; everything after them reads it only.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "common/mesh.h"
#include "common/status.h"

namespace hc::articulation {

// One bone of the rig (a skin joint of the file). Bones are ordered parents first.
struct Bone {
  std::string name;
  int parent = -1;  // nearest ancestor node that is a bone; -1 for a root of the bone forest
  int depth = 0;    // depth of the bone's node in the file's node tree (root closeness)
  // The rig's joint: the bone node's origin in the rest pose, model frame (m).
  Eigen::Vector3d rest_origin_m = Eigen::Vector3d::Zero();
};

// One weighted influence of a bone on a vertex. `local` is the vertex's bind position in the
// bone's frame (file units, before the model scaling): posed = scale * (G_bone * local) + shift.
struct Influence {
  int bone = 0;
  double weight = 0.0;  // renormalised: a vertex's weights sum to 1
  Eigen::Vector3d local = Eigen::Vector3d::Zero();
};

// An animation clip sampled at frames: for each frame and bone the bone node's global transform
// (file units, the scene root's frame).
struct Clip {
  std::string name;
  std::vector<double> times_s;
  std::vector<std::vector<Eigen::Affine3d>> bone_globals;  // [frame][bone]
};

// What reading found that the user should know (weights renormalised, traps avoided).
struct SkinnedReadReport {
  std::string format;          // importer that read it ("glTF2", "FBX", "Collada", "X", ...)
  std::int64_t meshes = 0;     // triangle meshes of the file that were used
  std::int64_t input_vertices = 0;
  std::int64_t renormalised_vertices = 0;  // weight sum differed from 1 by more than 1e-3
  double min_weight_sum = 0.0;             // before renormalisation, over weighted vertices
  double max_weight_sum = 0.0;
  std::int64_t unweighted_vertices = 0;  // no weight at all: given their nearest neighbour's
  std::int64_t pivot_nodes = 0;          // FBX "$AssimpFbx$" helper nodes passed through
  std::int64_t bones_shared_by_meshes = 0;  // bones that influence vertices of several meshes
  double file_height = 0.0;   // rest-pose extent along +Y, file units
  double scale = 1.0;         // model metres per file unit
  std::vector<std::string> warnings;
};

struct SkinnedCharacter {
  std::string source;  // file name, for messages
  // Rest pose (the node tree's own transforms), model frame in metres: +Y up, feet at y = 0,
  // centred in x and z. All meshes of the file concatenated, triangles only.
  TriangleMesh mesh;
  std::vector<int> vertex_mesh;  // #V: which mesh of the file the vertex came from
  // Compressed rows: the influences of vertex i are influences[influence_start[i] ..
  // influence_start[i + 1]); weights sum to 1 and each is > 0.
  std::vector<std::int64_t> influence_start;
  std::vector<Influence> influences;
  std::vector<Bone> bones;
  std::vector<Clip> clips;
  // model = scale * file + shift (the similarity applied to rest pose and clips).
  double scale = 1.0;
  Eigen::Vector3d shift = Eigen::Vector3d::Zero();
  // Rest-pose global transform of every bone (file units).
  std::vector<Eigen::Affine3d> rest_bone_globals;
  SkinnedReadReport report;

  Eigen::Index num_bones() const { return static_cast<Eigen::Index>(bones.size()); }
  // #V by #bones dense weights (small characters; tests and segmentation helpers).
  Eigen::MatrixXd dense_weights() const;
  // Vertex positions (model frame, m) for the given bone globals (a clip frame or the rest pose),
  // by linear blend skinning (thesis Eq. 6.1). #V by 3.
  MatrixX3d pose(const std::vector<Eigen::Affine3d>& bone_globals) const;
};

// Checks the invariants above (shapes, indices in range, weights positive and summing to 1,
// bones parents-first without cycles, clip frames complete). kInvalidArgument naming what is
// wrong; used by decoders before they return and by tests.
Status validate(const SkinnedCharacter& character);

}  // namespace hc::articulation
