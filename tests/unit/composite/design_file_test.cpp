// Design files: round trip, use as a material (same positions as the composite it describes, a
// different specimen refused), malformed input, and the print file sliced by PrusaSlicer with each
// printer material's filament matching its cells' volume.
#include <gtest/gtest.h>

#include <filesystem>

#include "../export/prusa_slicer.h"
#include "design_fixture.h"
#include "fabrication/composite/design_file.h"

namespace hc::composite {
namespace {

namespace fs = std::filesystem;

Library library_of(const std::vector<BaseMaterial>& models, const std::vector<std::string>& printer) {
  Library lib;
  for (std::size_t i = 0; i < models.size(); ++i)
    lib.materials.push_back({"base" + std::to_string(i), printer[i % printer.size()],
                             "base.json", default_colour(static_cast<int>(i), 9),
                             {"base" + std::to_string(i), printer[i % printer.size()], models[i], nullptr}});
  return lib;
}

TEST(DesignFile, RoundTripAndMaterialMatchTheComposite) {
  const TetMesh mesh = testing::block(4, 4, 3);
  const std::vector<BaseMaterial> models = testing::nine_base_materials();
  const Library lib = library_of(models, {"PLA", "TPU 95A", "TPU 85A"});
  Result<CellGrid> grid = CellGrid::equal_layers(mesh_box(mesh), 3);
  ASSERT_TRUE(grid.ok());
  const std::vector<int> cells = {6, 2, 6};
  const DesignFile d = make_design_file(*grid, lib, cells, Json{{"rms_error_m", 1e-6}});
  EXPECT_EQ(d.materials.size(), 2u);  // only the materials used are embedded
  Result<DesignFile> back = parse_design(dump_json(design_to_json(d)), "d.json");
  ASSERT_TRUE(back.ok()) << back.status().to_string();
  EXPECT_EQ(back->cells, d.cells);
  EXPECT_EQ(back->grid.z_m(), grid->z_m());
  EXPECT_TRUE(is_design_document(dump_json(design_to_json(d))));
  // As a material: the same simulated positions as the composite built from the library.
  const material::Samples loads = testing::load_cases(mesh);
  Result<std::unique_ptr<fem::MaterialModel>> m = design_material(*back, mesh);
  ASSERT_TRUE(m.ok()) << m.status().to_string();
  Result<CompositeMaterial> ref = make_composite(models, element_cells(mesh, *grid), cells, 3);
  ASSERT_TRUE(ref.ok());
  Result<ExampleSimulator> sim = ExampleSimulator::create(loads, ForwardOptions{});
  ASSERT_TRUE(sim.ok());
  Result<MatrixX3d> a = sim->simulate(0, **m);
  Result<MatrixX3d> b = sim->simulate(0, *ref);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_LT((*a - *b).cwiseAbs().maxCoeff(), 1e-12);
  // A different specimen ("a target on a different specimen") is refused, with both sizes.
  const TetMesh other = testing::block(4, 4, 3, 0.03);
  Result<std::unique_ptr<fem::MaterialModel>> bad = design_material(*back, other);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(bad.status().message().find("50 x 50 x 25 mm"), std::string::npos)
      << bad.status().message();
}

TEST(DesignFile, MalformedInputNamesTheKey) {
  const TetMesh mesh = testing::block(2, 2, 2);
  const Library lib = library_of(testing::nine_base_materials(), {"PLA"});
  Result<CellGrid> grid = CellGrid::equal_layers(mesh_box(mesh), 2);
  ASSERT_TRUE(grid.ok());
  const Json good = design_to_json(make_design_file(*grid, lib, {0, 1}));
  const auto expect_error = [&](Json j, const std::string& what) {
    Result<DesignFile> r = parse_design(j.dump(), "d.json");
    ASSERT_FALSE(r.ok()) << what;
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(r.status().message().find(what), std::string::npos) << r.status().message();
  };
  Json j = good;
  j["design"] = Json::array({"base0"});
  expect_error(j, "1 materials for 2 cells");
  j = good;
  j["design"][1] = "nonexistent";
  expect_error(j, "design[1]");
  j = good;
  j["cells"]["z_m"] = Json::array({0.0, 0.02, 0.01});
  expect_error(j, "cells");
  j = good;
  j["specimen"]["box_m"][1][2] = 1.0;
  expect_error(j, "specimen.box_m");
  j = good;
  j["materials"][0]["colour"] = "#GG0000";
  expect_error(j, "materials[0].colour");
  j = good;
  j["materials"][0]["base"]["values"] = Json::array();
  expect_error(j, "materials[0].base");
  j = good;
  j["format"] = "hardcopy.material";
  expect_error(j, "format");
}

// The composite as a print file: one volume per cell; PrusaSlicer 2.5 slices it with one extruder
// per printer material, each extruding its cells' volume within 1 % (expected values: the cells'
// box volumes).
TEST(DesignFile, PrintFileSlicedByPrusaSlicer) {
  if (!hc::testing::prusa_slicer_available()) GTEST_SKIP() << "prusa-slicer is not installed";
  const Library lib = library_of(testing::nine_base_materials(), {"PLA", "TPU 95A", "PETG"});
  // 40 x 50 x 12 mm, 2 x 1 x 3 voxels.
  Result<CellGrid> grid = CellGrid::voxels(
      Eigen::AlignedBox3d(Eigen::Vector3d::Zero(), Eigen::Vector3d(0.04, 0.05, 0.012)), {2, 1, 3});
  ASSERT_TRUE(grid.ok());
  const std::vector<int> cells = {0, 1, 2, 0, 4, 2};  // printer materials PLA TPU PETG PLA TPU PETG
  const DesignFile d = make_design_file(*grid, lib, cells);
  const printfile::MultiMaterialModel model = design_print_model(d);
  ASSERT_EQ(model.materials.size(), 3u);
  ASSERT_EQ(model.objects[0].volumes.size(), 6u);
  const fs::path dir = fs::temp_directory_path() / ("hc_design_print_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  ASSERT_TRUE(printfile::write_multi_material_3mf(dir / "d.3mf", model).ok());
  std::string log;
  const auto used = hc::testing::prusa_slicer_filament_mm3(dir / "d.3mf", 3, dir, &log);
  ASSERT_TRUE(used.has_value()) << log;
  std::vector<double> expected(3, 0.0);
  for (int c = 0; c < grid->num_cells(); ++c)
    expected[static_cast<std::size_t>(model.objects[0].volumes[static_cast<std::size_t>(c)].material)] +=
        1e9 * grid->cell_box(c).volume();
  for (std::size_t i = 0; i < 3; ++i) {
    std::printf("%s: %.1f mm3 extruded, cells %.1f mm3 (%+.2f %%)\n", model.materials[i].name.c_str(),
                (*used)[i], expected[i], 100 * ((*used)[i] / expected[i] - 1));
    EXPECT_NEAR((*used)[i], expected[i], 0.01 * expected[i]);
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace hc::composite
