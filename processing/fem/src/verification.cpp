#include "processing/fem/verification.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <numbers>

#include "common/clock.h"
#include "processing/fem/contact.h"
#include "processing/fem/corotational.h"
#include "processing/fem/material_model.h"
#include "processing/fem/probe.h"

namespace hc::fem {

namespace {

// One side of a graded axis: steps starting at h_min growing by `growth`, scaled to end at
// `length`.
std::vector<double> graded_steps(double length, double h_min, double growth) {
  std::vector<double> steps;
  if (!(length > 0)) return steps;
  double sum = 0, h = h_min;
  while (sum < length * (1 - 1e-9)) {
    steps.push_back(h);
    sum += h;
    h *= growth;
  }
  for (double& s : steps) s *= length / sum;
  return steps;
}

// Deterministic uniform numbers in [-1, 1] (splitmix64), identical on every platform.
double unit_noise(std::uint64_t* state) {
  std::uint64_t z = (*state += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  z ^= z >> 31;
  return 2.0 * (static_cast<double>(z >> 11) * 0x1.0p-53) - 1.0;
}

VerificationCase finish(VerificationCase c) {
  c.error_rel = c.expected != 0 ? std::abs(c.computed - c.expected) / std::abs(c.expected)
                                : std::abs(c.computed);
  c.pass = c.error_rel <= c.tolerance;
  return c;
}

constexpr double kYoungsPa = 1e6;  // ANALYTIC_BENCHMARKS.md worked examples use E = 1 MPa
constexpr double kPoisson = 0.3;

}  // namespace

std::vector<double> graded_coordinates(double lo, double hi, double focus, double h_min,
                                       double growth) {
  focus = std::clamp(focus, lo, hi);
  std::vector<double> out;
  const std::vector<double> left = graded_steps(focus - lo, h_min, growth);
  const std::vector<double> right = graded_steps(hi - focus, h_min, growth);
  double x = lo;
  out.push_back(lo);
  for (auto it = left.rbegin(); it != left.rend(); ++it) out.push_back(x += *it);
  if (!left.empty()) out.back() = focus;
  x = focus;
  for (double s : right) out.push_back(x += s);
  out.back() = hi;
  return out;
}

std::vector<double> uniform_coordinates(double lo, double hi, int cells) {
  std::vector<double> out(static_cast<size_t>(cells) + 1);
  for (int i = 0; i <= cells; ++i) out[static_cast<size_t>(i)] = lo + (hi - lo) * i / cells;
  return out;
}

TetMesh structured_box_mesh(const std::vector<double>& xs, const std::vector<double>& ys,
                            const std::vector<double>& zs) {
  const int nx = static_cast<int>(xs.size()), ny = static_cast<int>(ys.size()),
            nz = static_cast<int>(zs.size());
  TetMesh m;
  m.nodes.resize(static_cast<Eigen::Index>(nx) * ny * nz, 3);
  auto id = [&](int i, int j, int k) { return i + nx * (j + ny * k); };
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) m.nodes.row(id(i, j, k)) << xs[i], ys[j], zs[k];
  const int cells = (nx - 1) * (ny - 1) * (nz - 1);
  m.tets.resize(6L * cells, 4);
  static constexpr int kPerm[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2},
                                      {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  Eigen::Index t = 0;
  for (int k = 0; k + 1 < nz; ++k) {
    for (int j = 0; j + 1 < ny; ++j) {
      for (int i = 0; i + 1 < nx; ++i) {
        for (const auto& p : kPerm) {
          int c[3] = {0, 0, 0};
          int v[4];
          v[0] = id(i, j, k);
          for (int s = 0; s < 3; ++s) {
            c[p[s]] = 1;
            v[s + 1] = id(i + c[0], j + c[1], k + c[2]);
          }
          const Eigen::Vector3d x0 = m.nodes.row(v[0]);
          const double vol = (m.nodes.row(v[1]).transpose() - x0)
                                 .dot((m.nodes.row(v[2]).transpose() - x0)
                                          .cross(m.nodes.row(v[3]).transpose() - x0));
          if (vol < 0) std::swap(v[1], v[2]);
          m.tets.row(t++) << v[0], v[1], v[2], v[3];
        }
      }
    }
  }
  return m;
}

std::vector<int> nodes_on_plane(const TetMesh& mesh, int axis, double value, double tolerance) {
  std::vector<int> out;
  for (Eigen::Index i = 0; i < mesh.num_nodes(); ++i) {
    if (std::abs(mesh.nodes(i, axis) - value) <= tolerance) out.push_back(static_cast<int>(i));
  }
  return out;
}

Result<VerificationCase> verify_patch(bool corotational) {
  const auto t0 = std::chrono::steady_clock::now();
  constexpr double kSize = 0.01;
  constexpr int kCells = 4;
  TetMesh mesh = structured_box_mesh(uniform_coordinates(0, kSize, kCells),
                                     uniform_coordinates(0, kSize, kCells),
                                     uniform_coordinates(0, kSize, kCells));
  // Perturb interior nodes (an irregular patch), keeping every tet positive.
  const double h = kSize / kCells;
  std::uint64_t state = 12345;
  std::vector<int> boundary;
  for (Eigen::Index i = 0; i < mesh.num_nodes(); ++i) {
    bool on_boundary = false;
    for (int a = 0; a < 3; ++a) {
      const double x = mesh.nodes(i, a);
      if (x < 1e-12 || x > kSize - 1e-12) on_boundary = true;
    }
    if (on_boundary) {
      boundary.push_back(static_cast<int>(i));
    } else {
      for (int a = 0; a < 3; ++a) mesh.nodes(i, a) += 0.2 * h * unit_noise(&state);
    }
  }
  CorotationalOptions options;
  options.corotational = corotational;
  HC_ASSIGN_OR_RETURN(CorotationalFem fem, CorotationalFem::create(mesh, boundary, options));
  fem.set_uniform_params(lambda_alpha_from_youngs_poisson(kYoungsPa, kPoisson));
  // A general linear field x = (I + A) X + c (A non-symmetric: strain plus a small rotation).
  Eigen::Matrix3d a;
  a << 1.0, 0.5, -0.3, 0.2, -0.8, 0.4, 0.1, 0.6, 0.7;
  a *= 1e-3;
  const Eigen::RowVector3d c(1e-5, -2e-5, 3e-5);
  const MatrixX3d exact =
      (mesh.nodes * (Eigen::Matrix3d::Identity() + a).transpose()).rowwise() + c;
  MatrixX3d x = mesh.nodes;
  for (int b : boundary) x.row(b) = exact.row(b);
  HC_RETURN_IF_ERROR(fem.set_positions(x));
  const MatrixX3d zero = MatrixX3d::Zero(mesh.num_nodes(), 3);
  HC_RETURN_IF_ERROR(fem.solve_static(zero, 100, 1e-16));
  const double max_disp = (exact - mesh.nodes).rowwise().norm().maxCoeff();
  const double err = (fem.positions() - exact).rowwise().norm().maxCoeff();
  VerificationCase vc;
  vc.name = corotational ? "patch_corotational" : "patch_linear";
  vc.quantity = "max interior position error / max displacement";
  vc.computed = err / max_disp;
  vc.expected = 0;
  vc.tolerance = 1e-8;
  vc.source =
      "constant-strain patch test (Irons; Zienkiewicz & Taylor, The Finite Element Method, ch. 9)";
  vc.tets = static_cast<long>(mesh.num_tets());
  vc.time_s = seconds_since(t0);
  return finish(vc);
}

Result<VerificationCase> verify_cantilever(int level) {
  const auto t0 = std::chrono::steady_clock::now();
  level = std::clamp(level, 1, 6);
  // ANALYTIC_BENCHMARKS.md §4 geometry; load reduced to 1 mN so that linear theory applies.
  constexpr double kL = 0.1, kB = 0.02, kH = 0.01, kP = 1e-3;
  const TetMesh mesh = structured_box_mesh(uniform_coordinates(0, kL, 20 * level),
                                           uniform_coordinates(-kB / 2, kB / 2, 4 * level),
                                           uniform_coordinates(-kH / 2, kH / 2, 2 * level));
  const std::vector<int> clamp = nodes_on_plane(mesh, 0, 0.0, 1e-9);
  HC_ASSIGN_OR_RETURN(CorotationalFem fem, CorotationalFem::create(mesh, clamp));
  fem.set_uniform_params(lambda_alpha_from_youngs_poisson(kYoungsPa, kPoisson));
  // Tip shear traction -P/(b h) in z: consistent nodal loads of a uniform traction on the tip face
  // are the tensor product of the 1D trapezoid weights.
  const std::vector<int> tip = nodes_on_plane(mesh, 0, kL, 1e-9);
  const double hy = kB / (4 * level), hz = kH / (2 * level);
  MatrixX3d f = MatrixX3d::Zero(mesh.num_nodes(), 3);
  std::vector<double> weight(tip.size());
  for (size_t k = 0; k < tip.size(); ++k) {
    const Eigen::Index i = tip[k];
    const bool edge_y = std::abs(std::abs(mesh.nodes(i, 1)) - kB / 2) < 1e-9;
    const bool edge_z = std::abs(std::abs(mesh.nodes(i, 2)) - kH / 2) < 1e-9;
    weight[k] = (edge_y ? 0.5 * hy : hy) * (edge_z ? 0.5 * hz : hz);
    f(i, 2) = -kP * weight[k] / (kB * kH);
  }
  HC_RETURN_IF_ERROR(fem.solve_static(f, 50, 1e-12));
  double deflection = 0, wsum = 0;
  for (size_t k = 0; k < tip.size(); ++k) {
    deflection -= weight[k] * (fem.positions()(tip[k], 2) - mesh.nodes(tip[k], 2));
    wsum += weight[k];
  }
  deflection /= wsum;
  const double inertia = kB * kH * kH * kH / 12;
  const double shear = kYoungsPa / (2 * (1 + kPoisson));
  const double expected =
      kP * kL * kL * kL / (3 * kYoungsPa * inertia) + kP * kL / (5.0 / 6.0 * shear * kB * kH);
  VerificationCase vc;
  vc.name = "cantilever";
  vc.quantity = "tip deflection (m)";
  vc.computed = deflection;
  vc.expected = expected;
  vc.tolerance = 0.10;
  vc.source =
      "Timoshenko: P L^3/(3 E I) + P L/(kappa G A), kappa = 5/6 (ANALYTIC_BENCHMARKS.md §4)";
  vc.level = level;
  vc.tets = static_cast<long>(mesh.num_tets());
  vc.time_s = seconds_since(t0);
  return finish(vc);
}

namespace {

constexpr double kBlockHalfWidthInA = 20;  // block is 40a x 40a x 20a
constexpr double kGrowth = 1.35;

TetMesh indentation_block(double a, int level) {
  const double h_min = a / (2.0 * level);
  const double w = kBlockHalfWidthInA * a;
  const std::vector<double> xy = graded_coordinates(-w, w, 0, h_min, kGrowth);
  const std::vector<double> z = graded_coordinates(-w, 0, 0, h_min, kGrowth);
  return structured_box_mesh(xy, xy, z);
}

Result<double> indentation_force(const TetMesh& mesh, const Probe& probe, double depth) {
  const double bottom = mesh.nodes.col(2).minCoeff();
  HC_ASSIGN_OR_RETURN(CorotationalFem fem,
                      CorotationalFem::create(mesh, nodes_on_plane(mesh, 2, bottom, 1e-12)));
  fem.set_uniform_params(lambda_alpha_from_youngs_poisson(kYoungsPa, kPoisson));
  HC_ASSIGN_OR_RETURN(ContactSolver contact, ContactSolver::create(&fem, probe));
  ContactSummary s;
  HC_RETURN_IF_ERROR(contact.solve_depth(depth, &s));
  return s.force_n;
}

}  // namespace

Result<VerificationCase> verify_flat_punch(int level) {
  const auto t0 = std::chrono::steady_clock::now();
  level = std::clamp(level, 1, 6);
  constexpr double kA = 2.5e-3;  // ANALYTIC_BENCHMARKS.md §3 worked example radius
  const double depth = 0.01 * kA;
  const TetMesh mesh = indentation_block(kA, level);
  HC_ASSIGN_OR_RETURN(std::unique_ptr<Probe> probe,
                      make_flat_probe(kA, Eigen::Vector3d(0, 0, kA), Eigen::Vector3d(0, 0, -1)));
  HC_ASSIGN_OR_RETURN(double force, indentation_force(mesh, *probe, depth));
  const double e_star = kYoungsPa / (1 - kPoisson * kPoisson);
  VerificationCase vc;
  vc.name = "flat_punch";
  vc.quantity = "force (N)";
  vc.computed = force;
  vc.expected = 2 * kA * e_star * depth;
  vc.tolerance = 0.10;
  vc.source = "Boussinesq/Sneddon flat punch F = 2 a E* d (ANALYTIC_BENCHMARKS.md §3)";
  vc.level = level;
  vc.tets = static_cast<long>(mesh.num_tets());
  vc.time_s = seconds_since(t0);
  return finish(vc);
}

Result<VerificationCase> verify_sphere(int level) {
  const auto t0 = std::chrono::steady_clock::now();
  level = std::clamp(level, 1, 6);
  constexpr double kR = 0.01, kDepth = 1e-4;
  const double a_hertz = std::sqrt(kR * kDepth);
  const TetMesh mesh = indentation_block(a_hertz, level);
  HC_ASSIGN_OR_RETURN(
      std::unique_ptr<Probe> probe,
      make_sphere_probe(kR, Eigen::Vector3d(0, 0, kR + 1e-3), Eigen::Vector3d(0, 0, -1)));
  HC_ASSIGN_OR_RETURN(double force, indentation_force(mesh, *probe, kDepth));
  // Sneddon 1965: d = (a/2) ln((R+a)/(R-a)); solve for a by bisection, then F.
  double lo = 0, hi = kR * (1 - 1e-12);
  for (int it = 0; it < 200; ++it) {
    const double mid = 0.5 * (lo + hi);
    const double d = 0.5 * mid * std::log((kR + mid) / (kR - mid));
    (d < kDepth ? lo : hi) = mid;
  }
  const double a = 0.5 * (lo + hi);
  const double e_star = kYoungsPa / (1 - kPoisson * kPoisson);
  const double l = std::log((kR + a) / (kR - a));
  VerificationCase vc;
  vc.name = "sphere";
  vc.quantity = "force (N)";
  vc.computed = force;
  vc.expected = 0.5 * e_star * ((a * a + kR * kR) * l - 2 * a * kR);
  vc.tolerance = 0.10;
  vc.source =
      "Sneddon 1965 exact sphere (-> Hertz F = 4/3 E* R^1/2 d^3/2) (ANALYTIC_BENCHMARKS.md §1-2)";
  vc.level = level;
  vc.tets = static_cast<long>(mesh.num_tets());
  vc.time_s = seconds_since(t0);
  return finish(vc);
}

std::vector<VerificationCase> run_verification(int level, std::vector<Status>* errors) {
  std::vector<VerificationCase> out;
  auto add = [&](Result<VerificationCase> r, const char* name) {
    if (r.ok()) {
      out.push_back(*r);
    } else {
      VerificationCase failed;
      failed.name = name;
      failed.pass = false;
      failed.level = level;
      out.push_back(failed);
      if (errors != nullptr) errors->push_back(r.status());
    }
  };
  add(verify_patch(false), "patch_linear");
  add(verify_patch(true), "patch_corotational");
  add(verify_cantilever(level), "cantilever");
  add(verify_flat_punch(level), "flat_punch");
  add(verify_sphere(level), "sphere");
  return out;
}

}  // namespace hc::fem
