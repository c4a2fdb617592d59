// Closed, outward-oriented triangle meshes of the solids joint hulls are made of (the
// polygonisation of thesis Sec. 6.4.3's implicit CSG): spheres, cone sectors, cylinders and
// annular-sector prisms, in a local frame. Curved surfaces are faceted either inside the true
// surface (kInscribed: every vertex on it) or around it (kCircumscribed: every facet outside it),
// so that a solid that must stay clear of another by d keeps at least d after faceting.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <functional>

#include "common/mesh.h"

namespace hc::articulation {

enum class Facet { kInscribed, kCircumscribed };

// world = origin + axes * local; axes' columns are the local x, y, z axes (orthonormal,
// right-handed).
struct LocalFrame {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();
};

TriangleMesh transformed(const TriangleMesh& mesh, const LocalFrame& frame);

// UV sphere of `radius` about the local origin, `segments` around the z axis and segments / 2
// latitude bands.
TriangleMesh sphere_mesh(double radius, int segments, Facet facet);

// The solid cone of half-angle psi(theta) about local +y with its apex at the origin, cut by the
// star-shaped cap at distance reach(direction) from the apex (a spherical sector when reach is
// constant). theta is the direction about y, measured from +z towards +x; 0 < psi < pi. The
// cone's sides are faceted inside (kInscribed) or outside (kCircumscribed) the true cone. With
// inner > 0 the cone of half-angle `inner` and the ball of radius `near` about the apex are left
// out (a conical shell, closed near the apex by a cap at distance `near` < reach). Generatrices
// are at theta = 2 pi j / segments + theta_offset.
TriangleMesh cone_sector_mesh(const std::function<double(double)>& psi,
                              const std::function<double(const Eigen::Vector3d&)>& reach,
                              int segments, Facet facet, double inner = 0.0, double near = 0.0,
                              double theta_offset = 0.0);
inline TriangleMesh cone_sector_mesh(const std::function<double(double)>& psi, double radius,
                                     int segments, Facet facet) {
  return cone_sector_mesh(psi, [radius](const Eigen::Vector3d&) { return radius; }, segments,
                          facet);
}

// Cylinder about local x from x0 to x1 of `radius`, its vertices at angles 2 pi (j + phase) /
// segments. Coaxial cylinders of one joint get different phases: an edge of one lying exactly on
// a cap edge of another would leave slivers in their boolean.
TriangleMesh cylinder_mesh(double radius, double x0, double x1, int segments, Facet facet,
                           double phase = 0.0);

// Prism along local x from x0 to x1 over the annular sector of radii [r0, r1(x, phi)] (r0 = 0: a
// wedge whose edge is the x axis) and angles [phi0, phi1] measured in the (y, z) plane from +y
// towards +z (0 < phi1 - phi0 < 2 pi), with `stations` + 1 cross-sections along x. The inner arc
// is faceted inside (kInscribed) or outside (kCircumscribed) the circle of r0; r1 > r0.
// The angle between the cross-sections' samples of such a prism over [phi0, phi1].
double sector_step(double phi0, double phi1, int segments_per_turn);
TriangleMesh sector_prism_mesh(double r0, const std::function<double(double, double)>& r1,
                               double phi0, double phi1, double x0, double x1, int stations,
                               int segments_per_turn, Facet inner_facet);
inline TriangleMesh sector_prism_mesh(double r0, double r1, double phi0, double phi1, double x0,
                                      double x1, int segments_per_turn, Facet inner_facet) {
  return sector_prism_mesh(
      r0, [r1](double, double) { return r1; }, phi0, phi1, x0, x1, 1, segments_per_turn,
      inner_facet);
}

// Several closed meshes as one (no boolean: for solids known to be apart).
TriangleMesh concatenated(const std::vector<TriangleMesh>& meshes);

// Signed volume of a closed, outward-oriented mesh (divergence theorem).
double enclosed_volume(const TriangleMesh& mesh);

}  // namespace hc::articulation
