// Carving (thesis Sec. 6.4.3): the joints' hulls subtracted from the fabrication mesh in one exact
// CSG sequence, the result split into its connected parts, each named after the links it holds;
// and the checks that every joint really separated its two sides. Also the link topology that
// decides which joints can be cut at all: links that touch through a transition without a joint
// are one part, so a joint whose two links are already one part, or that would close a loop of
// parts, cannot work.
#pragma once

#include <string>
#include <vector>

#include "common/mesh.h"
#include "common/progress.h"
#include "common/status.h"
#include "fabrication/articulation/joint.h"
#include "fabrication/articulation/joint_hull.h"

namespace hc::articulation {

// A link pair that touches (a transition of the segmentation), jointed or not.
struct LinkContact {
  int a = -1, b = -1;
};

// Excludes (with a reason) every joint that cannot separate its links or would close a loop of
// parts, strongest joints first. `joints` may already hold excluded ones.
void exclude_unseparable_joints(const std::vector<LinkContact>& contacts, int links,
                                std::vector<Joint>* joints);

struct CarvedPart {
  std::string name;
  TriangleMesh mesh;        // closed; metres
  std::vector<int> links;   // links whose vertices it holds, nearest the root first
};

struct CarveSummary {
  int components = 0;             // of the carved mesh, debris included
  int cavities = 0;               // inward shells kept inside the part that holds them
  int debris_pieces = 0;          // pieces dropped as debris
  double debris_volume_m3 = 0.0;  // their total volume
  bool closed = false;
  std::int64_t self_intersecting_pairs_after_rounding = 0;
  std::vector<int> unseparated;  // joints whose two probe points ended in one part
  std::vector<int> severed;      // joints whose cut bounds a piece that holds no joint
  double time_s = 0.0;
};

// Subtracts the hulls of the non-excluded joints from `fabrication` (F) and splits the result.
// `vertex_link` labels F's vertices; `bone_names` and `bone_depth` name and order the links.
// Pieces that hold no joint and enclose less than `debris_volume_m3` are dropped (counted in the
// summary): crumbs a hull pinched off F's surface.
Result<std::vector<CarvedPart>> carve_parts(
    const TriangleMesh& fabrication, const std::vector<int>& vertex_link,
    const std::vector<std::string>& bone_names, const std::vector<int>& bone_depth,
    const std::vector<Joint>& joints, const std::vector<JointHull>& hulls, double debris_volume_m3,
    ProgressReporter* progress, CarveSummary* summary);

// A point of the joint's moving (child) side and of its fixed (parent) side, inside the material
// of each after carving: the ball's centre and the socket's shell below it; the knuckle's ring and
// the pin's axis.
Eigen::Vector3d child_probe(const Joint& joint);
Eigen::Vector3d parent_probe(const Joint& joint);

// Connected components of a mesh through shared vertices, each as its own mesh.
std::vector<TriangleMesh> split_components(const TriangleMesh& mesh);

// A closed solid: one outward shell with the inward shells (cavities) inside it; its volume net
// of them.
struct Solid {
  TriangleMesh mesh;
  double volume_m3 = 0.0;
};

// The solids of a closed mesh's components (split_components), each cavity with the solid that
// holds it; an inward shell inside no solid bounds nothing and is dropped. `cavities` (optional)
// counts the cavities kept.
Result<std::vector<Solid>> solids_of(const TriangleMesh& mesh, int* cavities = nullptr);

}  // namespace hc::articulation
