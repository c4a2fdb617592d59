// The data-driven non-linear material (thesis Sec. 4.2.3): per element, (λ, α) as a radial-basis-
// function interpolant over the rotated-frame strain 6-vector (Eq. 4.9, φ(r) = r), and its JSON
// file format. An RbfMaterial implements processing/fem's MaterialModel, so incremental loading
// can simulate with it.
//
// JSON layout (version 1; SI units: Pa; strains dimensionless, Eq. 4.1 order with engineering
// shears as in processing/fem/corotational.h):
//   {
//     "format": "hardcopy.material", "version": 1,
//     "kind": "heterogeneous",                 // one RBF per mesh element, in tet order
//     "elements": [RBF, ...]
//   }
// or
//   {
//     "format": "hardcopy.material", "version": 1,
//     "kind": "base",                          // named homogeneous materials (Ch. 5 base
//     materials) "materials": [{"name": "foam", "rbf": RBF}, ...], "element_material": [0, 0, 1,
//     ...]       // optional: material index per element; absent =
//   }                                          // every element uses materials[0] (any mesh size)
// with
//   RBF = {"centres": [[e_xx,e_yy,e_zz,g_xy,g_xz,g_yz], ...],   // M ≥ 0 centres in strain space
//          "weights": [[w_lambda, w_alpha], ...],                 // M weights (Pa)
//          "constant": [c_lambda, c_alpha],                       // polynomial term (Pa)
//          "lambda_floor_pa": f,                                  // > 0, lower bound on λ
//          "max_poisson": 0.49}                                   // optional, in (0, 0.5)
// Evaluation: p(ε) = c + Σ_i w_i ‖ε − ε_i‖, then projected to a physically valid value:
// λ ≥ lambda_floor_pa and 0 ≤ ν = α/λ ≤ max_poisson (thesis Sec. 4.6: "we limit Poisson's ratio to
// physically valid values").
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "common/json.h"
#include "common/status.h"
#include "processing/fem/corotational.h"
#include "processing/fem/material_model.h"

namespace hc::material {

using fem::LambdaAlpha;
using fem::Vector6d;

inline constexpr std::string_view kMaterialFormat = "hardcopy.material";
inline constexpr int kMaterialVersion = 1;
inline constexpr double kDefaultMaxPoisson = 0.49;

// One interpolant p(ε): R⁶ → R² (Eq. 4.9) with the biharmonic kernel φ(r) = r plus a constant
// term. φ(r) = r is only conditionally positive definite (order 1), so the constant polynomial
// makes interpolation well-posed (Carr et al. 2001, Sec. 3); it also carries the average material
// when the basis is small.
struct StrainRbf {
  std::vector<Vector6d> centres;                     // M centres
  Eigen::Matrix<double, Eigen::Dynamic, 2> weights;  // M by 2: (w_λ, w_α) in Pa
  Eigen::Vector2d constant = Eigen::Vector2d::Zero();
  double lambda_floor_pa = 1.0;
  double max_poisson = kDefaultMaxPoisson;

  Eigen::Index size() const { return static_cast<Eigen::Index>(centres.size()); }
  // Unprojected c + Σ w_i ‖ε − ε_i‖ as (λ, α).
  Eigen::Vector2d evaluate_raw(const Vector6d& strain) const;
  // Projected onto λ ≥ lambda_floor_pa, 0 ≤ α ≤ max_poisson·λ.
  LambdaAlpha evaluate(const Vector6d& strain) const;
  // Finite values, matching sizes, lambda_floor_pa > 0, max_poisson in (0, 0.5).
  Status validate() const;
};

// (λ, α) projected onto λ ≥ lambda_floor, 0 ≤ α/λ ≤ max_poisson.
LambdaAlpha project_valid(const Eigen::Vector2d& p, double lambda_floor_pa, double max_poisson);

enum class MaterialKind { kHeterogeneous, kBase };

struct Material {
  MaterialKind kind = MaterialKind::kHeterogeneous;
  std::vector<StrainRbf> rbfs;        // heterogeneous: one per element; base: one per material
  std::vector<std::string> names;     // base: one per material; heterogeneous: empty
  std::vector<int> element_material;  // base: per-element index into rbfs, or empty (all use 0)

  // Elements described: heterogeneous #rbfs, base with element_material its size, else -1 (any).
  Eigen::Index num_elements() const;
  const StrainRbf& rbf_of(Eigen::Index element) const;
  Status validate() const;
};

// The MaterialModel over a Material (thread-compatible; evaluation is const).
class RbfMaterial final : public fem::MaterialModel {
 public:
  explicit RbfMaterial(Material material) : material_(std::move(material)) {}
  LambdaAlpha params(Eigen::Index element, const Vector6d& strain) const override;
  Eigen::Index num_elements() const override { return material_.num_elements(); }
  const Material& material() const { return material_; }

 private:
  Material material_;
};

// Parses a material document; `name` prefixes error messages. kInvalidArgument on malformed JSON,
// wrong format, unknown version or kind, missing keys, wrong sizes, non-finite numbers.
Result<Material> parse_material(std::string_view text, std::string_view name);
Result<Material> read_material(const std::filesystem::path& path);
// The file as a MaterialModel (an RbfMaterial) for fem's incremental loading.
Result<std::unique_ptr<fem::MaterialModel>> load_material(const std::filesystem::path& path);

Json material_to_json(const Material& material);
// Validates, then writes atomically.
Status save_material(const std::filesystem::path& path, const Material& material);

}  // namespace hc::material
