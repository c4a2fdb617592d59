// A scene without mesh keys is meshed for its contact (contact_meshing.h) and answers the closed
// forms of ANALYTIC_BENCHMARKS.md within 5 % on default settings (the measured errors are next to
// the tests); explicit coarse meshes still
// answer (contact points on the faces keep the probe from slipping between nodes) and converge
// as they are refined.
#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <string>

#include "processing/meshing/tetrahedralize.h"
#include "processing/scene/contact_meshing.h"
#include "processing/scene/scene.h"
#include "sanitizer.h"

namespace hc::scene {
namespace {

// ANALYTIC_BENCHMARKS.md §2: Sneddon's exact rigid sphere, d = (a/2) ln((R+a)/(R−a)),
// F = (E*/2) [(a² + R²) ln((R+a)/(R−a)) − 2 a R] (→ Hertz 4/3 E* √R d^(3/2)).
double sneddon_sphere_force(double e, double nu, double r, double d) {
  double lo = 0, hi = r * (1 - 1e-12);
  for (int it = 0; it < 200; ++it) {
    const double mid = 0.5 * (lo + hi);
    (0.5 * mid * std::log((r + mid) / (r - mid)) < d ? lo : hi) = mid;
  }
  const double a = 0.5 * (lo + hi);
  const double l = std::log((r + a) / (r - a));
  return 0.5 * e / (1 - nu * nu) * ((a * a + r * r) * l - 2 * a * r);
}

// §3: Boussinesq/Sneddon flat punch, F = 2 a E* d.
double punch_force(double e, double nu, double a, double d) {
  return 2 * a * e / (1 - nu * nu) * d;
}

// A block `size` (m) on a fixed base, linear co-rotational material, the probe's reference point
// 0.5 mm above the top face's centre, by depth, no mesh keys.
nlohmann::json contact_scene(const Eigen::Vector3d& size, double e, double nu,
                             const std::string& shape, double radius, double depth) {
  const double lift = shape == "sphere" ? radius + 5e-4 : 5e-4;
  return {{"specimen", {{"box_m", {size.x(), size.y(), size.z()}}}},
          {"material", {{"linear", {{"youngs_pa", e}, {"poisson", nu}}}}},
          {"fixed", "bottom"},
          {"probe",
           {{"shape", shape},
            {"radius_m", radius},
            {"position_m", {size.x() / 2, size.y() / 2, size.z() + lift}},
            {"direction", {0, 0, -1}}}},
          {"load", {{"depth_m", depth}}},
          {"steps", 2}};
}

Result<SimulationResult> simulate_scene(const nlohmann::json& j) {
  HC_ASSIGN_OR_RETURN(Scene s, parse_scene(j.dump(), "scene.json", "/tmp"));
  return simulate(s);
}

// A block 160 contact radii wide and 80 deep, for the half-space formulas. A fixed base stiffens
// the answer by the finite-layer effect (Hayes et al. 1972, ANALYTIC_BENCHMARKS.md §3), not by the
// mesh: measured here with the same meshing, flat punches at 10 radii deep (a/h = 0.1, the issue's
// minimum) gave +9.7 / +14.4 / +9.7 %, spheres at a/h = 0.045-0.075 +4.2 / +9.1 / +9.8 %, and the
// third sphere below still +2.2 % more at 40 radii deep than at 80 (0.33644 against 0.32919 N).
// The graded mesh grows coarse away from the contact, so the larger block costs few tets.
Eigen::Vector3d half_space_block(double contact_radius) {
  return Eigen::Vector3d(160, 160, 80) * contact_radius;
}

struct Case {
  double e, nu, r, d;
};

// The accuracy on default settings, measured with these cases (Release, this machine,
// `ctest -R ContactDefaults --output-on-failure`): spheres +2.5 / +4.6 / +4.6 %, punches
// +0.6 / +4.8 / +2.2 %, ~43k tets each. These are sums of errors of both signs, measured apart
// (2026-11-28, experiments not kept):
// * the linear tets are too stiff: Hertz's pressure applied as loads on the first sphere scene's
//   mesh gives 6.3 % (nu 0) / 5.5 % (nu 0.3) too little displacement at elements a/4, 3.3 / 3.2 %
//   at a/8 (O(h));
// * the contact edge falls between nodes: a punch shifted by 0.1 a steps gives -1.0 ... +6.2 %
//   (the third case), +3.7 ... +7.2 % (the second); a mesh with nodes on the rim gives a steady
//   +13.0 / +9.5 / +7.5 % at a/4, a/6, a/8 (O(h^0.8)): the edge's position, not the rim's
//   resolution, is what the rim-free default gains;
// * the sphere's contact, solved exactly (any solver tolerance or penalty gives the same force to
//   0.1 %), adds -1.8 % (nu 0.3) to +2.4 % (nu 0) to the tets' stiffness.
// So 5 % holds for these cases, for spheres with 0.25 <= nu <= 0.45 and for most punches up to
// nu ~0.4; not for nu near 0 (a sphere at nu 0: +8.7 %).
constexpr double kDefaultSettingsTolerance = 0.05;

// Three sets each: the (0.5 MPa, 0.4, R 10 mm, d 0.5 mm: a 2.2 mm, Hertz 0.887 N) and two
// others.
TEST(ContactDefaults, SphereWithinFivePercentOfSneddon) {
  HC_SKIP_WHEN_SANITIZED("~10x slower: ~40k-tet contact solves");
  const Case cases[] = {
      {0.5e6, 0.4, 0.01, 5e-4}, {2e6, 0.3, 0.005, 2e-4}, {50e3, 0.25, 0.02, 1e-3}};
  for (const Case& c : cases) {
    const Eigen::Vector3d block = half_space_block(std::sqrt(c.r * c.d));
    Result<SimulationResult> r =
        simulate_scene(contact_scene(block, c.e, c.nu, "sphere", c.r, c.d));
    ASSERT_TRUE(r.ok()) << r.status().to_string();
    const double expected = sneddon_sphere_force(c.e, c.nu, c.r, c.d);
    std::printf(
        "sphere E %.3g nu %.2f R %.3g d %.3g: %.5g N vs %.5g N (%+.2f %%), %ld tets, %.1f s\n", c.e,
        c.nu, c.r, c.d, r->force_n, expected, 100 * (r->force_n / expected - 1),
        r->mesh_report.tets, r->time_s);
    EXPECT_EQ(r->mesh_report.method, "contact_adaptive");
    EXPECT_NEAR(r->mesh_report.patch_radius_m, std::sqrt(c.r * c.d), 1e-9);
    EXPECT_NEAR(r->force_n, expected, kDefaultSettingsTolerance * expected);
  }
}

TEST(ContactDefaults, FlatPunchWithinFivePercentOfSneddon) {
  HC_SKIP_WHEN_SANITIZED("~10x slower: ~40k-tet contact solves");
  const Case cases[] = {
      {1e6, 0.3, 0.0025, 2.5e-5}, {0.2e6, 0.45, 0.005, 1e-4}, {3e6, 0.35, 0.002, 1e-5}};
  for (const Case& c : cases) {
    const Eigen::Vector3d block = half_space_block(c.r);
    Result<SimulationResult> r = simulate_scene(contact_scene(block, c.e, c.nu, "flat", c.r, c.d));
    ASSERT_TRUE(r.ok()) << r.status().to_string();
    const double expected = punch_force(c.e, c.nu, c.r, c.d);
    std::printf(
        "punch E %.3g nu %.2f a %.3g d %.3g: %.5g N vs %.5g N (%+.2f %%), %ld tets, %.1f s\n", c.e,
        c.nu, c.r, c.d, r->force_n, expected, 100 * (r->force_n / expected - 1),
        r->mesh_report.tets, r->time_s);
    EXPECT_NEAR(r->force_n, expected, kDefaultSettingsTolerance * expected);
  }
}

// "contact_elements_per_radius" refines the default mesh, and the answer converges: the second
// sphere case above at 4 and 6 elements per contact radius (measured +4.60 / +2.74 %, 43k / 103k
// tets; Sneddon 0.5837 N).
TEST(ContactDefaults, RefiningTheContactMeshConverges) {
  HC_SKIP_WHEN_SANITIZED("~10x slower: a 100k-tet contact solve");
  const Case c{2e6, 0.3, 0.005, 2e-4};
  const double a = std::sqrt(c.r * c.d);
  const double expected = sneddon_sphere_force(c.e, c.nu, c.r, c.d);
  double error[2] = {0, 0};
  long tets[2] = {0, 0};
  for (int k = 0; k < 2; ++k) {
    nlohmann::json j = contact_scene(half_space_block(a), c.e, c.nu, "sphere", c.r, c.d);
    if (k == 1) j["specimen"]["contact_elements_per_radius"] = 6;
    Result<SimulationResult> r = simulate_scene(j);
    ASSERT_TRUE(r.ok()) << r.status().to_string();
    EXPECT_NEAR(r->mesh_report.fine_size_m, a / (k == 0 ? 4 : 6), 1e-12);
    EXPECT_EQ(r->mesh_report.elements_per_radius, k == 0 ? 4 : 6);
    error[k] = r->force_n / expected - 1;
    tets[k] = r->mesh_report.tets;
    std::printf("%d elements per radius: %.5g N (%+.2f %%), %ld tets\n", k == 0 ? 4 : 6, r->force_n,
                100 * error[k], tets[k]);
  }
  EXPECT_GT(tets[1], 2 * tets[0]);
  EXPECT_GT(error[1], 0);  // linear tets converge from the stiff side
  EXPECT_LT(error[1], 0.75 * error[0]);
}

// The answer is the contact's equilibrium, whatever the load steps: with 2 steps one depth
// increment's active set cycled between 58 and 32-36 contact points, and holding one of them
// (as every increment did after 20 iterations) gave 1.657 N against 1.865 N from 10 steps; that
// increment is now solved again in halves (contact.cpp, kCutBackAfter). A case tuned on nothing
// else (inputs chosen after the meshing was: Sneddon 1.8038 N).
TEST(ContactDefaults, SphereForceDoesNotDependOnTheLoadSteps) {
  HC_SKIP_WHEN_SANITIZED("~10x slower: ~40k-tet contact solves");
  const Case c{2e6, 0.3, 0.006, 4e-4};
  const Eigen::Vector3d block = half_space_block(std::sqrt(c.r * c.d));
  nlohmann::json j = contact_scene(block, c.e, c.nu, "sphere", c.r, c.d);
  double force[2] = {0, 0};
  const int steps[2] = {2, 10};
  for (int k = 0; k < 2; ++k) {
    j["steps"] = steps[k];
    Result<SimulationResult> r = simulate_scene(j);
    ASSERT_TRUE(r.ok()) << r.status().to_string();
    force[k] = r->force_n;
  }
  EXPECT_NEAR(force[0], force[1], 1e-3 * force[1]);  // one equilibrium, to the solver's tolerance
  const double expected = sneddon_sphere_force(c.e, c.nu, c.r, c.d);
  EXPECT_NEAR(force[0], expected, kDefaultSettingsTolerance * expected);
}

// Near-incompressible materials are warned about (scene.h, kLockingPoisson), others not; an
// explicit coarse mesh keeps this quick.
TEST(ContactDefaults, NearIncompressibleMaterialsAreWarnedAbout) {
  for (const double nu : {0.3, 0.45, 0.49}) {
    nlohmann::json j = contact_scene({0.05, 0.05, 0.025}, 0.5e6, nu, "sphere", 0.01, 5e-4);
    j["specimen"]["cells"] = {4, 4, 2};
    j["steps"] = 1;
    Result<SimulationResult> r = simulate_scene(j);
    ASSERT_TRUE(r.ok()) << r.status().to_string();
    if (nu >= kLockingPoisson) {
      ASSERT_EQ(r->warnings.size(), 1u) << nu;
      EXPECT_NE(r->warnings[0].find("incompressible"), std::string::npos) << r->warnings[0];
    } else {
      EXPECT_TRUE(r->warnings.empty()) << nu << ": " << r->warnings.front();
    }
  }
}

// The first report: the documented box, no mesh keys, a sphere just above the top face
// (was "the probe does not reach the specimen": the default mesh had almost no nodes). Also by
// force, which needs the specimen's modulus to size the patch (Hertz depth of 0.5 N: 0.36 mm).
TEST(ContactDefaults, TheDocumentedBoxAnswersByDepthAndByForce) {
  nlohmann::json j = contact_scene({0.1, 0.1, 0.05}, 0.5e6, 0.4, "sphere", 0.01, 5e-4);
  j["steps"] = 1;
  j["specimen"]["max_tet_volume_m3"] = 1e-6;  // explicit keys win: a coarse TetGen mesh
  Result<SimulationResult> coarse = simulate_scene(j);
  ASSERT_TRUE(coarse.ok()) << coarse.status().to_string();
  EXPECT_EQ(coarse->mesh_report.method, "tetgen");
  EXPECT_GT(coarse->force_n, 0);
  j["load"] = {{"force_n", 0.5}};
  Result<SimulationResult> by_force = simulate_scene(j);
  ASSERT_TRUE(by_force.ok()) << by_force.status().to_string();
  EXPECT_NEAR(by_force->force_n, 0.5, 1e-3);
}

// Explicit structured meshes from 2 x 2 x 1 cells (a 50 mm cell under a 10 mm sphere: the probe
// meets no node until it has sunk deep, so only the points on the faces carry it) answer, and the
// error falls as they are refined.
TEST(ContactDefaults, ExplicitCoarseMeshesAnswerAndConverge) {
  const double expected = sneddon_sphere_force(0.5e6, 0.4, 0.01, 5e-4);
  double previous = INFINITY;
  for (const int n : {2, 4, 8}) {
    nlohmann::json j = contact_scene({0.1, 0.1, 0.05}, 0.5e6, 0.4, "sphere", 0.01, 5e-4);
    j["specimen"]["cells"] = {n, n, (n + 1) / 2};
    j["probe"]["position_m"] = {0.043, 0.057, 0.0605};  // between the nodes of every grid
    Result<SimulationResult> r = simulate_scene(j);
    ASSERT_TRUE(r.ok()) << n << " cells: " << r.status().to_string();
    const double error = std::abs(r->force_n / expected - 1);
    std::printf("%d x %d x %d cells: %.4g N (%+.1f %%)\n", n, n, (n + 1) / 2, r->force_n,
                100 * (r->force_n / expected - 1));
    EXPECT_GT(r->force_n, 0);
    EXPECT_LT(error, previous);
    previous = error;
  }
}

TEST(ContactDefaults, PatchAndSizeFieldFollowTheProbe) {
  // A sphere by force: Hertz depth d = (3F / (4 E* √R))^(2/3), a = √(R d).
  auto probe = fem::make_sphere_probe(0.01, {0.05, 0.05, 0.07}, {0, 0, -1});
  ASSERT_TRUE(probe.ok());
  const double e_star = 0.5e6 / (1 - 0.16);
  Result<ContactPatch> patch = expected_contact_patch(
      meshing::box_surface({0.1, 0.1, 0.05}), **probe, {fem::LoadControl::kForce, 0.887}, e_star);
  ASSERT_TRUE(patch.ok()) << patch.status().to_string();
  EXPECT_NEAR(patch->depth_m, 5e-4, 2e-6);  // 0.887 N is Hertz's force at 0.5 mm
  EXPECT_NEAR(patch->radius_m, std::sqrt(0.01 * patch->depth_m), 1e-12);
  EXPECT_NEAR((patch->centre_m - Eigen::Vector3d(0.05, 0.05, 0.05)).norm(), 0, 2e-4);
  const meshing::GradedSize size = contact_size_field(
      *patch, Eigen::AlignedBox3d(Eigen::Vector3d::Zero(), Eigen::Vector3d(0.1, 0.1, 0.05)));
  EXPECT_NEAR(size(patch->centre_m), patch->radius_m / 4, 1e-12);
  EXPECT_GT(size({0.0, 0.0, 0.0}), 10 * size(patch->centre_m));
  // A probe whose path misses the block says where both are.
  auto away = fem::make_sphere_probe(0.01, {0.3, 0.05, 0.07}, {0, 0, -1});
  ASSERT_TRUE(away.ok());
  Result<ContactPatch> missed = expected_contact_patch(
      meshing::box_surface({0.1, 0.1, 0.05}), **away, {fem::LoadControl::kDepth, 1e-3}, e_star);
  ASSERT_FALSE(missed.ok());
  EXPECT_NE(missed.status().message().find("misses the specimen"), std::string::npos);
}

}  // namespace
}  // namespace hc::scene
