// The "ground-truth physics" for the material tests: processing/hyperelastic's compressible
// (optionally strain-stiffening) neo-Hookean model, layered in z, indented by a sphere probe under
// force control. A different model from the co-rotational one the fitter uses (issue 3).
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include "material_test_util.h"
#include "processing/hyperelastic/neo_hookean.h"
#include "processing/material/synth.h"

namespace hc::material::testing {

struct HyperelasticReference {
  TetMesh mesh;
  std::vector<hyperelastic::MaterialLayer> layers;
  int steps = 4;

  ReferenceSimulator simulator() const {
    return [this](const ProbePose& pose, double force_n) -> Result<ReferenceIndentation> {
      HC_ASSIGN_OR_RETURN(std::vector<hyperelastic::NeoHookeanMaterial> per_tet,
                          hyperelastic::layered_materials(mesh, layers));
      HC_ASSIGN_OR_RETURN(hyperelastic::NeoHookeanModel model,
                          hyperelastic::NeoHookeanModel::create(mesh, per_tet));
      // Start at first contact with a node: processing/hyperelastic's force control takes secant
      // steps in depth and overshoots when its first steps find no contact.
      const Eigen::Vector3d d = pose.direction.normalized();
      double travel = 1e300;
      for (Eigen::Index n = 0; n < mesh.num_nodes(); ++n) {
        // |p − (c + t d)| = r  →  t = (p−c)·d − sqrt(r² − |(p−c) − ((p−c)·d) d|²)
        const Eigen::Vector3d w = mesh.nodes.row(n).transpose() - pose.position_m;
        const double along = w.dot(d);
        const double off2 = (w - along * d).squaredNorm();
        if (off2 <= pose.radius_m * pose.radius_m)
          travel = std::min(travel, along - std::sqrt(pose.radius_m * pose.radius_m - off2));
      }
      if (travel > 1e299) return invalid_argument("the probe misses the specimen");
      hyperelastic::ProbeOptions po;
      po.start_position_m = pose.position_m + std::max(travel, 0.0) * d;
      po.direction = pose.direction;
      po.radius_m = pose.radius_m;
      // Penalty stiffness well above the block's stiffness at the scale of an element, so that
      // residual penetration is small against the displacements.
      po.stiffness_n_per_m = 1e5;
      std::unique_ptr<hyperelastic::RigidProbe> probe = hyperelastic::make_sphere_probe(po);
      hyperelastic::Boundary boundary;
      boundary.fixed_nodes = bottom_nodes(mesh);
      boundary.contacts = {probe.get()};
      hyperelastic::IndentOptions io;
      io.steps = steps;
      io.force_control = true;
      io.force_n = force_n;
      Eigen::VectorXd x = model.rest_positions();
      hyperelastic::IndentSummary is;
      HC_RETURN_IF_ERROR(hyperelastic::indent(model, boundary, *probe, io, &x, &is));
      if (!is.usable) return failed_precondition("reference indentation: " + is.message);
      ReferenceIndentation out;
      out.positions_m = Eigen::Map<const MatrixX3d>(x.data(), mesh.num_nodes(), 3);
      out.contact_forces_n = MatrixX3d::Zero(mesh.num_nodes(), 3);
      for (Eigen::Index n = 0; n < mesh.num_nodes(); ++n) {
        Eigen::Vector3d grad = Eigen::Vector3d::Zero();
        probe->node_energy(x.segment<3>(3 * n), &grad, nullptr);
        out.contact_forces_n.row(n) = -grad.transpose();  // force on the node = −∂E/∂x
      }
      return out;
    };
  }
};

}  // namespace hc::material::testing
