// Rigid probes as signed distance fields (thesis Sec. 4.2.4): a sphere, a flat-ended cylinder (the
// disk probes of Fig. 4.4.2) and any closed triangle mesh. A probe has a pose (world from probe
// frame) and a pushing direction (world unit vector); loading moves it along that direction.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <memory>
#include <optional>
#include <vector>

#include "common/mesh.h"
#include "common/status.h"

namespace hc::fem {

class Probe {
 public:
  virtual ~Probe() = default;

  // Signed distance (m) from a point in the probe frame to the probe surface: negative inside.
  // Writes the outward unit normal of the closest surface point (probe frame) when `normal` is not
  // null.
  virtual double local_signed_distance(const Eigen::Vector3d& p, Eigen::Vector3d* normal) const = 0;
  // Bounding box in the probe frame.
  virtual Eigen::AlignedBox3d local_bounds() const = 0;
  virtual std::unique_ptr<Probe> clone() const = 0;

  // Signed distance and outward normal in the world frame.
  double signed_distance(const Eigen::Vector3d& p_world, Eigen::Vector3d* normal_world) const;
  Eigen::AlignedBox3d world_bounds() const;

  const Eigen::Isometry3d& pose() const { return pose_; }  // T_world_probe
  void set_pose(const Eigen::Isometry3d& pose) { pose_ = pose; }
  const Eigen::Vector3d& direction() const { return direction_; }
  // Normalises; invalid_argument for a zero or non-finite vector.
  Status set_direction(const Eigen::Vector3d& direction);
  // Moves the probe by `distance_m` along direction().
  void advance(double distance_m) { pose_.pretranslate(distance_m * direction_); }

  // Smallest travel t >= 0 along direction() after which some point of `points` (#P by 3, world) is
  // inside or on the probe, found by sphere tracing the distance field; nullopt when no point is
  // reached within max_travel_m (an "unreachable" probe). Points already inside give 0.
  std::optional<double> travel_to_contact(
      const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>& points,
      double max_travel_m) const;

 protected:
  Eigen::Isometry3d pose_ = Eigen::Isometry3d::Identity();
  Eigen::Vector3d direction_ = -Eigen::Vector3d::UnitZ();
};

// Sphere of the given radius centred at the probe-frame origin.
class SphereProbe final : public Probe {
 public:
  explicit SphereProbe(double radius_m) : radius_(radius_m) {}
  double local_signed_distance(const Eigen::Vector3d& p, Eigen::Vector3d* normal) const override;
  Eigen::AlignedBox3d local_bounds() const override;
  std::unique_ptr<Probe> clone() const override { return std::make_unique<SphereProbe>(*this); }
  double radius() const { return radius_; }

 private:
  double radius_;
};

// Flat-ended cylinder (a disk probe / flat punch): radius r, the flat contact face is the disk z =
// 0 of the probe frame and the body extends to z = height. Orient it with a pose whose -z axis is
// the pushing direction (make_flat_probe does this).
class CylinderProbe final : public Probe {
 public:
  CylinderProbe(double radius_m, double height_m) : radius_(radius_m), height_(height_m) {}
  double local_signed_distance(const Eigen::Vector3d& p, Eigen::Vector3d* normal) const override;
  Eigen::AlignedBox3d local_bounds() const override;
  std::unique_ptr<Probe> clone() const override { return std::make_unique<CylinderProbe>(*this); }
  double radius() const { return radius_; }
  double height() const { return height_; }

 private:
  double radius_;
  double height_;
};

// Any closed, consistently oriented triangle mesh (vertices in the probe frame, metres). Distance
// to the closest triangle; inside/outside by the generalised winding number (robust to small
// defects).
class MeshProbe final : public Probe {
 public:
  // invalid_argument for an empty mesh, bad indices, non-finite vertices or a mesh that is not
  // closed (winding number of an interior point far from 1).
  static Result<std::unique_ptr<MeshProbe>> create(const TriangleMesh& mesh);
  double local_signed_distance(const Eigen::Vector3d& p, Eigen::Vector3d* normal) const override;
  Eigen::AlignedBox3d local_bounds() const override;
  std::unique_ptr<Probe> clone() const override { return std::make_unique<MeshProbe>(*this); }
  const TriangleMesh& mesh() const { return mesh_; }

 private:
  explicit MeshProbe(TriangleMesh mesh);
  TriangleMesh mesh_;
  Eigen::AlignedBox3d bounds_;
};

// Convenience constructors: the probe's reference point (sphere centre, centre of the flat face,
// mesh origin) at `position_m`, pushing along `direction` (normalised). The flat probe's height
// defaults to 4 radii. invalid_argument for non-positive sizes, non-finite values or a zero
// direction.
Result<std::unique_ptr<Probe>> make_sphere_probe(double radius_m, const Eigen::Vector3d& position_m,
                                                 const Eigen::Vector3d& direction);
Result<std::unique_ptr<Probe>> make_flat_probe(double radius_m, const Eigen::Vector3d& position_m,
                                               const Eigen::Vector3d& direction,
                                               double height_m = 0);
// The mesh's local frame is kept (no rotation); its origin is placed at position_m.
Result<std::unique_ptr<Probe>> make_mesh_probe(const TriangleMesh& mesh,
                                               const Eigen::Vector3d& position_m,
                                               const Eigen::Vector3d& direction);

}  // namespace hc::fem
