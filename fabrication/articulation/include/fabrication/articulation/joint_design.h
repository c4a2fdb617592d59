// Parametric joints as geometric models of strength (thesis Sec. 6.4.2): a ball-and-socket and a
// hinge whose three critical cross-sections (Fig. 6.4.6) are maximised in their minimum under the
// feasibility constraints of Eqs. 6.4 and 6.5, with the area lost to range cuts (Fig. 6.4.9,
// Eq. 6.6) recomputed at every evaluation.
//
// Joint frame [a, n, f] (right-handed, f = a x n): c is the rotation centre, n points from the
// parent (root side) to the child, a is the hinge axis, f the forward direction where the ball's
// opening-angle parameter theta is zero. Lengths in metres, areas in m^2, angles in radians.
//
// Ball-and-socket (child owns the ball): ball radius r' = r - d; socket cavity radius r in the
// parent; the child's neck is the cone of half-angle alpha about n with cos(alpha) = h / r' (it
// meets the ball in the circle at height h); the parent is cut by the cone of half-angle
// psi(theta) = alpha + phi(theta) + delta, delta = asin(d / r') keeping the clearance d from the
// neck tilted by phi. Critical areas:
//   A1 = equator of the socket shell, pi (r_max^2 - r^2), less the sectors where psi >= 90 deg;
//   A2 = the lip holding the ball: the cylinder of radius r' from s0 = sqrt(r^2 - r'^2) up to h,
//        less what the range cone removes, r' * integral of clamp(r'/tan(psi) - s0, 0, h - s0);
//   A3 = the neck, pi (r'^2 - h^2).
// Constraints (Eq. 6.4): d < r < r_max, s0 < h < r'.
//
// Hinge (child owns the knuckle, parent the fork and pin): a knuckle of radius R - d and width
// b - 2d turning in a slot of radius R and width b, on a pin of radius r - d through a hole of
// radius r; the knuckle's neck is the wedge of half-angle alpha about n with sin(alpha) =
// (R - d - r) / (R - d) (the neck as strong as the knuckle's ligaments, A4 = A2 as the thesis
// chooses); the parent is cut by the wedge from -(alpha + gamma_b + delta) to alpha + gamma_f +
// delta, delta = asin(d / (R - d)). Critical areas:
//   A1 = the pin in double shear, 2 pi (r - d)^2;
//   A2 = the knuckle's two ligaments, 2 (b - 2d)(R - d - r);
//   A3 = the fork's section through the axis, pi r_max^2 - 2 b (R - r + d), less the disc
//        segment beyond R - d on each side whose swing wedge reaches 90 deg.
// Constraints (Eq. 6.5): r > d, R > d + r, r_max^2 > (b/2)^2 + R^2, b > 2d.
#pragma once

#include <array>
#include <string>

#include "common/status.h"

namespace hc::articulation {

// Opening angle of a ball joint as a function of direction theta about n (0 along f, pi/2
// along a): an ellipse in polar form through phi_f at theta = 0 and phi_a at theta = pi/2. (The
// thesis writes phi_a sin(theta) + phi_b cos(theta), which is negative over half a turn; the
// ellipse is what its "elliptical opening angles" describe.) Equal values: a round cone beta.
struct BallRange {
  double phi_f = 0.0;
  double phi_a = 0.0;
  double at(double theta) const;
  double max() const { return phi_f > phi_a ? phi_f : phi_a; }
};

// Swing angles of a hinge about a: forward (towards f) and backward.
struct HingeRange {
  double forward = 0.0;
  double backward = 0.0;
};

struct JointDesignOptions {
  double clearance_m = 0.3e-3;  // d
  // Directions theta at which Eq. 6.6's integral is sampled.
  int theta_samples = 90;
  // Grid points per parameter and zoom levels of the max-min search.
  int grid = 48;
  int levels = 7;
  Status validate() const;
};

struct BallSocketDesign {
  bool feasible = false;  // some (r, h) satisfies Eq. 6.4's constraints
  double clearance = 0.0;  // the d it was designed for
  double r = 0.0;         // socket radius
  double h = 0.0;         // neck height above c
  double ball_radius = 0.0;  // r - d
  double s0 = 0.0;           // height where the socket sphere has the ball's radius
  double alpha = 0.0;        // neck half-angle
  double delta = 0.0;        // clearance angle
  std::array<double, 3> areas{};  // A1, A2, A3 (m^2)
  double min_area = 0.0;
  // Radius of the socket's opening at its narrowest direction (the ball must not pass): the
  // largest over theta of the socket sphere's radius at the lip's top. < ball_radius when the
  // lip holds everywhere.
  double opening_radius = 0.0;
  int evaluations = 0;
};

struct HingeDesign {
  bool feasible = false;
  double clearance = 0.0;  // the d it was designed for
  double R = 0.0;  // slot radius
  double r = 0.0;  // hole radius (pin radius r - d)
  double b = 0.0;  // slot width
  double alpha = 0.0;
  double delta = 0.0;
  std::array<double, 3> areas{};
  double min_area = 0.0;
  int evaluations = 0;
};

// The critical areas of one ball-and-socket parameter choice (no constraint checks).
std::array<double, 3> ball_socket_areas(double r_max, double r, double h, const BallRange& range,
                                        const JointDesignOptions& options);
// The critical areas of one hinge parameter choice (no constraint checks).
std::array<double, 3> hinge_areas(double r_max, double R, double r, double b,
                                  const HingeRange& range, const JointDesignOptions& options);

// Eq. 6.4: the (r, h) maximising the smallest critical area for a maximum inscribed sphere of
// radius r_max. Infeasible (feasible = false) when r_max is too small for the clearance.
BallSocketDesign design_ball_socket(double r_max, const BallRange& range,
                                    const JointDesignOptions& options);

// Eq. 6.5: the (R, r, b) maximising the smallest critical area.
HingeDesign design_hinge(double r_max, const HingeRange& range, const JointDesignOptions& options);

}  // namespace hc::articulation
