// The virtual specimen of the simulated world: a block whose top surface carries painted marker
// dots and which a spherical probe indents from above. The hidden material is what the capture
// pipeline will later try to recover, so the force law here must differ from the fitter's model.
//
// World frame: z up, the specimen's top surface at z = top_z_m() before deformation, the probe
// pressing along -z (a 4-DOF arm keeps its tool vertical).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <memory>
#include <string>
#include <vector>

#include "common/status.h"

namespace hc::devices::sim {

// Where and how deep the probe indents the top surface.
struct Indentation {
  double center_x_m = 0.0;  // probe axis, world frame
  double center_y_m = 0.0;
  double depth_m = 0.0;  // top_z - (lowest point of the probe); <= 0 means no contact
  double probe_radius_m = 0.005;
};

class Specimen {
 public:
  virtual ~Specimen() = default;
  virtual std::string name() const = 0;
  // Undeformed height of the top surface, m.
  virtual double top_z_m() const = 0;
  // Extent of the top surface in x and y, m.
  virtual Eigen::AlignedBox2d footprint() const = 0;
  // Reaction force on the probe (N, >= 0, pushing it up along +z) for an indentation.
  virtual double force_n(const Indentation& indentation) const = 0;
  // Displacement (m) of a point on the undeformed top surface under the indentation.
  virtual Eigen::Vector3d displacement(const Eigen::Vector3d& rest_point,
                                       const Indentation& indentation) const = 0;
  // Undeformed marker centres (painted dots) on the top surface, world frame, m.
  virtual const std::vector<Eigen::Vector3d>& rest_markers() const = 0;
  // Radius of a painted dot, m.
  virtual double marker_radius_m() const = 0;
};

// A rigid sphere on an elastic half-space (Hertz contact), with a hidden stiffening:
//   E* = E / (1 - nu^2)                        (rigid indenter; K. L. Johnson, Contact Mechanics,
//   1985, §4.2) F_Hertz(d) = 4/3 E* sqrt(R) d^(3/2)        (Johnson §4.2, contact radius a = sqrt(R
//   d)) F(d) = F_Hertz(d) * (1 + stiffening * d / R)
// Surface displacements from the Hertz pressure p0 sqrt(1 - r^2/a^2), p0 = 2 a E* / (pi R)
// (Johnson §3.4, displacements under the Hertz pressure, rigid indenter):
//   u_z(r) = -(2 a^2 - r^2) / (2 R)                                            r <= a
//   u_z(r) = -[(2 a^2 - r^2) asin(a / r) + a sqrt(r^2 - a^2)] / (pi R)         r >  a
//   u_r(r) = -(1 - 2nu)(1 + nu)/(3E) * a^2 p0 / r * [1 - (1 - r^2/a^2)^(3/2)]   r <= a
//   u_r(r) = -(1 - 2nu)(1 + nu)/(3E) * a^2 p0 / r                             r >  a
// (negative = down / towards the axis). The block is finite but treated as a half-space; the
// stiffening changes only the force, so markers follow Hertz kinematics exactly.
class HertzSpecimen final : public Specimen {
 public:
  struct Options {
    double youngs_modulus_pa = 1.0e6;  // silicone-like
    double poisson_ratio = 0.45;
    double stiffening = 0.5;  // dimensionless; 0 = pure Hertz
    double top_z_m = 0.05;
    Eigen::Vector2d center_m{0.0, 0.0};
    Eigen::Vector2d size_m{0.06, 0.06};
    double marker_spacing_m = 0.003;  // thesis 5.6: dotted grids with 3 mm spacing
    double marker_radius_m = 0.0006;
    Status validate() const;
  };
  explicit HertzSpecimen(const Options& options);

  std::string name() const override { return "hertz"; }
  double top_z_m() const override { return options_.top_z_m; }
  Eigen::AlignedBox2d footprint() const override;
  double force_n(const Indentation& indentation) const override;
  Eigen::Vector3d displacement(const Eigen::Vector3d& rest_point,
                               const Indentation& indentation) const override;
  const std::vector<Eigen::Vector3d>& rest_markers() const override { return markers_; }
  double marker_radius_m() const override { return options_.marker_radius_m; }
  const Options& options() const { return options_; }
  // E* = E / (1 - nu^2), Pa.
  double effective_modulus_pa() const;

 private:
  Options options_;
  std::vector<Eigen::Vector3d> markers_;
};

// A grid of marker centres with `spacing` over `footprint` (centred, inclusive of both edges when
// they fit), at height z.
std::vector<Eigen::Vector3d> marker_grid(const Eigen::AlignedBox2d& footprint, double spacing_m,
                                         double z_m);

}  // namespace hc::devices::sim
