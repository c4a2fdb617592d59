// Layered simulated specimens (HyperelasticSpecimenOptions::material_layers): the hidden layered
// material of the whole-loop demo. A one-layer stack is the homogeneous block exactly; a stack of a
// soft and a stiff material indents between the two uniform blocks (stiffness is monotone in the
// moduli: the thesis's uniform-fill bounds, Sec. 5.5.3), and closer to the material on top, which
// the probe loads directly; bad stacks are refused naming the layer.
#include <gtest/gtest.h>

#include "common/config.h"
#include "rig_daemon/simulation/hyperelastic_specimen.h"
#include "rig_daemon/simulation/sim_world.h"

namespace hc::devices::sim {
namespace {

constexpr double kSoftPa = 2.0e5, kStiffPa = 1.0e6;

HyperelasticSpecimenOptions block(std::vector<MaterialLayer> layers, double youngs = kSoftPa) {
  HyperelasticSpecimenOptions o;
  o.size_m = {0.03, 0.03};
  o.height_m = 0.016;
  o.layers = 4;  // 4 mm cells
  o.youngs_modulus_pa = youngs;
  o.max_depth_m = 0.002;
  o.depth_steps = 2;
  o.material_layers = std::move(layers);
  return o;
}

double force_at_2mm(const HyperelasticSpecimenOptions& o) {
  auto s = HyperelasticSpecimen::create(o);
  EXPECT_TRUE(s.ok()) << s.status().to_string();
  if (!s.ok()) return 0;
  Indentation ind;
  ind.depth_m = 0.002;
  const double f = (*s)->force_n(ind);
  EXPECT_TRUE((*s)->all_converged());
  return f;
}

TEST(LayeredSpecimen, OneLayerIsTheHomogeneousBlock) {
  EXPECT_EQ(force_at_2mm(block({{0.016, kSoftPa, 0.45, 1.0}})), force_at_2mm(block({})));
}

TEST(LayeredSpecimen, StackIndentsBetweenItsUniformBlocks) {
  const double soft = force_at_2mm(block({}, kSoftPa));
  const double stiff = force_at_2mm(block({}, kStiffPa));
  const double stiff_on_top =
      force_at_2mm(block({{0.008, kSoftPa, 0.45, 1.0}, {0.008, kStiffPa, 0.45, 1.0}}));
  const double soft_on_top =
      force_at_2mm(block({{0.008, kStiffPa, 0.45, 1.0}, {0.008, kSoftPa, 0.45, 1.0}}));
  EXPECT_GT(stiff_on_top, soft);
  EXPECT_LT(stiff_on_top, stiff);
  EXPECT_GT(soft_on_top, soft);
  EXPECT_LT(soft_on_top, stiff);
  // The probe loads the top layer directly: the stiff-on-top stack is the stiffer one.
  EXPECT_GT(stiff_on_top, soft_on_top);
}

TEST(LayeredSpecimen, BadStacksNameTheLayer) {
  Status s = block({{0.006, kSoftPa, 0.45, 1.0}, {0.010, kStiffPa, 0.45, 1.0}}).validate();
  EXPECT_NE(s.message().find("material_layers[0].thickness_m"), std::string::npos) << s.message();
  s = block({{0.008, kSoftPa, 0.45, 1.0}, {0.004, kStiffPa, 0.45, 1.0}}).validate();
  EXPECT_NE(s.message().find("add up to"), std::string::npos) << s.message();
  s = block({{0.008, kSoftPa, 0.5, 1.0}, {0.008, kStiffPa, 0.45, 1.0}}).validate();
  EXPECT_NE(s.message().find("material_layers[0]"), std::string::npos) << s.message();
  // From a rig config's world section, the key is named with its line.
  Result<Config> cfg = parse_config(R"(specimen:
  model: hyperelastic
  material_layers:
    - {thickness_m: 0.015, youngs_modulus_pa: 2.0e5}
    - {thickness_m: 0.015, youngs_modulus_pa: -1}
)",
                                    "world.yaml");
  ASSERT_TRUE(cfg.ok());
  Result<WorldOptions> w = read_config<WorldOptions>(*cfg);
  ASSERT_FALSE(w.ok());
  EXPECT_NE(w.status().message().find("material_layers[1].youngs_modulus_pa"), std::string::npos)
      << w.status().message();
}

}  // namespace
}  // namespace hc::devices::sim
