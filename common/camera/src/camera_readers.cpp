// A camera from a rig YAML's config map and to/from JSON (camera/camera_model.h), and look_at.
#include <fmt/format.h>

#include <Eigen/Geometry>

#include <array>
#include <cmath>
#include <string>

#include "camera/camera_model.h"
#include "common/json_reader.h"

namespace hc {

void look_at(const Eigen::Vector3d& position, const Eigen::Vector3d& target, CameraModel& cam) {
  const Eigen::Vector3d z = (target - position).normalized();
  Eigen::Vector3d up(0.0, 0.0, 1.0);
  if (std::abs(z.dot(up)) > 0.999) up = Eigen::Vector3d(0.0, 1.0, 0.0);
  const Eigen::Vector3d x = z.cross(up).normalized();
  const Eigen::Vector3d y = z.cross(x);
  cam.R.row(0) = x.transpose();
  cam.R.row(1) = y.transpose();
  cam.R.row(2) = z.transpose();
  cam.t_m = -cam.R * position;
}

namespace {

bool is_rotation(const Eigen::Matrix3d& R) {
  return (R * R.transpose() - Eigen::Matrix3d::Identity()).norm() <= 1e-6 &&
         R.determinant() > 0.0;
}

}  // namespace

Status read_camera(ConfigNode node, CameraModel& cam) {
  node.optional("width", cam.width, Bounds::between(8, 16384));
  node.optional("height", cam.height, Bounds::between(8, 16384));
  cam.cx = 0.5 * (cam.width - 1.0);
  cam.cy = 0.5 * (cam.height - 1.0);
  node.optional("fx", cam.fx, Bounds::positive());
  node.optional("fy", cam.fy, Bounds::positive());
  node.optional("cx", cam.cx);
  node.optional("cy", cam.cy);
  if (node.optional("distortion", cam.distortion)) {
    const std::size_t n = cam.distortion.size();
    if (n != 0 && n != 4 && n != 5 && n != 8)
      node.error("distortion", fmt::format("has {} coefficients (expected 0, 4, 5 or 8: k1 k2 p1 "
                                           "p2 [k3 [k4 k5 k6]])",
                                           n));
  }
  std::array<std::array<double, 3>, 3> R{};
  std::array<double, 3> t{}, position{}, target{};
  const bool has_r = node.optional("R", R);
  const bool has_t = node.optional("t", t);
  const bool has_pos = node.optional("position_m", position);
  const bool has_target = node.optional("look_at_m", target);
  if (has_r != has_t) node.error("R and t must be given together");
  if (has_pos != has_target) node.error("position_m and look_at_m must be given together");
  if (has_r && has_pos) node.error("give either R and t or position_m and look_at_m, not both");
  if (!node.status().ok()) return node.status();
  if (has_r) {
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) cam.R(i, j) = R[i][j];
    cam.t_m = Eigen::Vector3d(t[0], t[1], t[2]);
    if (!is_rotation(cam.R))
      node.error("R", "must be a rotation matrix (orthonormal, determinant +1)");
  } else if (has_pos) {
    const Eigen::Vector3d p(position[0], position[1], position[2]);
    const Eigen::Vector3d q(target[0], target[1], target[2]);
    if ((q - p).norm() < 1e-6)
      node.error("look_at_m", "must differ from position_m");
    else
      look_at(p, q, cam);
  }
  return node.status();
}

Json camera_to_json(const CameraModel& c) {
  return Json{{"width", c.width},
              {"height", c.height},
              {"fx", c.fx},
              {"fy", c.fy},
              {"cx", c.cx},
              {"cy", c.cy},
              {"distortion", c.distortion},
              {"R", eigen_to_json(c.R)},
              {"t_m", eigen_to_json(c.t_m)},
              {"center_m", eigen_to_json(c.center_m())}};
}

Result<CameraModel> camera_from_json(const Json& j, const std::string& name,
                                     std::string_view where) {
  const JsonNode node(j, where);
  HC_RETURN_IF_ERROR(node.expect_object());
  CameraModel c;
  c.name = name;
  HC_RETURN_IF_ERROR(node.get("width", c.width, Bounds::between(1, 1e6)));
  HC_RETURN_IF_ERROR(node.get("height", c.height, Bounds::between(1, 1e6)));
  HC_RETURN_IF_ERROR(node.get("fx", c.fx));
  HC_RETURN_IF_ERROR(node.get("fy", c.fy));
  HC_RETURN_IF_ERROR(node.get("cx", c.cx));
  HC_RETURN_IF_ERROR(node.get("cy", c.cy));
  HC_RETURN_IF_ERROR(node.get("distortion", c.distortion));
  HC_ASSIGN_OR_RETURN(JsonNode rows, node.member("R"));
  HC_RETURN_IF_ERROR(rows.expect_array_of(3, "rows"));
  for (std::size_t a = 0; a < 3; ++a) {
    HC_ASSIGN_OR_RETURN(Eigen::Vector3d row, rows[a].vector<3>());
    c.R.row(static_cast<Eigen::Index>(a)) = row.transpose();
  }
  HC_RETURN_IF_ERROR(node.get("t_m", c.t_m));
  if (const Status s = validate(c); !s.ok())
    return invalid_argument(fmt::format("{}: {}", where, s.message()));
  return c;
}

}  // namespace hc
