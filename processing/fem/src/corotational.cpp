#include "processing/fem/corotational.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>

namespace hc::fem {

const Matrix6d& g_matrix() {
  static const Matrix6d kG = [] {
    Matrix6d g = Matrix6d::Zero();
    g.diagonal() << 1, 1, 1, 0.5, 0.5, 0.5;
    return g;
  }();
  return kG;
}

const Matrix6d& h_matrix() {
  static const Matrix6d kH = [] {
    Matrix6d h = Matrix6d::Zero();
    h.topLeftCorner<3, 3>() << -1, 1, 1, 1, -1, 1, 1, 1, -1;
    h.bottomRightCorner<3, 3>() = -Eigen::Matrix3d::Identity();
    return h;
  }();
  return kH;
}

Matrix6d elasticity_matrix(const LambdaAlpha& p) {
  return p.lambda * g_matrix() + p.alpha * h_matrix();
}

Eigen::Matrix3d polar_rotation(const Eigen::Matrix3d& a, Eigen::Quaterniond* q,
                               int max_iterations) {
  // Mueller, Bender, Chentanez, Macklin 2016, "A robust method to extract the rotational part of
  // deformations": maximises tr(R^T A) by rotating q about the torque axis; always returns a
  // rotation (also for flat and inverted elements, where SVD-based polar decompositions need sign
  // fixes).
  //
  // Their step, torque / tr(R^T A), takes the objective's Hessian (in the rotation vector) as
  // tr(B) I with B = A R^T; the exact Hessian is tr(B) I - sym(B). With it the step is Newton's:
  // for the small strains of a fit, 2-3 iterations to 1e-13 from a warm start instead of 22-31
  // (measured on random strains of 1-20 %; their step shrinks the error only ~3x per
  // iteration). Newton's step is taken only where that Hessian is positive definite and the step
  // at most 4x theirs (near-flat or inverted elements keep their robust step).
  constexpr double kAngleTolerance = 1e-13;
  for (int it = 0; it < max_iterations; ++it) {
    const Eigen::Matrix3d r = q->toRotationMatrix();
    const Eigen::Vector3d omega_num =
        r.col(0).cross(a.col(0)) + r.col(1).cross(a.col(1)) + r.col(2).cross(a.col(2));
    const double trace = r.col(0).dot(a.col(0)) + r.col(1).dot(a.col(1)) + r.col(2).dot(a.col(2));
    Eigen::Vector3d omega = omega_num / (std::abs(trace) + 1e-9);
    bool newton_step = false;
    if (trace > 0) {
      const Eigen::Matrix3d b = a * r.transpose();
      const Eigen::LLT<Eigen::Matrix3d> hessian(trace * Eigen::Matrix3d::Identity() -
                                                0.5 * (b + b.transpose()));
      if (hessian.info() == Eigen::Success) {
        const Eigen::Vector3d newton = hessian.solve(omega_num);
        if (newton.allFinite() && newton.norm() <= 4 * omega.norm()) {
          omega = newton;
          newton_step = true;
        }
      }
    }
    const double w = omega.norm();
    if (!(w >= kAngleTolerance)) break;  // also stops on NaN
    *q = Eigen::Quaterniond(Eigen::AngleAxisd(w, omega / w)) * *q;
    q->normalize();
    // Newton's error squares each step: after one this small the next would be below the
    // tolerance, so it is not computed (from the warm starts of an equilibrium iteration most
    // elements need one step).
    if (newton_step && w * w < kAngleTolerance) break;
  }
  return q->toRotationMatrix();
}

Eigen::Matrix3d polar_rotation(const Eigen::Matrix3d& f) {
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  return polar_rotation(f, &q, 100);
}

Status CorotationalOptions::validate() const {
  if (!(min_relative_volume >= 0) || !std::isfinite(min_relative_volume)) {
    return invalid_argument("CorotationalOptions: min_relative_volume must be >= 0");
  }
  if (polar_max_iterations < 1) {
    return invalid_argument("CorotationalOptions: polar_max_iterations must be >= 1");
  }
  return {};
}

struct CorotationalFem::Impl {
  TetMesh mesh;
  CorotationalOptions options;
  std::vector<int> fixed_nodes;
  std::vector<int> free_index;  // per node: index among free nodes or -1
  Eigen::Index num_free = 0;
  std::vector<Matrix43d> grads;
  std::vector<double> volumes;
  std::vector<LambdaAlpha> params;
  std::vector<Matrix6d> elasticity;  // per element when anisotropic, else empty
  MatrixX3d x;
  std::vector<Eigen::Matrix3d> rotations;
  std::vector<Eigen::Quaterniond> quats;
  SparseMatrix k;
  Eigen::VectorXd rhs;
  // Scatter map: per element 16 (a, b) node pairs x 3 columns: index into k's values of the first
  // entry of the rows of node a in column c of node b; -1 when the pair is not stored in the upper
  // triangle.
  std::vector<int> scatter;
  // Per free node and column c: value index of the node's own diagonal block (rows 0..c).
  std::vector<int> self_start;
  // Three coordinates per free node: ordered on the nodes' graph.
  SparseCholesky cholesky{SparseCholesky::Options{.force_supernodal = false, .block_size = 3}};

  // Parts of create(): shape-function gradients and volumes (refusing degenerate and inverted
  // tets); the free-node numbering (unreferenced nodes are fixed too); K's upper-triangle pattern
  // and the scatter map.
  Status set_rest_geometry();
  Status number_free_nodes(const std::vector<int>& fixed_in, const std::vector<char>& used);
  Status build_pattern();

  // The right-hand side rhs + extra (+ the free nodes' external forces when given); extra is
  // empty or one entry per free dof.
  Result<Eigen::VectorXd> load(const MatrixX3d* external_forces,
                               const Eigen::VectorXd& extra) const;
  // The free nodes' positions as a vector over the free dofs, and back.
  Eigen::VectorXd free_positions() const;
  void set_free_positions(const Eigen::VectorXd& v);
};

Result<Eigen::VectorXd> CorotationalFem::Impl::load(const MatrixX3d* external_forces,
                                                    const Eigen::VectorXd& extra) const {
  if (extra.size() != 0 && extra.size() != 3 * num_free) {
    return invalid_argument("FEM: extra right-hand side has the wrong length");
  }
  Eigen::VectorXd b = rhs;
  if (extra.size() != 0) b += extra;
  if (external_forces != nullptr) {
    for (Eigen::Index i = 0; i < external_forces->rows(); ++i) {
      const int f = free_index[static_cast<size_t>(i)];
      if (f >= 0) b.segment<3>(3 * f) += external_forces->row(i).transpose();
    }
  }
  return b;
}

Eigen::VectorXd CorotationalFem::Impl::free_positions() const {
  Eigen::VectorXd v(3 * num_free);
  for (Eigen::Index i = 0; i < x.rows(); ++i) {
    const int f = free_index[static_cast<size_t>(i)];
    if (f >= 0) v.segment<3>(3 * f) = x.row(i).transpose();
  }
  return v;
}

void CorotationalFem::Impl::set_free_positions(const Eigen::VectorXd& v) {
  for (Eigen::Index i = 0; i < x.rows(); ++i) {
    const int f = free_index[static_cast<size_t>(i)];
    if (f >= 0) x.row(i) = v.segment<3>(3 * f).transpose();
  }
}

CorotationalFem::CorotationalFem(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
CorotationalFem::CorotationalFem(CorotationalFem&&) noexcept = default;
CorotationalFem& CorotationalFem::operator=(CorotationalFem&&) noexcept = default;
CorotationalFem::~CorotationalFem() = default;

namespace {

// Checks the mesh; *used_nodes marks the nodes some tet references.
Status check_mesh(const TetMesh& mesh, std::vector<char>* used_nodes) {
  const Eigen::Index n = mesh.num_nodes();
  const Eigen::Index t = mesh.num_tets();
  if (n < 4 || t < 1) {
    return invalid_argument("FEM mesh needs at least 4 nodes and 1 tetrahedron, got " +
                            std::to_string(n) + " nodes and " + std::to_string(t) + " tets");
  }
  if (!mesh.nodes.allFinite()) {
    for (Eigen::Index i = 0; i < n; ++i) {
      if (!mesh.nodes.row(i).allFinite()) {
        return invalid_argument("FEM mesh: node " + std::to_string(i) +
                                " has a non-finite coordinate");
      }
    }
  }
  std::vector<char>& used = *used_nodes;
  used.assign(static_cast<size_t>(n), 0);
  for (Eigen::Index e = 0; e < t; ++e) {
    for (int a = 0; a < 4; ++a) {
      const int v = mesh.tets(e, a);
      if (v < 0 || v >= n) {
        return invalid_argument("FEM mesh: tet " + std::to_string(e) + " references node " +
                                std::to_string(v) + " (mesh has " + std::to_string(n) + " nodes)");
      }
      used[static_cast<size_t>(v)] = 1;
    }
  }
  return {};
}

}  // namespace

Status CorotationalFem::Impl::set_rest_geometry() {
  const Eigen::Index t = mesh.num_tets();
  grads.resize(static_cast<size_t>(t));
  volumes.resize(static_cast<size_t>(t));
  double mean_abs_volume = 0;
  std::vector<double> signed_volume(static_cast<size_t>(t));
  std::vector<Eigen::Matrix3d> dm(static_cast<size_t>(t));
  for (Eigen::Index e = 0; e < t; ++e) {
    const Eigen::Vector3d x0 = mesh.nodes.row(mesh.tets(e, 0)).transpose();
    Eigen::Matrix3d d;
    for (int a = 1; a < 4; ++a) d.col(a - 1) = mesh.nodes.row(mesh.tets(e, a)).transpose() - x0;
    dm[static_cast<size_t>(e)] = d;
    signed_volume[static_cast<size_t>(e)] = d.determinant() / 6.0;
    mean_abs_volume += std::abs(signed_volume[static_cast<size_t>(e)]);
  }
  mean_abs_volume /= static_cast<double>(t);
  for (Eigen::Index e = 0; e < t; ++e) {
    const double v = signed_volume[static_cast<size_t>(e)];
    if (!(v > options.min_relative_volume * mean_abs_volume) || !(v > 0)) {
      const bool inverted = v < 0 && std::abs(v) > options.min_relative_volume * mean_abs_volume;
      return invalid_argument("FEM mesh: tet " + std::to_string(e) + " is " +
                              (inverted ? "inverted" : "degenerate") + " (signed volume " +
                              std::to_string(v) + " m^3, mean " + std::to_string(mean_abs_volume) +
                              " m^3)");
    }
    const Eigen::Matrix3d inv = dm[static_cast<size_t>(e)].inverse();
    Matrix43d g;
    g.bottomRows<3>() = inv;  // row a-1 of Dm^{-1} is grad N_a for a = 1..3
    g.row(0) = -inv.colwise().sum();
    grads[static_cast<size_t>(e)] = g;
    volumes[static_cast<size_t>(e)] = v;
  }
  return {};
}

Status CorotationalFem::Impl::number_free_nodes(const std::vector<int>& fixed_in,
                                                const std::vector<char>& used) {
  const Eigen::Index n = mesh.num_nodes();
  // Fixed nodes (unreferenced nodes are fixed too: they carry no stiffness).
  std::vector<char> fixed(static_cast<size_t>(n), 0);
  for (int f : fixed_in) {
    if (f < 0 || f >= n) {
      return invalid_argument("FEM: fixed node " + std::to_string(f) + " out of range (mesh has " +
                              std::to_string(n) + " nodes)");
    }
    fixed[static_cast<size_t>(f)] = 1;
  }
  free_index.assign(static_cast<size_t>(n), -1);
  for (Eigen::Index i = 0; i < n; ++i) {
    if (!used[static_cast<size_t>(i)]) fixed[static_cast<size_t>(i)] = 1;
    if (fixed[static_cast<size_t>(i)]) {
      fixed_nodes.push_back(static_cast<int>(i));
    } else {
      free_index[static_cast<size_t>(i)] = static_cast<int>(num_free++);
    }
  }
  if (num_free == 0) return invalid_argument("FEM: every node is fixed; nothing to solve");
  return {};
}

Status CorotationalFem::Impl::build_pattern() {
  const Eigen::Index t = mesh.num_tets();
  // Pattern: for each free node j, the free nodes i <= j it shares an element with (node
  // adjacency).
  std::vector<std::vector<int>> upper_nbrs(static_cast<size_t>(num_free));
  for (Eigen::Index e = 0; e < t; ++e) {
    for (int a = 0; a < 4; ++a) {
      const int fa = free_index[static_cast<size_t>(mesh.tets(e, a))];
      if (fa < 0) continue;
      for (int b = 0; b < 4; ++b) {
        const int fb = free_index[static_cast<size_t>(mesh.tets(e, b))];
        if (fb < 0 || fa > fb) continue;
        upper_nbrs[static_cast<size_t>(fb)].push_back(fa);
      }
    }
  }
  Eigen::Index nnz = 0;
  for (auto& v : upper_nbrs) {
    std::sort(v.begin(), v.end());
    v.erase(std::unique(v.begin(), v.end()), v.end());
    nnz += 9 * static_cast<Eigen::Index>(v.size()) - 3;  // self block contributes 6, others 9
  }
  const Eigen::Index ndof = 3 * num_free;
  if (nnz > std::numeric_limits<int>::max()) return invalid_argument("FEM: mesh too large");
  k.resize(ndof, ndof);
  k.resizeNonZeros(nnz);
  int* outer = k.outerIndexPtr();
  int* inner = k.innerIndexPtr();
  // column_start[j] for each free node's first column, and per node the position of each neighbour.
  self_start.resize(static_cast<size_t>(ndof));
  int pos = 0;
  for (Eigen::Index j = 0; j < num_free; ++j) {
    const auto& nb = upper_nbrs[static_cast<size_t>(j)];
    for (int c = 0; c < 3; ++c) {
      outer[3 * j + c] = pos;
      for (int i : nb) {
        const int rows = (i == j) ? c + 1 : 3;
        if (i == j) self_start[static_cast<size_t>(3 * j + c)] = pos;
        for (int r = 0; r < rows; ++r) inner[pos++] = 3 * i + r;
      }
    }
  }
  outer[ndof] = pos;
  k.valuePtr()[0] = 0;
  std::fill(k.valuePtr(), k.valuePtr() + nnz, 0.0);
  // Scatter map. Position of node i's rows in column (3j + c): column start + 9 * (rank of i among
  // j's neighbours) works for c's offset since all neighbour blocks before the self block have 3
  // rows.
  scatter.assign(static_cast<size_t>(t) * 48, -1);
  for (Eigen::Index e = 0; e < t; ++e) {
    for (int a = 0; a < 4; ++a) {
      const int fa = free_index[static_cast<size_t>(mesh.tets(e, a))];
      if (fa < 0) continue;
      for (int b = 0; b < 4; ++b) {
        const int fb = free_index[static_cast<size_t>(mesh.tets(e, b))];
        if (fb < 0 || fa > fb) continue;
        const auto& nb = upper_nbrs[static_cast<size_t>(fb)];
        const auto rank = std::lower_bound(nb.begin(), nb.end(), fa) - nb.begin();
        for (int c = 0; c < 3; ++c) {
          scatter[static_cast<size_t>(e) * 48 + static_cast<size_t>(a * 4 + b) * 3 +
                  static_cast<size_t>(c)] = outer[3 * fb + c] + 3 * static_cast<int>(rank);
        }
      }
    }
  }
  rhs = Eigen::VectorXd::Zero(ndof);
  return {};
}

Result<CorotationalFem> CorotationalFem::create(const TetMesh& mesh,
                                                const std::vector<int>& fixed_nodes,
                                                const CorotationalOptions& options) {
  HC_RETURN_IF_ERROR(options.validate());
  std::vector<char> used;
  HC_RETURN_IF_ERROR(check_mesh(mesh, &used));
  auto impl = std::make_unique<Impl>();
  Impl& s = *impl;
  s.mesh = mesh;
  s.options = options;
  HC_RETURN_IF_ERROR(s.set_rest_geometry());
  HC_RETURN_IF_ERROR(s.number_free_nodes(fixed_nodes, used));
  HC_RETURN_IF_ERROR(s.build_pattern());
  const auto t = static_cast<size_t>(mesh.num_tets());
  s.params.assign(t, LambdaAlpha{});
  s.x = mesh.nodes;
  s.rotations.assign(t, Eigen::Matrix3d::Identity());
  s.quats.assign(t, Eigen::Quaterniond::Identity());
  HC_RETURN_IF_ERROR(s.cholesky.analyze(s.k));
  return CorotationalFem(std::move(impl));
}

const TetMesh& CorotationalFem::mesh() const { return impl_->mesh; }
Eigen::Index CorotationalFem::num_nodes() const { return impl_->mesh.num_nodes(); }
Eigen::Index CorotationalFem::num_elements() const { return impl_->mesh.num_tets(); }
Eigen::Index CorotationalFem::num_free_dofs() const { return 3 * impl_->num_free; }
bool CorotationalFem::is_fixed(Eigen::Index node) const {
  return impl_->free_index[static_cast<size_t>(node)] < 0;
}
const std::vector<int>& CorotationalFem::fixed_nodes() const { return impl_->fixed_nodes; }
int CorotationalFem::dof(Eigen::Index node, int axis) const {
  const int f = impl_->free_index[static_cast<size_t>(node)];
  return f < 0 ? -1 : 3 * f + axis;
}
std::array<int, 12> CorotationalFem::element_dofs(Eigen::Index e) const {
  std::array<int, 12> d{};
  for (int a = 0; a < 4; ++a) {
    for (int c = 0; c < 3; ++c) d[static_cast<size_t>(3 * a + c)] = dof(impl_->mesh.tets(e, a), c);
  }
  return d;
}

double CorotationalFem::volume(Eigen::Index e) const {
  return impl_->volumes[static_cast<size_t>(e)];
}
const Matrix43d& CorotationalFem::shape_gradients(Eigen::Index e) const {
  return impl_->grads[static_cast<size_t>(e)];
}

Matrix6x12d CorotationalFem::b_matrix(Eigen::Index e) const {
  const Matrix43d& g = shape_gradients(e);
  Matrix6x12d b = Matrix6x12d::Zero();
  for (int a = 0; a < 4; ++a) {
    const int c = 3 * a;
    b(0, c) = g(a, 0);
    b(1, c + 1) = g(a, 1);
    b(2, c + 2) = g(a, 2);
    b(3, c) = g(a, 1);
    b(3, c + 1) = g(a, 0);
    b(4, c) = g(a, 2);
    b(4, c + 2) = g(a, 0);
    b(5, c + 1) = g(a, 2);
    b(5, c + 2) = g(a, 1);
  }
  return b;
}

Matrix12d CorotationalFem::stiffness_g(Eigen::Index e) const {
  const Matrix6x12d b = b_matrix(e);
  return volume(e) * b.transpose() * g_matrix() * b;
}
Matrix12d CorotationalFem::stiffness_h(Eigen::Index e) const {
  const Matrix6x12d b = b_matrix(e);
  return volume(e) * b.transpose() * h_matrix() * b;
}
Matrix12d CorotationalFem::element_stiffness(Eigen::Index e) const {
  const Matrix6x12d b = b_matrix(e);
  return volume(e) * b.transpose() * element_elasticity(e) * b;
}

Vector12d CorotationalFem::rest_positions(Eigen::Index e) const {
  Vector12d v;
  for (int a = 0; a < 4; ++a) v.segment<3>(3 * a) = impl_->mesh.nodes.row(impl_->mesh.tets(e, a));
  return v;
}
Vector12d CorotationalFem::current_positions(Eigen::Index e) const {
  Vector12d v;
  for (int a = 0; a < 4; ++a) v.segment<3>(3 * a) = impl_->x.row(impl_->mesh.tets(e, a));
  return v;
}

Status CorotationalFem::set_params(const std::vector<LambdaAlpha>& params) {
  if (static_cast<Eigen::Index>(params.size()) != num_elements()) {
    return invalid_argument("FEM: " + std::to_string(params.size()) + " element parameters for " +
                            std::to_string(num_elements()) + " elements");
  }
  for (size_t e = 0; e < params.size(); ++e) {
    if (!std::isfinite(params[e].lambda) || !std::isfinite(params[e].alpha)) {
      return invalid_argument("FEM: element " + std::to_string(e) + " has non-finite parameters");
    }
  }
  impl_->params = params;
  return {};
}
void CorotationalFem::set_uniform_params(const LambdaAlpha& p) {
  std::fill(impl_->params.begin(), impl_->params.end(), p);
}
const std::vector<LambdaAlpha>& CorotationalFem::params() const { return impl_->params; }

Status CorotationalFem::set_elasticity(std::vector<Matrix6d> elasticity) {
  if (static_cast<Eigen::Index>(elasticity.size()) != num_elements()) {
    return invalid_argument("FEM: " + std::to_string(elasticity.size()) +
                            " elasticity matrices for " + std::to_string(num_elements()) +
                            " elements");
  }
  for (size_t e = 0; e < elasticity.size(); ++e) {
    const Matrix6d& m = elasticity[e];
    if (!m.allFinite()) {
      return invalid_argument("FEM: element " + std::to_string(e) +
                              " has a non-finite elasticity matrix");
    }
    if ((m - m.transpose()).cwiseAbs().maxCoeff() > 1e-9 * m.cwiseAbs().maxCoeff()) {
      return invalid_argument("FEM: element " + std::to_string(e) +
                              " has a non-symmetric elasticity matrix");
    }
  }
  impl_->elasticity = std::move(elasticity);
  return {};
}
void CorotationalFem::clear_elasticity() { impl_->elasticity.clear(); }
bool CorotationalFem::has_elasticity() const { return !impl_->elasticity.empty(); }
Matrix6d CorotationalFem::element_elasticity(Eigen::Index e) const {
  if (!impl_->elasticity.empty()) return impl_->elasticity[static_cast<size_t>(e)];
  return elasticity_matrix(impl_->params[static_cast<size_t>(e)]);
}

Status CorotationalFem::set_positions(const MatrixX3d& x) {
  if (x.rows() != num_nodes()) {
    return invalid_argument("FEM: " + std::to_string(x.rows()) + " positions for " +
                            std::to_string(num_nodes()) + " nodes");
  }
  if (!x.allFinite()) return invalid_argument("FEM: non-finite node positions");
  impl_->x = x;
  return {};
}
const MatrixX3d& CorotationalFem::positions() const { return impl_->x; }
MatrixX3d CorotationalFem::displacements() const { return impl_->x - impl_->mesh.nodes; }

namespace {

Eigen::Matrix3d deformation_gradient(const MatrixX3d& x, const MatrixX4i& tets, Eigen::Index e,
                                     const Matrix43d& g) {
  Eigen::Matrix3d f = Eigen::Matrix3d::Zero();
  for (int a = 0; a < 4; ++a) f.noalias() += x.row(tets(e, a)).transpose() * g.row(a);
  return f;
}

}  // namespace

void CorotationalFem::update_rotations() {
  Impl& s = *impl_;
  if (!s.options.corotational) {
    set_rotations_identity();
    return;
  }
  // Each element's rotation is its own: one of the few loops here worth spreading over cores.
  // Isolated: callers run models in parallel (one per example), and a thread waiting here must
  // not pick up another model's work in the middle of this one's.
  const auto rotate = [&](const tbb::blocked_range<Eigen::Index>& range) {
    for (Eigen::Index e = range.begin(); e < range.end(); ++e) {
      const auto ue = static_cast<size_t>(e);
      const Eigen::Matrix3d f = deformation_gradient(s.x, s.mesh.tets, e, s.grads[ue]);
      s.rotations[ue] = polar_rotation(f, &s.quats[ue], s.options.polar_max_iterations);
    }
  };
  tbb::this_task_arena::isolate([&] {
    tbb::parallel_for(tbb::blocked_range<Eigen::Index>(0, num_elements(), 1024), rotate);
  });
}

const Eigen::Matrix3d& CorotationalFem::rotation(Eigen::Index e) const {
  return impl_->rotations[static_cast<size_t>(e)];
}
void CorotationalFem::set_rotations_identity() {
  std::fill(impl_->rotations.begin(), impl_->rotations.end(), Eigen::Matrix3d::Identity());
  std::fill(impl_->quats.begin(), impl_->quats.end(), Eigen::Quaterniond::Identity());
}

Vector6d CorotationalFem::strain(Eigen::Index e) const {
  const Impl& s = *impl_;
  const auto ue = static_cast<size_t>(e);
  const Eigen::Matrix3d fr =
      s.rotations[ue].transpose() * deformation_gradient(s.x, s.mesh.tets, e, s.grads[ue]);
  Vector6d eps;
  eps << fr(0, 0) - 1, fr(1, 1) - 1, fr(2, 2) - 1, fr(0, 1) + fr(1, 0), fr(0, 2) + fr(2, 0),
      fr(1, 2) + fr(2, 1);
  return eps;
}

Eigen::Matrix<double, Eigen::Dynamic, 6> CorotationalFem::strains() const {
  Eigen::Matrix<double, Eigen::Dynamic, 6> out(num_elements(), 6);
  for (Eigen::Index e = 0; e < num_elements(); ++e) out.row(e) = strain(e).transpose();
  return out;
}

void CorotationalFem::assemble() {
  Impl& s = *impl_;
  double* values = s.k.valuePtr();
  std::fill(values, values + s.k.nonZeros(), 0.0);
  s.rhs.setZero();
  if (!s.elasticity.empty()) {
    assemble_anisotropic();
    return;
  }
  const Eigen::Index t = num_elements();
  const auto& tets = s.mesh.tets;
  for (Eigen::Index e = 0; e < t; ++e) {
    const auto ue = static_cast<size_t>(e);
    const Matrix43d& g = s.grads[ue];
    const double v = s.volumes[ue];
    const LambdaAlpha& p = s.params[ue];
    const double va = v * p.alpha;                      // V * first Lame parameter
    const double vmu = v * (0.5 * p.lambda - p.alpha);  // V * shear modulus
    // Rotated gradients h_a = R g_a (rows). K^w_ab = V [alpha h_a h_b^T + mu h_b h_a^T + mu
    // (g_a.g_b) I] (the isotropic B^T E B written per node pair, rotated: R K_ab R^T).
    const Matrix43d h = g * s.rotations[ue].transpose();
    const int* sc = &s.scatter[ue * 48];
    int fr[4];
    for (int a = 0; a < 4; ++a) fr[a] = s.free_index[static_cast<size_t>(tets(e, a))];
    for (int a = 0; a < 4; ++a) {
      if (fr[a] < 0) continue;
      double* rhs_a = s.rhs.data() + 3 * fr[a];
      // R K_e X_e = V (lambda + alpha) h_a (see header: B X_e = (1,1,1,0,0,0)).
      const double vsum = v * (p.lambda + p.alpha);
      for (int r = 0; r < 3; ++r) rhs_a[r] += vsum * h(a, r);
      for (int b = 0; b < 4; ++b) {
        const double mgg = vmu * g.row(a).dot(g.row(b));
        if (fr[b] >= 0) {
          if (fr[a] > fr[b]) continue;
          const int* col = sc + (a * 4 + b) * 3;
          const int rows_max = (a == b) ? 0 : 2;  // diagonal block: upper triangle only
          for (int c = 0; c < 3; ++c) {
            double* dst = values + col[c];
            const int rmax = (a == b) ? c : rows_max;
            for (int r = 0; r <= rmax; ++r) {
              dst[r] += va * h(a, r) * h(b, c) + vmu * h(b, r) * h(a, c) + (r == c ? mgg : 0.0);
            }
          }
        } else {
          // Fixed neighbour: its known position moves to the right-hand side.
          const Eigen::Vector3d xb = s.x.row(tets(e, b)).transpose();
          const double hb_x = h.row(b).dot(xb.transpose());
          const double ha_x = h.row(a).dot(xb.transpose());
          for (int r = 0; r < 3; ++r) {
            rhs_a[r] -= va * h(a, r) * hb_x + vmu * h(b, r) * ha_x + mgg * xb(r);
          }
        }
      }
    }
  }
}

void CorotationalFem::assemble_anisotropic() {
  // The general form of the isotropic loop above: K^w_e = R^ K_e R^T with R^ = diag(R, R, R, R),
  // i.e. V (B R^T)^T E (B R^T), and the rest-shape term R^ K_e X_e = V R B_a^T E (1,1,1,0,0,0)^T
  // per node a (B X_e is the identity's strain).
  Impl& s = *impl_;
  double* values = s.k.valuePtr();
  const auto& tets = s.mesh.tets;
  Vector6d identity_strain;
  identity_strain << 1, 1, 1, 0, 0, 0;
  for (Eigen::Index e = 0; e < num_elements(); ++e) {
    const auto ue = static_cast<size_t>(e);
    const Eigen::Matrix3d& r = s.rotations[ue];
    const Matrix6x12d b = b_matrix(e);
    Matrix6x12d br;
    for (int a = 0; a < 4; ++a) br.middleCols<3>(3 * a) = b.middleCols<3>(3 * a) * r.transpose();
    const Matrix6d ve = s.volumes[ue] * s.elasticity[ue];
    const Matrix12d kw = br.transpose() * ve * br;
    const Vector12d rest = br.transpose() * (ve * identity_strain);
    const int* sc = &s.scatter[ue * 48];
    int fr[4];
    for (int a = 0; a < 4; ++a) fr[a] = s.free_index[static_cast<size_t>(tets(e, a))];
    for (int a = 0; a < 4; ++a) {
      if (fr[a] < 0) continue;
      double* rhs_a = s.rhs.data() + 3 * fr[a];
      for (int c = 0; c < 3; ++c) rhs_a[c] += rest(3 * a + c);
      for (int b2 = 0; b2 < 4; ++b2) {
        if (fr[b2] >= 0) {
          if (fr[a] > fr[b2]) continue;
          const int* col = sc + (a * 4 + b2) * 3;
          for (int c = 0; c < 3; ++c) {
            double* dst = values + col[c];
            const int rmax = (a == b2) ? c : 2;  // diagonal block: upper triangle only
            for (int row = 0; row <= rmax; ++row) dst[row] += kw(3 * a + row, 3 * b2 + c);
          }
        } else {
          const Eigen::Vector3d xb = s.x.row(tets(e, b2)).transpose();
          for (int row = 0; row < 3; ++row)
            rhs_a[row] -= kw.block<1, 3>(3 * a + row, 3 * b2).dot(xb.transpose());
        }
      }
    }
  }
}

const SparseMatrix& CorotationalFem::stiffness() const { return impl_->k; }

void CorotationalFem::add_to_node_block(Eigen::Index node, const Eigen::Matrix3d& block) {
  Impl& s = *impl_;
  const int f = s.free_index[static_cast<size_t>(node)];
  if (f < 0) return;
  double* values = s.k.valuePtr();
  for (int c = 0; c < 3; ++c) {
    double* dst = values + s.self_start[static_cast<size_t>(3 * f + c)];
    for (int r = 0; r <= c; ++r) dst[r] += block(r, c);
  }
}

void CorotationalFem::add_to_element_block(Eigen::Index e, int a, int b,
                                           const Eigen::Matrix3d& block) {
  Impl& s = *impl_;
  const int fa = s.free_index[static_cast<size_t>(s.mesh.tets(e, a))];
  const int fb = s.free_index[static_cast<size_t>(s.mesh.tets(e, b))];
  if (fa < 0 || fb < 0) return;
  if (a == b) {
    add_to_node_block(s.mesh.tets(e, a), block);
    return;
  }
  // The scatter map stores the pair with the smaller free index as the row node.
  const Eigen::Matrix3d m = fa <= fb ? block : Eigen::Matrix3d(block.transpose());
  const int ra = fa <= fb ? a : b, cb = fa <= fb ? b : a;
  const int* col = &s.scatter[static_cast<size_t>(e) * 48 + static_cast<size_t>(ra * 4 + cb) * 3];
  double* values = s.k.valuePtr();
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) values[col[c] + r] += m(r, c);
}

const Eigen::VectorXd& CorotationalFem::rest_rhs() const { return impl_->rhs; }

Status CorotationalFem::factorize() { return impl_->cholesky.factorize(impl_->k); }
const SparseCholesky& CorotationalFem::cholesky() const { return impl_->cholesky; }

Status CorotationalFem::solve(const MatrixX3d& external_forces) {
  return solve(external_forces, Eigen::VectorXd());
}

Status CorotationalFem::solve(const MatrixX3d& external_forces, const Eigen::VectorXd& extra_rhs) {
  Impl& s = *impl_;
  if (external_forces.rows() != num_nodes()) {
    return invalid_argument("FEM: " + std::to_string(external_forces.rows()) + " force rows for " +
                            std::to_string(num_nodes()) + " nodes");
  }
  if (!external_forces.allFinite()) return invalid_argument("FEM: non-finite external forces");
  HC_ASSIGN_OR_RETURN(const Eigen::VectorXd b, s.load(&external_forces, extra_rhs));
  Eigen::VectorXd xs;
  HC_RETURN_IF_ERROR(s.cholesky.solve(b, &xs));
  if (!xs.allFinite()) return failed_precondition("FEM: solve produced non-finite positions");
  s.set_free_positions(xs);
  return {};
}

Status CorotationalFem::solve_preconditioned(const Eigen::VectorXd& extra_rhs,
                                             const PcgOptions& options, PcgSummary* summary) {
  Impl& s = *impl_;
  *summary = PcgSummary{};
  HC_ASSIGN_OR_RETURN(const Eigen::VectorXd b, s.load(nullptr, extra_rhs));
  if (!s.cholesky.factorized() || s.num_free == 0) return {};
  Eigen::VectorXd x = s.free_positions();
  // Written out rather than Eigen's ConjugateGradient: that stops on the residual relative to b,
  // and here the warm start leaves an increment a millionth of the positions, so the test must be
  // relative to the starting residual; the preconditioner is CHOLMOD's factor (or the caller's).
  const auto k = s.k.selfadjointView<Eigen::Upper>();
  const auto apply = [&](const Eigen::VectorXd& r, Eigen::VectorXd* z) {
    return options.precondition ? options.precondition(r, z) : s.cholesky.solve(r, z);
  };
  Eigen::VectorXd r = b - k * x;
  Eigen::VectorXd z;
  HC_RETURN_IF_ERROR(apply(r, &z));
  double rz = r.dot(z);
  const double stop = options.relative_tolerance * options.relative_tolerance * rz;
  Eigen::VectorXd p = z, kp(b.size());
  int it = 0;
  bool done = !(rz > 0);  // already the solution
  for (; !done && it < options.max_iterations; ++it) {
    kp.noalias() = k * p;
    const double pkp = p.dot(kp);
    if (!(pkp > 0) || !std::isfinite(pkp)) break;  // K not positive definite along p
    const double alpha = rz / pkp;
    x += alpha * p;
    r -= alpha * kp;
    HC_RETURN_IF_ERROR(apply(r, &z));
    const double rz_next = r.dot(z);
    if (rz_next <= stop) {
      done = true;
      ++it;
      break;
    }
    p = z + (rz_next / rz) * p;
    rz = rz_next;
  }
  summary->iterations = it;
  if (!done || !x.allFinite()) return {};
  s.set_free_positions(x);
  summary->converged = true;
  return {};
}

Status CorotationalFem::step(const MatrixX3d& external_forces) {
  update_rotations();
  assemble();
  HC_RETURN_IF_ERROR(factorize());
  return solve(external_forces);
}

Status CorotationalFem::solve_static(const MatrixX3d& external_forces, int max_iterations,
                                     double tolerance_m, int* iterations) {
  int it = 0;
  for (; it < std::max(1, max_iterations); ++it) {
    const MatrixX3d before = impl_->x;
    HC_RETURN_IF_ERROR(step(external_forces));
    const double change = (impl_->x - before).cwiseAbs().maxCoeff();
    if (change <= tolerance_m || !impl_->options.corotational) {
      ++it;
      if (iterations != nullptr) *iterations = it;
      return {};
    }
  }
  if (iterations != nullptr) *iterations = it;
  return failed_precondition("FEM: co-rotational iteration did not converge in " +
                             std::to_string(it) + " iterations");
}

MatrixX3d CorotationalFem::elastic_forces() const {
  const Impl& s = *impl_;
  MatrixX3d f = MatrixX3d::Zero(num_nodes(), 3);
  const auto& tets = s.mesh.tets;
  for (Eigen::Index e = 0; e < num_elements(); ++e) {
    const auto ue = static_cast<size_t>(e);
    const Matrix6x12d b = b_matrix(e);
    const Eigen::Matrix3d& r = s.rotations[ue];
    Vector12d u;
    for (int a = 0; a < 4; ++a) {
      u.segment<3>(3 * a) = r.transpose() * s.x.row(tets(e, a)).transpose() -
                            s.mesh.nodes.row(tets(e, a)).transpose();
    }
    // f_e = -R V B^T E B u (B u is rotation-frame strain; exact also for translated frames as B
    // annihilates translations).
    const Vector6d sigma = element_elasticity(e) * (b * u);
    const Vector12d fl = -s.volumes[ue] * b.transpose() * sigma;
    for (int a = 0; a < 4; ++a) f.row(tets(e, a)) += (r * fl.segment<3>(3 * a)).transpose();
  }
  return f;
}

const CorotationalOptions& CorotationalFem::options() const { return impl_->options; }

}  // namespace hc::fem
