// The scene's specimen: its mesh (explicit keys or contact-adaptive), its fixed nodes, the probe.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>

#include "common/mesh_io.h"
#include "processing/fem/material_model.h"
#include "processing/material/material.h"
#include "processing/meshing/tetrahedralize.h"
#include "processing/scene/contact_meshing.h"
#include "processing/scene/scene.h"

namespace hc::scene {

namespace {

// E* = E / (1 − ν²) of the scene's material near z (m): the layer containing z (else the nearest),
// a file material's first element at zero strain.
Result<double> effective_modulus(const MaterialSpec& m, double z) {
  double e = m.youngs_pa, nu = m.poisson;
  if (m.kind == MaterialKind::kLayered) {
    double best = std::numeric_limits<double>::infinity();
    for (const LayerSpec& l : m.layers) {
      const double d = z < l.z_min_m ? l.z_min_m - z : (z > l.z_max_m ? z - l.z_max_m : 0.0);
      if (d < best) {
        best = d;
        e = l.youngs_pa;
        nu = l.poisson;
      }
    }
  } else if (m.kind == MaterialKind::kFile) {
    HC_ASSIGN_OR_RETURN(std::unique_ptr<fem::MaterialModel> model, material::load_material(m.file));
    const fem::YoungsPoisson yp =
        fem::youngs_poisson_from_lambda_alpha(model->params(0, fem::Vector6d::Zero()));
    e = yp.youngs_pa;
    nu = yp.poisson;
  }
  return e / (1 - nu * nu);
}

// Shortest and longest edge of the mesh (m).
void edge_range(const TetMesh& mesh, double* shortest, double* longest) {
  *shortest = std::numeric_limits<double>::infinity();
  *longest = 0;
  for (Eigen::Index t = 0; t < mesh.num_tets(); ++t)
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) {
        const double l = (mesh.nodes.row(mesh.tets(t, a)) - mesh.nodes.row(mesh.tets(t, b))).norm();
        *shortest = std::min(*shortest, l);
        *longest = std::max(*longest, l);
      }
}

}  // namespace

Result<std::unique_ptr<fem::Probe>> build_probe(const ProbeSpec& p) {
  switch (p.shape) {
    case ProbeSpec::Shape::kSphere:
      return fem::make_sphere_probe(p.radius_m, p.position_m, p.direction);
    case ProbeSpec::Shape::kFlat:
      return fem::make_flat_probe(p.radius_m, p.position_m, p.direction);
    case ProbeSpec::Shape::kMesh: {
      HC_ASSIGN_OR_RETURN(TriangleMesh m, read_mesh(p.mesh));
      m.vertices *= p.scale_to_m;
      return fem::make_mesh_probe(m, p.position_m, p.direction);
    }
  }
  return internal_error("unknown probe shape");
}

Result<TetMesh> build_specimen(const SpecimenSpec& spec) {
  if (spec.kind == SpecimenSpec::Kind::kBox) {
    const Eigen::Vector3d size = spec.box_m * spec.scale_to_m;
    if (spec.cells) return meshing::structured_box(size, *spec.cells);
    meshing::TetrahedralizeOptions options;
    options.max_radius_edge_ratio = 1.414;
    options.max_volume = spec.max_tet_volume_m3;
    return meshing::box_tet_mesh(size, options);
  }
  HC_ASSIGN_OR_RETURN(TriangleMesh surface, read_mesh(spec.mesh));
  surface.vertices *= spec.scale_to_m;
  meshing::TetrahedralizeOptions options;
  options.max_radius_edge_ratio = 1.414;
  options.max_volume = spec.max_tet_volume_m3;
  return meshing::tetrahedralize(surface, options);
}

Result<std::vector<int>> fixed_nodes(const Scene& scene, const TetMesh& mesh) {
  if (!scene.fixed_bottom) {
    for (int n : scene.fixed_nodes) {
      if (n >= mesh.num_nodes()) {
        return invalid_argument("scene: fixed node " + std::to_string(n) +
                                " out of range (mesh has " + std::to_string(mesh.num_nodes()) +
                                " nodes)");
      }
    }
    std::vector<int> out = scene.fixed_nodes;
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
    return out;
  }
  const double zmin = mesh.nodes.col(2).minCoeff();
  const double size = (mesh.nodes.colwise().maxCoeff() - mesh.nodes.colwise().minCoeff()).norm();
  std::vector<int> out;
  for (Eigen::Index i = 0; i < mesh.num_nodes(); ++i) {
    if (mesh.nodes(i, 2) <= zmin + 1e-9 * size) out.push_back(static_cast<int>(i));
  }
  return out;
}

Result<TetMesh> build_specimen(const Scene& scene, MeshReport* report) {
  const auto t0 = std::chrono::steady_clock::now();
  const SpecimenSpec& spec = scene.specimen;
  MeshReport r;
  TetMesh mesh;
  if (spec.cells || spec.max_tet_volume_m3 > 0) {
    r.method = spec.cells ? "structured" : "tetgen";
    HC_ASSIGN_OR_RETURN(mesh, build_specimen(spec));
  } else {
    r.method = "contact_adaptive";
    TriangleMesh surface;
    if (spec.kind == SpecimenSpec::Kind::kBox) {
      surface = meshing::box_surface(spec.box_m * spec.scale_to_m);
    } else {
      HC_ASSIGN_OR_RETURN(surface, read_mesh(spec.mesh));
      surface.vertices *= spec.scale_to_m;
    }
    HC_ASSIGN_OR_RETURN(std::unique_ptr<fem::Probe> probe, build_probe(scene.probe));
    // The patch's z picks the layer whose modulus sets the expected depth under force control.
    HC_ASSIGN_OR_RETURN(const double e_star,
                        effective_modulus(scene.material, surface.vertices.col(2).maxCoeff()));
    HC_ASSIGN_OR_RETURN(const ContactPatch patch,
                        expected_contact_patch(surface, *probe, scene.load, e_star));
    const Eigen::AlignedBox3d box(surface.vertices.colwise().minCoeff().transpose(),
                                  surface.vertices.colwise().maxCoeff().transpose());
    ContactMeshingOptions meshing_options;
    if (spec.contact_elements_per_radius > 0) {
      // The fine region's tets grow as the cube of the refinement: so does the budget.
      const double ratio =
          spec.contact_elements_per_radius / meshing_options.elements_per_patch_radius;
      meshing_options.max_tets *= std::max(1.0, ratio * ratio * ratio);
      meshing_options.elements_per_patch_radius = spec.contact_elements_per_radius;
    }
    const meshing::GradedSize size = contact_size_field(patch, box, meshing_options);
    meshing::TetrahedralizeOptions options;
    options.max_radius_edge_ratio = 1.414;
    options.edge_size = size;
    if (spec.kind == SpecimenSpec::Kind::kBox) {
      HC_ASSIGN_OR_RETURN(mesh, meshing::box_tet_mesh(spec.box_m * spec.scale_to_m, options));
    } else {
      HC_ASSIGN_OR_RETURN(mesh, meshing::tetrahedralize(surface, options));
    }
    r.focus_m = patch.centre_m;
    r.patch_radius_m = patch.radius_m;
    r.fine_size_m = size.fine;
    r.coarse_size_m = size.coarse;
    r.growth = size.growth;
    r.elements_per_radius = meshing_options.elements_per_patch_radius;
  }
  r.nodes = static_cast<long>(mesh.num_nodes());
  r.tets = static_cast<long>(mesh.num_tets());
  edge_range(mesh, &r.min_edge_m, &r.max_edge_m);
  r.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (report != nullptr) *report = r;
  return mesh;
}

}  // namespace hc::scene
