// Contact-adaptive specimen meshes: a size field graded from where the probe will touch the
// specimen to a coarse far field, so that a scene without mesh keys gets elements small against
// the contact patch (a sphere of radius R pressed to depth d touches a disk of radius √(R d):
// 2.2 mm for R = 10 mm, d = 0.5 mm) and few elsewhere.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/mesh.h"
#include "common/status.h"
#include "processing/fem/contact.h"
#include "processing/fem/probe.h"
#include "processing/meshing/size_field.h"

namespace hc::scene {

struct ContactPatch {
  Eigen::Vector3d centre_m = Eigen::Vector3d::Zero();  // first contact point on the surface
  double radius_m = 0;                                 // expected contact radius at full load
  double depth_m = 0;                                  // expected depth at full load
};

// Where `probe` (at its start pose, moving along its direction) first touches the closed `surface`
// (metres) and how large its contact patch will be under `load`: a sphere of radius R at depth d
// touches a disk of radius √(R d) (Hertz; under force control d = (3 F / (4 E* √R))^(2/3)); a flat
// punch its own radius; a mesh probe the widest section of its own surface within d of its tip
// (force control: d as for a sphere of its feature size). `effective_modulus_pa` is the specimen's
// E* = E / (1 − ν²) near the contact (force control only). invalid_argument when the probe's path
// misses the surface.
Result<ContactPatch> expected_contact_patch(const TriangleMesh& surface, const fem::Probe& probe,
                                            const fem::Load& load, double effective_modulus_pa);

struct ContactMeshingOptions {
  // Fine size = patch radius / this (TetGen's edges come out ~1.2 x the size on the surface).
  double elements_per_patch_radius = 4;
  // The fine size holds within this many patch radii of the contact point.
  double fine_region_radii = 3;
  double growth = 0.3;  // size increase per unit distance beyond the fine region
  // Far-field size = this x the specimen's smallest bounding-box extent.
  double coarse_fraction = 0.25;
  // Budget: when the estimated tet count exceeds it, all sizes grow until it fits.
  double max_tets = 80000;

  Status validate() const;
};

// The size field for `patch` on a specimen with bounding box `specimen` (metres).
meshing::GradedSize contact_size_field(const ContactPatch& patch,
                                       const Eigen::AlignedBox3d& specimen,
                                       const ContactMeshingOptions& options = {});

}  // namespace hc::scene
