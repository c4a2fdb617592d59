// The multi-material 3MF, checked by third-party programs: lib3mf reads every object, volume
// triangle and material back; PrusaSlicer 2.5 (Debian's prusa-slicer, headless --export-gcode with a
// multi-extruder configuration) slices it with every volume on its own extruder.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>

#include "Model/COM/NMR_DLLInterfaces.h"
#include "fabrication/export/multi_material_3mf.h"

namespace hc::printfile {
namespace {

namespace fs = std::filesystem;

fs::path temp_dir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("hc_export_" + name + "_" + std::to_string(::getpid()));
  fs::create_directories(d);
  return d;
}

// Layers of a 40 x 50 mm block stacked in z (metres), each its own volume and material, plus an
// optional split of the top layer into two side-by-side volumes (voxel-like cells).
MultiMaterialModel layered_block(const std::vector<double>& z_mm, bool split_top) {
  MultiMaterialModel m;
  m.materials = {{"PLA red", {200, 30, 30}}, {"PLA green", {30, 160, 60}},
                 {"TPU 95A blue", {40, 60, 200}}};
  PrintObject o;
  o.name = "composite";
  for (std::size_t i = 0; i + 1 < z_mm.size(); ++i) {
    const double z0 = z_mm[i] / 1000, z1 = z_mm[i + 1] / 1000;
    if (split_top && i + 2 == z_mm.size()) {
      o.volumes.push_back({"top left", box_triangles({Eigen::Vector3d(0, 0, z0), Eigen::Vector3d(0.02, 0.05, z1)}), 0});
      o.volumes.push_back({"top right", box_triangles({Eigen::Vector3d(0.02, 0, z0), Eigen::Vector3d(0.04, 0.05, z1)}), 2});
    } else {
      o.volumes.push_back({"layer " + std::to_string(i),
                           box_triangles({Eigen::Vector3d(0, 0, z0), Eigen::Vector3d(0.04, 0.05, z1)}),
                           static_cast<int>(i % 3)});
    }
  }
  m.objects.push_back(std::move(o));
  return m;
}

std::string get_utf8(NMR::PLib3MFBase* obj, bool material, DWORD index = 0) {
  ULONG needed = 0;
  if (material)
    NMR::lib3mf_basematerial_getnameutf8(obj, index, nullptr, 0, &needed);
  else
    NMR::lib3mf_object_getnameutf8(obj, nullptr, 0, &needed);
  std::string s(needed + 1, '\0');
  if (material)
    NMR::lib3mf_basematerial_getnameutf8(obj, index, s.data(), static_cast<ULONG>(s.size()), &needed);
  else
    NMR::lib3mf_object_getnameutf8(obj, s.data(), static_cast<ULONG>(s.size()), &needed);
  s.resize(needed);
  return s;
}

TEST(MultiMaterial3mf, Lib3mfReadsObjectsVolumesAndOpaqueMaterials) {
  const MultiMaterialModel model = layered_block({0, 5, 10, 15}, /*split_top=*/true);
  const fs::path dir = temp_dir("lib3mf");
  const fs::path file = dir / "block.3mf";
  ASSERT_TRUE(write_multi_material_3mf(file, model).ok());

  NMR::PLib3MFModel* m = nullptr;
  ASSERT_EQ(NMR::lib3mf_createmodel(&m), 0);
  NMR::PLib3MFModelReader* reader = nullptr;
  ASSERT_EQ(NMR::lib3mf_model_queryreader(m, "3mf", &reader), 0);
  ASSERT_EQ(NMR::lib3mf_reader_readfromfileutf8(reader, file.string().c_str()), 0);
  DWORD unit = 99;
  ASSERT_EQ(NMR::lib3mf_model_getunit(m, &unit), 0);
  EXPECT_EQ(unit, static_cast<DWORD>(NMR::MODELUNIT_MILLIMETER));
  // Materials: the names and opaque colours given (expected values: the model above).
  NMR::PLib3MFModelBaseMaterial* group = nullptr;
  ASSERT_EQ(NMR::lib3mf_model_getbasematerialbyid(m, 1, &group), 0);
  DWORD count = 0;
  ASSERT_EQ(NMR::lib3mf_basematerial_getcount(group, &count), 0);
  ASSERT_EQ(count, 3u);
  for (DWORD i = 0; i < count; ++i) {
    EXPECT_EQ(get_utf8(group, true, i), model.materials[i].name);
    BYTE r = 0, g = 0, b = 0, a = 0;
    ASSERT_EQ(NMR::lib3mf_basematerial_getdisplaycolor(group, i, &r, &g, &b, &a), 0);
    EXPECT_EQ(r, model.materials[i].rgb[0]);
    EXPECT_EQ(a, 255) << "material " << i << " must be opaque";
  }
  // The one object: 4 volumes x (8 vertices, 12 triangles), per-triangle materials in volume order.
  NMR::PLib3MFModelMeshObject* obj = nullptr;
  ASSERT_EQ(NMR::lib3mf_model_getmeshobjectbyid(m, 2, &obj), 0);
  EXPECT_EQ(get_utf8(obj, false), "composite");
  DWORD nv = 0, nt = 0;
  NMR::lib3mf_meshobject_getvertexcount(obj, &nv);
  NMR::lib3mf_meshobject_gettrianglecount(obj, &nt);
  EXPECT_EQ(nv, 32u);
  EXPECT_EQ(nt, 48u);
  NMR::PLib3MFPropertyHandler* props = nullptr;
  ASSERT_EQ(NMR::lib3mf_meshobject_createpropertyhandler(obj, &props), 0);
  for (DWORD t = 0; t < nt; ++t) {
    DWORD gid = 0, mi = 0;
    ASSERT_EQ(NMR::lib3mf_propertyhandler_getbasematerial(props, t, &gid, &mi), 0);
    EXPECT_EQ(gid, 1u);
    EXPECT_EQ(mi, static_cast<DWORD>(model.objects[0].volumes[t / 12].material)) << "triangle " << t;
  }
  // Millimetres: the block's far corner is (40, 50, 15) mm.
  float hi[3] = {0, 0, 0};
  for (DWORD v = 0; v < nv; ++v) {
    NMR::MODELMESHVERTEX p;
    NMR::lib3mf_meshobject_getvertex(obj, v, &p);
    for (int c = 0; c < 3; ++c) hi[c] = std::max(hi[c], p.m_fPosition[c]);
  }
  EXPECT_FLOAT_EQ(hi[0], 40.0f);
  EXPECT_FLOAT_EQ(hi[1], 50.0f);
  EXPECT_FLOAT_EQ(hi[2], 15.0f);
  NMR::lib3mf_release(props);
  NMR::lib3mf_release(obj);
  NMR::lib3mf_release(group);
  NMR::lib3mf_release(reader);
  NMR::lib3mf_release(m);
  fs::remove_all(dir);
}

TEST(MultiMaterial3mf, SlicerMetadataNamesVolumesAndExtruders) {
  const MultiMaterialModel model = layered_block({0, 5, 10}, false);
  const std::string prusa = slic3r_model_config(model);
  EXPECT_NE(prusa.find("<volume firstid=\"0\" lastid=\"11\">"), std::string::npos) << prusa;
  EXPECT_NE(prusa.find("<volume firstid=\"12\" lastid=\"23\">"), std::string::npos);
  EXPECT_NE(prusa.find("key=\"extruder\" value=\"2\""), std::string::npos);
  EXPECT_NE(prusa.find("key=\"volume_type\" value=\"ModelPart\""), std::string::npos);
  const std::string bambu = bambu_model_settings(model);
  EXPECT_NE(bambu.find("subtype=\"normal_part\" firstid=\"12\" lastid=\"23\""), std::string::npos)
      << bambu;
  EXPECT_NE(bambu.find("<metadata key=\"extruder\" value=\"2\"/>"), std::string::npos);
}

TEST(MultiMaterial3mf, BadInputWritesNothing) {
  const fs::path dir = temp_dir("bad");
  const fs::path file = dir / "bad.3mf";
  MultiMaterialModel m = layered_block({0, 5}, false);
  m.objects[0].volumes[0].material = 7;
  Status s = write_multi_material_3mf(file, m);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("uses material 7 of 3"), std::string::npos) << s.message();
  m = layered_block({0, 5}, false);
  m.materials.clear();
  EXPECT_EQ(write_multi_material_3mf(file, m).code(), StatusCode::kInvalidArgument);
  m = layered_block({0, 5}, false);
  m.objects[0].volumes[0].mesh.triangles(0, 0) = 99;
  EXPECT_EQ(write_multi_material_3mf(file, m).code(), StatusCode::kInvalidArgument);
  m = layered_block({0, 5}, false);
  m.objects[0].name = "a\x01";
  EXPECT_EQ(write_multi_material_3mf(file, m).code(), StatusCode::kInvalidArgument);
  EXPECT_TRUE(fs::is_empty(dir));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace hc::printfile

#include "prusa_slicer.h"

namespace hc::printfile {
namespace {

// PrusaSlicer slices every volume with its extruder: per-extruder filament within 1 % of the
// volumes' geometric volume (expected values: box volumes of the model above).
TEST(MultiMaterial3mf, PrusaSlicerUsesEachVolumesExtruder) {
  if (!hc::testing::prusa_slicer_available()) GTEST_SKIP() << "prusa-slicer is not installed";
  const MultiMaterialModel model = layered_block({0, 4, 8, 12}, /*split_top=*/true);
  const fs::path dir = temp_dir("prusa");
  const fs::path file = dir / "block.3mf";
  ASSERT_TRUE(write_multi_material_3mf(file, model).ok());
  std::string log;
  const auto used = hc::testing::prusa_slicer_filament_mm3(file, 3, dir, &log);
  ASSERT_TRUE(used.has_value()) << log;
  ASSERT_EQ(used->size(), 3u) << log;
  // Material 0: layer 0 (40 x 50 x 4 mm) + top left (20 x 50 x 4); 1: layer 1; 2: top right.
  const double expected[3] = {40 * 50 * 4 + 20 * 50 * 4, 40 * 50 * 4, 20 * 50 * 4};
  for (int i = 0; i < 3; ++i) {
    std::printf("extruder %d: %.1f mm3, geometry %.1f mm3 (%+.2f %%)\n", i + 1, (*used)[i],
                expected[i], 100 * ((*used)[i] / expected[i] - 1));
    EXPECT_NEAR((*used)[i], expected[i], 0.01 * expected[i]) << "extruder " << i + 1;
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace hc::printfile
