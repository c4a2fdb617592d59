// The transversely isotropic fibre term of the reference model (psi_f = E_f/8 (I4 - 1)^2): stress
// and tangent against finite differences, and its small-strain stiffness.
#include <gtest/gtest.h>

#include <random>

#include "processing/hyperelastic/neo_hookean.h"

namespace hc::hyperelastic {
namespace {

NeoHookeanMaterial fibred(const Eigen::Vector3d& axis) {
  NeoHookeanMaterial m;
  m.youngs_pa = 2e5;
  m.poisson = 0.3;
  m.stiffening = 1.0;
  m.fibre_pa = 5e5;
  m.fibre_axis = axis.normalized();
  return m;
}

TEST(Fibre, StressAndTangentMatchFiniteDifferences) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-0.25, 0.25);
  for (const Eigen::Vector3d& axis : {Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(1, 2, -0.5)}) {
    const NeoHookeanMaterial m = fibred(axis);
    for (int trial = 0; trial < 10; ++trial) {
      Eigen::Matrix3d F = Eigen::Matrix3d::Identity();
      for (int i = 0; i < 9; ++i) F.data()[i] += u(rng);
      ASSERT_GT(F.determinant(), 0);
      Eigen::Matrix3d P;
      Eigen::Matrix<double, 9, 9> T;
      neo_hookean_density(m, F, &P, &T);
      const double h = 1e-6;
      for (int i = 0; i < 9; ++i) {
        Eigen::Matrix3d Fp = F, Fm = F;
        Fp.data()[i] += h;
        Fm.data()[i] -= h;
        const double dpsi = (neo_hookean_density(m, Fp, nullptr, nullptr) -
                             neo_hookean_density(m, Fm, nullptr, nullptr)) /
                            (2 * h);
        EXPECT_NEAR(P.data()[i], dpsi, 1e-6 * m.fibre_pa) << "entry " << i;
        Eigen::Matrix3d Pp, Pm;
        neo_hookean_density(m, Fp, &Pp, nullptr);
        neo_hookean_density(m, Fm, &Pm, nullptr);
        const Eigen::Matrix3d dP = (Pp - Pm) / (2 * h);
        for (int j = 0; j < 9; ++j) EXPECT_NEAR(T(j, i), dP.data()[j], 1e-5 * m.fibre_pa);
      }
    }
  }
}

// At F = I the tangent is linear elasticity plus E_f on the axial normal entry only: dP33/dF33 =
// lambda + 2 mu + E_f, dP11/dF11 = lambda + 2 mu, shear dP13/dF13 = mu (transverse isotropy with
// C33 = C11 + E_f; expected values from the energy's second derivative at rest).
TEST(Fibre, SmallStrainStiffnessAddsToTheAxisOnly) {
  const NeoHookeanMaterial m = fibred(Eigen::Vector3d::UnitZ());
  Eigen::Matrix3d P;
  Eigen::Matrix<double, 9, 9> T;
  neo_hookean_density(m, Eigen::Matrix3d::Identity(), &P, &T);
  const double lambda = m.lambda_pa(), mu = m.mu_pa();
  EXPECT_NEAR(T(8, 8), lambda + 2 * mu + m.fibre_pa, 1e-9 * m.fibre_pa);
  EXPECT_NEAR(T(0, 0), lambda + 2 * mu, 1e-9 * m.fibre_pa);
  EXPECT_NEAR(T(6, 6), mu, 1e-9 * m.fibre_pa);  // dP(0,2)/dF(0,2): index 3 * 2 + 0
  EXPECT_LT(P.norm(), 1e-9);
  NeoHookeanMaterial bad = m;
  bad.fibre_pa = -1;
  EXPECT_FALSE(bad.validate().ok());
  bad = m;
  bad.fibre_axis = Eigen::Vector3d(0, 0, 2);
  EXPECT_FALSE(bad.validate().ok());
}

}  // namespace
}  // namespace hc::hyperelastic
