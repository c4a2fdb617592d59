// Base materials: the feasibility projections, the cardinal RBF, the elasticity matrices, and the
// base-material and library files (round trip and malformed input).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <filesystem>
#include <fstream>
#include <random>

#include "fabrication/composite/base_material.h"
#include "fabrication/composite/library.h"

namespace hc::composite {
namespace {

namespace fs = std::filesystem;

Eigen::VectorXd vec(std::initializer_list<double> v) {
  Eigen::VectorXd out(static_cast<Eigen::Index>(v.size()));
  Eigen::Index i = 0;
  for (double x : v) out(i++) = x;
  return out;
}

// Isotropic: (E, nu) of the projection lie in the limits; feasible points do not move.
TEST(Projection, IsotropicClampsYoungsAndPoisson) {
  FeasibilityLimits l;
  l.min_modulus_pa = 1e3;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1e6, 1e6);
  for (int k = 0; k < 200; ++k) {
    const Eigen::VectorXd q = project_feasible(BaseModel::kIsotropic, vec({u(rng), u(rng)}), l);
    const double lambda = q(0), mu = q(1);
    const double e = mu * (3 * lambda + 2 * mu) / (lambda + mu);
    const double nu = lambda / (2 * (lambda + mu));
    EXPECT_GE(e, l.min_modulus_pa * (1 - 1e-12));
    EXPECT_GE(nu, l.min_poisson - 1e-12);
    EXPECT_LE(nu, l.max_poisson + 1e-12);
    EXPECT_TRUE(is_feasible(BaseModel::kIsotropic, q, l));
    EXPECT_LT((project_feasible(BaseModel::kIsotropic, q, l) - q).norm(), 1e-9 * q.norm());
  }
  // E = 1 MPa, nu = 0.3: lambda = 576.9 kPa, mu = 384.6 kPa (Eq. 4.7) is already feasible.
  const Eigen::VectorXd p = vec({1e6 * 0.3 / (1.3 * 0.4), 1e6 / 2.6});
  EXPECT_LT((project_feasible(BaseModel::kIsotropic, p, l) - p).norm(), 1e-9 * p.norm());
}

// Transverse: the closed-form positive-definiteness conditions hold after projection, the result
// is still of the form of Eq. 5.6, and no feasible transversely isotropic matrix is closer in the
// Frobenius norm (checked against random feasible ones).
TEST(Projection, TransverseKeepsStructureAndPositiveDefiniteness) {
  FeasibilityLimits l;
  l.min_modulus_pa = 1e2;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1e6, 1e6);
  for (int k = 0; k < 100; ++k) {
    const Eigen::VectorXd p = vec({u(rng), u(rng), u(rng), u(rng), u(rng)});
    const Eigen::VectorXd q = project_feasible(BaseModel::kTransverse, p, l);
    EXPECT_GT(q(4), 0);
    EXPECT_GT(q(0), std::abs(q(1)));
    EXPECT_GT(q(3), 0);
    EXPECT_GT(q(3) * (q(0) + q(1)), 2 * q(2) * q(2));
    const Matrix6d e = elasticity_matrix(BaseModel::kTransverse, q);
    EXPECT_GT(Eigen::SelfAdjointEigenSolver<Matrix6d>(e).eigenvalues().minCoeff(), 0);
    const double dist = (e - elasticity_matrix(BaseModel::kTransverse, p)).norm();
    for (int t = 0; t < 50; ++t) {
      const Eigen::VectorXd r = project_feasible(
          BaseModel::kTransverse, q + 1e5 * vec({u(rng), u(rng), u(rng), u(rng), u(rng)}) / 1e6, l);
      EXPECT_GE((elasticity_matrix(BaseModel::kTransverse, r) -
                 elasticity_matrix(BaseModel::kTransverse, p))
                        .norm(),
                dist * (1 - 1e-9));
    }
  }
}

// A modulus of 1e30 Pa beside ones of 1e5 Pa (found by fuzz_base_material): the projection keeps
// the stiffness's condition number within 1e9, so double precision still finds it positive
// definite; ordinary materials (condition numbers below 1e4) do not move.
TEST(Projection, TransverseStaysPositiveDefiniteInDoublePrecision) {
  FeasibilityLimits l;
  l.min_modulus_pa = 1e2;
  for (const double huge : {1e12, 1e20, 4.2e30, 1e300}) {
    const Eigen::VectorXd q =
        project_feasible(BaseModel::kTransverse, vec({huge, 1e5, 1e5, 9e5, 1.2e5}), l);
    const Eigen::VectorXd ev =
        Eigen::SelfAdjointEigenSolver<Matrix6d>(elasticity_matrix(BaseModel::kTransverse, q))
            .eigenvalues();
    EXPECT_GT(ev.minCoeff(), 0) << huge;
    EXPECT_LE(ev.maxCoeff() / ev.minCoeff(), 1.01e9) << huge;
  }
  const Eigen::VectorXd fibre = vec({4e5, 1e5, 1e5, 9e5, 1.2e5});
  EXPECT_EQ(project_feasible(BaseModel::kTransverse, fibre, l), fibre);
}

// Eq. 5.6 in Eq. 4.1 order, and isotropy as its special case: E11 = lambda + 2 mu, E12 = E13 =
// lambda, E33 = E11, E44 = mu reproduce the isotropic matrix.
TEST(Elasticity, TransverseReducesToIsotropic) {
  const double lambda = 3e5, mu = 2e5;
  const Matrix6d iso = elasticity_matrix(BaseModel::kIsotropic, vec({lambda, mu}));
  const Matrix6d ti =
      elasticity_matrix(BaseModel::kTransverse, vec({lambda + 2 * mu, lambda, lambda, lambda + 2 * mu, mu}));
  EXPECT_LT((iso - ti).norm(), 1e-9 * iso.norm());
  // Eq. 4.6 with lambda_th = 2 (lambda + mu), alpha = lambda (processing/fem's parameters).
  const Matrix6d fem = fem::elasticity_matrix({2 * (lambda + mu), lambda});
  EXPECT_LT((iso - fem).norm(), 1e-9 * iso.norm());
  const fem::LambdaAlpha back = isotropic_stand_in(iso);
  EXPECT_NEAR(back.lambda, 2 * (lambda + mu), 1e-6);
  EXPECT_NEAR(back.alpha, lambda, 1e-6);
}

TEST(Features, InvariantsAreRotationInvariant) {
  Vector6d s;
  s << 0.01, -0.02, 0.005, 0.012, -0.004, 0.007;
  Eigen::Matrix3d t;
  t << s(0), s(3) / 2, s(4) / 2, s(3) / 2, s(1), s(5) / 2, s(4) / 2, s(5) / 2, s(2);
  const Eigen::Matrix3d r = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const Eigen::Matrix3d tr = r * t * r.transpose();
  Vector6d sr;
  sr << tr(0, 0), tr(1, 1), tr(2, 2), 2 * tr(0, 1), 2 * tr(0, 2), 2 * tr(1, 2);
  EXPECT_LT((strain_features(BaseModel::kIsotropic, s) - strain_features(BaseModel::kIsotropic, sr)).norm(),
            1e-12);
  // Uniaxial compression eps_zz = -e: I1 = -e, sqrt(J2) = e / sqrt 3, cbrt(J3) = -e cbrt(2) / 3.
  Vector6d u = Vector6d::Zero();
  u(2) = -0.03;
  const Eigen::VectorXd f = strain_features(BaseModel::kIsotropic, u);
  EXPECT_NEAR(f(0), -0.03, 1e-15);
  EXPECT_NEAR(f(1), 0.03 / std::sqrt(3.0), 1e-15);
  EXPECT_NEAR(f(2), -0.03 * std::cbrt(2.0) / 3, 1e-15);
}

TEST(CardinalRbf, InterpolatesCentresAndConstants) {
  Eigen::MatrixXd c(4, 3);
  c << 0, 0, 0, -0.1, 0.05, 0, 0, 0.1, 0.02, 0.05, 0, -0.03;
  Result<CardinalRbf> rbf = CardinalRbf::create(c);
  ASSERT_TRUE(rbf.ok());
  for (Eigen::Index i = 0; i < 4; ++i) {
    const Eigen::VectorXd w = rbf->weights(c.row(i).transpose());
    EXPECT_LT((w - Eigen::VectorXd::Unit(4, i)).norm(), 1e-12);
  }
  EXPECT_NEAR(rbf->weights(Eigen::Vector3d(0.3, -0.2, 0.1)).sum(), 1.0, 1e-12);
  c.row(2) = c.row(1);
  EXPECT_EQ(CardinalRbf::create(c).status().code(), StatusCode::kInvalidArgument);
}

BaseMaterialFile sample_file() {
  Eigen::MatrixXd c(2, 3);
  c << 0, 0, 0, -0.1, 0.05, 0;
  Eigen::MatrixXd v(2, 2);
  v << 1e5, 5e4, 2e5, 9e4;
  Result<BaseMaterial> m = BaseMaterial::create(BaseModel::kIsotropic, c, v, FeasibilityLimits{});
  EXPECT_TRUE(m.ok());
  return {"foam", "TPU 85A", std::move(m).value(), Json{{"rms_error_m", 1e-5}}};
}

TEST(BaseMaterialFile, RoundTrip) {
  const BaseMaterialFile f = sample_file();
  Result<BaseMaterialFile> back = parse_base_material(dump_json(base_material_to_json(f)), "x");
  ASSERT_TRUE(back.ok()) << back.status().to_string();
  EXPECT_EQ(back->name, "foam");
  EXPECT_EQ(back->printer_material, "TPU 85A");
  EXPECT_EQ(back->material.values(), f.material.values());
  EXPECT_EQ(back->material.centres(), f.material.centres());
  EXPECT_DOUBLE_EQ(back->fit["rms_error_m"].get<double>(), 1e-5);
}

TEST(BaseMaterialFile, MalformedInputNamesTheKey) {
  const Json good = base_material_to_json(sample_file());
  const auto expect_error = [&](Json j, const std::string& what) {
    Result<BaseMaterialFile> r = parse_base_material(j.dump(), "b.json");
    ASSERT_FALSE(r.ok()) << what;
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(r.status().message().find(what), std::string::npos) << r.status().message();
  };
  Json j = good;
  j["units"]["stress"] = "MPa";
  expect_error(j, "units.stress");
  j = good;
  j["model"] = "orthotropic";
  expect_error(j, "model");
  j = good;
  j["values"][1] = Json::array({1.0, 2.0, 3.0});
  expect_error(j, "values[1]");
  j = good;
  j["centres"][1] = j["centres"][0];
  expect_error(j, "coincide");
  j = good;
  j["limits"]["max_poisson"] = 0.7;
  expect_error(j, "limits");
  j = good;
  j["colour"] = "red";
  expect_error(j, "unknown key 'colour'");
  j = good;
  j["version"] = 2;
  expect_error(j, "version");
  EXPECT_FALSE(parse_base_material("{\"format\": ", "b.json").ok());
  EXPECT_FALSE(parse_base_material("[]", "b.json").ok());
}

TEST(Library, ReadsFilesRelativeToItselfAndRejectsBadOnes) {
  const fs::path dir = fs::temp_directory_path() / ("hc_library_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  ASSERT_TRUE(save_base_material(dir / "foam.json", sample_file()).ok());
  const auto write = [&](const std::string& text) {
    std::ofstream(dir / "lib.json") << text;
    return read_library(dir / "lib.json");
  };
  Result<Library> lib = write(R"({"materials": [{"name": "soft", "file": "foam.json"},
      {"name": "hard", "file": "foam.json", "printer_material": "PLA", "colour": "#102030"}]})");
  ASSERT_TRUE(lib.ok()) << lib.status().to_string();
  EXPECT_EQ(lib->materials[0].printer_material, "TPU 85A");  // from the base file
  EXPECT_EQ(lib->materials[1].printer_material, "PLA");
  EXPECT_EQ(lib->materials[1].colour, (std::array<std::uint8_t, 3>{0x10, 0x20, 0x30}));
  EXPECT_EQ(lib->find("hard"), 1);
  const auto expect_error = [&](const std::string& text, const std::string& what) {
    Result<Library> r = write(text);
    ASSERT_FALSE(r.ok()) << what;
    EXPECT_NE(r.status().message().find(what), std::string::npos) << r.status().message();
  };
  expect_error(R"({"materials": []})", "the library lists no base materials");
  expect_error(R"({"materials": [{"name": "a", "file": "missing.json"}]})", "materials[0]");
  expect_error(R"({"materials": [{"name": "a", "file": "foam.json"}, {"name": "a", "file": "foam.json"}]})",
               "listed twice");
  expect_error(R"({"materials": [{"name": "a", "file": "foam.json", "colour": "#12345"}]})", "colour");
  expect_error(R"({"material": []})", "unknown key");
  fs::remove_all(dir);
}

}  // namespace
}  // namespace hc::composite
