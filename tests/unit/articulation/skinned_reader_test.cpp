// The Assimp-based skinned-character reader: the shared glTF characters (facts from
// shared/data/MANIFEST.md), Debian assimp-testmodels' FBX and .x characters, round trips of a
// synthetic rig through every format Assimp writes, and malformed input.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "fabrication/articulation/skinned_io.h"
#include "synthetic_skinned.h"

namespace hc::articulation {
namespace {

namespace fs = std::filesystem;
const std::string kSkinned = std::string(HARDCOPY_SHARED_DATA) + "/skinned/";
// Debian's assimp-testmodels (scripts/setup installs it).
const std::string kAssimpModels = "/usr/share/assimp/models/";

double weight_sum(const SkinnedCharacter& c, Eigen::Index v) {
  double s = 0;
  for (auto k = c.influence_start[static_cast<std::size_t>(v)];
       k < c.influence_start[static_cast<std::size_t>(v) + 1]; ++k)
    s += c.influences[static_cast<std::size_t>(k)].weight;
  return s;
}

struct SharedFact {
  const char* file;
  std::size_t bones;
  Eigen::Index triangles;
  std::size_t clips;
};

TEST(SkinnedReader, ReadsEverySharedCharacterWithTheManifestFacts) {
  // Joint and triangle counts from shared/data/MANIFEST.md; clips: Fox has Survey/Walk/Run, the
  // others one each (glTF-Sample-Models' READMEs).
  const SharedFact facts[] = {{"RiggedSimple.glb", 2, 188, 1},
                              {"RiggedFigure.glb", 19, 256, 1},
                              {"CesiumMan.glb", 19, 4672, 1},
                              {"Fox.glb", 24, 576, 3},
                              {"simple_skin.gltf", 2, 8, 1}};
  for (const SharedFact& f : facts) {
    SCOPED_TRACE(f.file);
    SkinnedReadOptions options;
    options.target_height_m = 0.1;
    Result<SkinnedCharacter> c = read_skinned_character(kSkinned + f.file, options);
    ASSERT_TRUE(c.ok()) << c.status().to_string();
    EXPECT_EQ(c->bones.size(), f.bones);
    EXPECT_EQ(c->mesh.num_triangles(), f.triangles);
    EXPECT_EQ(c->clips.size(), f.clips);
    EXPECT_TRUE(validate(*c).ok());
    // Scaled to the target height, feet on the ground.
    EXPECT_NEAR(c->mesh.vertices.col(1).minCoeff(), 0.0, 1e-12);
    EXPECT_NEAR(c->mesh.vertices.col(1).maxCoeff(), 0.1, 1e-12);
    for (Eigen::Index v = 0; v < c->mesh.num_vertices(); ++v)
      ASSERT_NEAR(weight_sum(*c, v), 1.0, 1e-12);
    // The rest pose posed by the skin is the mesh itself.
    EXPECT_LT((c->pose(c->rest_bone_globals) - c->mesh.vertices).cwiseAbs().maxCoeff(), 1e-12);
  }
}

TEST(SkinnedReader, RenormalisesTheWeightsOfCesiumMan) {
  // MANIFEST: 210 vertices with weight sums < 0.99, the smallest 0.185.
  Result<SkinnedCharacter> c = read_skinned_character(kSkinned + "CesiumMan.glb");
  ASSERT_TRUE(c.ok()) << c.status().to_string();
  EXPECT_EQ(c->report.renormalised_vertices, 210);
  EXPECT_NEAR(c->report.min_weight_sum, 0.185, 5e-4);
  EXPECT_EQ(c->report.format, "glTF2");
  // Fox's clips by name.
  Result<SkinnedCharacter> fox = read_skinned_character(kSkinned + "Fox.glb");
  ASSERT_TRUE(fox.ok());
  ASSERT_EQ(fox->clips.size(), 3u);
  EXPECT_EQ(fox->clips[0].name, "Survey");
  EXPECT_EQ(fox->clips[1].name, "Walk");
  EXPECT_EQ(fox->clips[2].name, "Run");
}

TEST(SkinnedReader, ReadsFbxAndDirectXCharactersOfAssimpTestModels) {
  if (!fs::exists(kAssimpModels)) GTEST_SKIP() << "assimp-testmodels not installed";
  // Bone and triangle counts as Assimp 5.2.5 reports them (aiMesh::mNumBones, mNumFaces).
  struct Case {
    const char* file;
    std::size_t bones;
    Eigen::Index triangles;
    std::size_t clips;
  };
  for (const Case& k : {Case{"FBX/animation_with_skeleton.fbx", 14, 2112, 1},
                        Case{"FBX/huesitos.fbx", 9, 120, 1},
                        Case{"X/Testwuson.X", 37, 3732, 3},
                        Case{"X/BCN_Epileptic.X", 54, 5126, 1}}) {
    SCOPED_TRACE(k.file);
    Result<SkinnedCharacter> c = read_skinned_character(kAssimpModels + k.file);
    ASSERT_TRUE(c.ok()) << c.status().to_string();
    EXPECT_EQ(c->bones.size(), k.bones);
    EXPECT_EQ(c->mesh.num_triangles(), k.triangles);
    EXPECT_EQ(c->clips.size(), k.clips);
  }
  // animation_with_skeleton.fbx's weights sum to between 0.94 and 1.38 (the issue's 1.38).
  Result<SkinnedCharacter> fbx =
      read_skinned_character(kAssimpModels + "FBX/animation_with_skeleton.fbx");
  ASSERT_TRUE(fbx.ok());
  EXPECT_NEAR(fbx->report.max_weight_sum, 1.3765, 1e-3);
  // BCN_Epileptic: three meshes share one skeleton.
  Result<SkinnedCharacter> x = read_skinned_character(kAssimpModels + "X/BCN_Epileptic.X");
  ASSERT_TRUE(x.ok());
  EXPECT_EQ(x->report.meshes, 3);
}

// Vertex positions of `c` posed at clip frame f, rounded to a key for matching by position.
std::map<std::array<long, 3>, Eigen::Vector3d> by_position(const MatrixX3d& rest,
                                                           const MatrixX3d& posed) {
  std::map<std::array<long, 3>, Eigen::Vector3d> out;
  for (Eigen::Index v = 0; v < rest.rows(); ++v)
    out[{std::lround(rest(v, 0) * 1e5), std::lround(rest(v, 1) * 1e5),
         std::lround(rest(v, 2) * 1e5)}] = posed.row(v).transpose();
  return out;
}

TEST(SkinnedReader, RoundTripsASyntheticRigThroughEveryFormatAssimpWrites) {
  testing::SyntheticLimb limb;
  limb.bones = 3;
  limb.rings = 19;
  limb.segments = 12;
  SkinnedCharacter c = testing::skinned_limb(limb);
  c.clips.push_back(testing::rotation_clip(c, 1, Eigen::Vector3d::UnitZ(),
                                           Eigen::Vector3d(0, 0.03, 0), 0.3, 0.5, 11));
  const fs::path dir = fs::temp_directory_path() / "hc_skinned_roundtrip";
  fs::create_directories(dir);
  // DirectX is read (assimp-testmodels above) but Assimp cannot write skinned .x files.
  EXPECT_EQ(write_skinned_character(dir / "limb.x", c).code(), StatusCode::kUnsupported);
  for (const char* ext : {"glb", "gltf", "fbx", "dae"}) {
    SCOPED_TRACE(ext);
    const fs::path path = dir / (std::string("limb.") + ext);
    ASSERT_TRUE(write_skinned_character(path, c).ok());
    Result<SkinnedCharacter> back = read_skinned_character(path);
    ASSERT_TRUE(back.ok()) << back.status().to_string();
    EXPECT_EQ(back->bones.size(), c.bones.size());
    EXPECT_EQ(back->mesh.num_triangles(), c.mesh.num_triangles());
    // Same rest pose (file units: the writer wrote metres and the reader keeps units).
    const auto expected = by_position(c.mesh.vertices, c.mesh.vertices);
    const auto got = by_position(back->mesh.vertices - back->shift.transpose().replicate(
                                                           back->mesh.num_vertices(), 1),
                                 back->mesh.vertices);
    EXPECT_EQ(got.size(), expected.size());
    ASSERT_EQ(back->clips.size(), 1u);
    // The middle frame posed by the read skin equals the synthetic pose (float precision).
    const std::size_t f = 5;
    const std::size_t g = back->clips[0].times_s.size() / 2;
    ASSERT_NEAR(back->clips[0].times_s[g], c.clips[0].times_s[f], 1e-4);
    const auto want = by_position(c.mesh.vertices, c.pose(c.clips[0].bone_globals[f]));
    const MatrixX3d unshifted =
        back->mesh.vertices - back->shift.transpose().replicate(back->mesh.num_vertices(), 1);
    const MatrixX3d posed = back->pose(back->clips[0].bone_globals[g]) -
                            back->shift.transpose().replicate(back->mesh.num_vertices(), 1);
    const auto have = by_position(unshifted, posed);
    double worst = 0;
    for (const auto& [key, p] : want) {
      auto it = have.find(key);
      ASSERT_NE(it, have.end());
      worst = std::max(worst, (it->second - p).norm());
    }
    EXPECT_LT(worst, 1e-5);  // float storage of 0.1 m coordinates
  }
  fs::remove_all(dir);
}

// ---- Malformed input ----

std::string base64(const std::string& bytes) {
  static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  std::size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const unsigned n = (unsigned(static_cast<unsigned char>(bytes[i])) << 16) |
                       (unsigned(static_cast<unsigned char>(bytes[i + 1])) << 8) |
                       unsigned(static_cast<unsigned char>(bytes[i + 2]));
    for (int s = 18; s >= 0; s -= 6) out += k[(n >> s) & 63];
  }
  if (i < bytes.size()) {
    unsigned n = unsigned(static_cast<unsigned char>(bytes[i])) << 16;
    if (i + 1 < bytes.size()) n |= unsigned(static_cast<unsigned char>(bytes[i + 1])) << 8;
    out += k[(n >> 18) & 63];
    out += k[(n >> 12) & 63];
    out += i + 1 < bytes.size() ? k[(n >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

template <typename T>
void append(std::string* buf, const std::vector<T>& values) {
  buf->append(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
}

// A tetrahedron skinned to two joints, written as a self-contained .gltf. `weights` are the four
// vertices' (joint 0, joint 1) weights; `cycle` makes joint 1 its own ancestor; `skin` false drops
// the skin.
std::string tetra_gltf(const std::vector<float>& weights, bool cycle = false, bool skin = true) {
  std::string buf;
  append(&buf, std::vector<float>{0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1});  // 48 bytes
  append(&buf, std::vector<std::uint16_t>{0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3});  // 24
  std::vector<std::uint16_t> joints;
  std::vector<float> w4;
  for (int v = 0; v < 4; ++v) {
    joints.insert(joints.end(), {0, 1, 0, 0});
    w4.insert(w4.end(), {weights[2 * v], weights[2 * v + 1], 0, 0});
  }
  append(&buf, joints);  // 32
  append(&buf, w4);      // 64
  std::vector<float> ibm;
  for (int j = 0; j < 2; ++j)
    ibm.insert(ibm.end(), {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, j ? -0.5f : 0.f, 0, 1});
  append(&buf, ibm);  // 128
  using nlohmann::json;
  json attributes = {{"POSITION", 0}};
  if (skin) attributes.update({{"JOINTS_0", 2}, {"WEIGHTS_0", 3}});
  json mesh_node = {{"mesh", 0}};
  if (skin) mesh_node["skin"] = 0;
  json j1 = {{"name", "j1"}, {"translation", {0, 0.5, 0}}};
  if (cycle) j1["children"] = {1};
  json g = {
      {"asset", {{"version", "2.0"}}},
      {"scene", 0},
      {"scenes", {{{"nodes", {0, 1}}}}},
      {"nodes", {mesh_node, {{"name", "j0"}, {"children", {2}}}, j1}},
      {"meshes", {{{"primitives", {{{"attributes", attributes}, {"indices", 1}}}}}}},
      {"buffers",
       {{{"byteLength", buf.size()},
         {"uri", "data:application/octet-stream;base64," + base64(buf)}}}},
      {"bufferViews",
       {{{"buffer", 0}, {"byteOffset", 0}, {"byteLength", 48}},
        {{"buffer", 0}, {"byteOffset", 48}, {"byteLength", 24}},
        {{"buffer", 0}, {"byteOffset", 72}, {"byteLength", 32}},
        {{"buffer", 0}, {"byteOffset", 104}, {"byteLength", 64}},
        {{"buffer", 0}, {"byteOffset", 168}, {"byteLength", 128}}}},
      {"accessors",
       {{{"bufferView", 0},
         {"componentType", 5126},
         {"count", 4},
         {"type", "VEC3"},
         {"min", {0, 0, 0}},
         {"max", {1, 1, 1}}},
        {{"bufferView", 1}, {"componentType", 5123}, {"count", 12}, {"type", "SCALAR"}},
        {{"bufferView", 2}, {"componentType", 5123}, {"count", 4}, {"type", "VEC4"}},
        {{"bufferView", 3}, {"componentType", 5126}, {"count", 4}, {"type", "VEC4"}},
        {{"bufferView", 4}, {"componentType", 5126}, {"count", 2}, {"type", "MAT4"}}}}};
  if (skin) g["skins"] = {{{"joints", {1, 2}}, {"inverseBindMatrices", 4}}};
  return g.dump();
}

Result<SkinnedCharacter> parse_gltf(const std::string& text) {
  return parse_skinned_character(text, "gltf", "tetra.gltf");
}

TEST(SkinnedReader, ReadsAHandMadeGltfAndRenormalisesItsWeights) {
  // Sums 0.5, 1, 2 and 0.25 -> each vertex renormalised to 1; three of four differ from 1.
  Result<SkinnedCharacter> c = parse_gltf(tetra_gltf({0.5f, 0, 0.5f, 0.5f, 1, 1, 0, 0.25f}));
  ASSERT_TRUE(c.ok()) << c.status().to_string();
  EXPECT_EQ(c->mesh.num_triangles(), 4);
  EXPECT_EQ(c->report.renormalised_vertices, 3);
  EXPECT_NEAR(c->report.min_weight_sum, 0.25, 1e-7);
  EXPECT_NEAR(c->report.max_weight_sum, 2.0, 1e-7);
  ASSERT_EQ(c->bones.size(), 2u);
  EXPECT_EQ(c->bones[1].parent, 0);
}

// A DirectX file written by hand: a tetrahedron skinned to frames Root and J1 (weights 1.0/0.7
// and 0.3/1.0/1.0: vertex 1 sums to 1.0, vertices 0, 2, 3 have one bone each).
constexpr const char* kTetraX = R"(xof 0303txt 0032
Frame Root {
 FrameTransformMatrix { 1.0,0.0,0.0,0.0,0.0,1.0,0.0,0.0,0.0,0.0,1.0,0.0,0.0,0.0,0.0,1.0;; }
 Frame J1 {
  FrameTransformMatrix { 1.0,0.0,0.0,0.0,0.0,1.0,0.0,0.0,0.0,0.0,1.0,0.0,0.0,0.5,0.0,1.0;; }
 }
 Mesh Tetra {
  4;
  0.0;0.0;0.0;,
  1.0;0.0;0.0;,
  0.0;1.0;0.0;,
  0.0;0.0;1.0;;
  4;
  3;0,1,2;,
  3;0,1,3;,
  3;0,3,2;,
  3;1,2,3;;
  XSkinMeshHeader { 2; 2; 2; }
  SkinWeights {
   "Root";
   2;
   0,1;
   1.0,0.7;
   1.0,0.0,0.0,0.0,0.0,1.0,0.0,0.0,0.0,0.0,1.0,0.0,0.0,0.0,0.0,1.0;;
  }
  SkinWeights {
   "J1";
   3;
   1,2,3;
   0.3,1.0,1.0;
   1.0,0.0,0.0,0.0,0.0,1.0,0.0,0.0,0.0,0.0,1.0,0.0,0.0,-0.5,0.0,1.0;;
  }
 }
}
)";

TEST(SkinnedReader, ReadsAHandWrittenDirectXFile) {
  Result<SkinnedCharacter> c = parse_skinned_character(kTetraX, "x", "tetra.x");
  ASSERT_TRUE(c.ok()) << c.status().to_string();
  EXPECT_EQ(c->mesh.num_triangles(), 4);
  ASSERT_EQ(c->bones.size(), 2u);
  EXPECT_EQ(c->bones[0].name, "Root");
  EXPECT_EQ(c->bones[1].parent, 0);
  EXPECT_EQ(c->report.renormalised_vertices, 0);
  EXPECT_EQ(c->report.format, "DirectX");
}

TEST(SkinnedReader, RejectsMalformedInputWithAClearMessage) {
  struct Bad {
    std::string what;
    Result<SkinnedCharacter> result;
    std::string expected;
  };
  std::vector<Bad> cases;
  cases.push_back({"weights all zero", parse_gltf(tetra_gltf({0, 0, 0, 0, 0, 0, 0, 0})), "zero"});
  cases.push_back({"no skin", parse_gltf(tetra_gltf({1, 0, 1, 0, 0, 1, 0, 1}, false, false)),
                   "no skin"});
  cases.push_back({"bone cycle", parse_gltf(tetra_gltf({1, 0, 1, 0, 0, 1, 0, 1}, true)),
                   "recursive"});
  cases.push_back({"empty", parse_skinned_character("", "glb", "empty.glb"), "empty"});
  cases.push_back({"garbage glb", parse_skinned_character("glTF\x02garbage", "glb", "bad.glb"),
                   "bad.glb"});
  cases.push_back({"not json", parse_gltf("{\"asset\": "), "tetra.gltf"});
  cases.push_back({"unknown format", parse_skinned_character("x", "obj", "a.obj"), "'.obj'"});
  for (Bad& b : cases) {
    SCOPED_TRACE(b.what);
    ASSERT_FALSE(b.result.ok());
    EXPECT_EQ(b.result.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(b.result.status().message().find(b.expected), std::string::npos)
        << b.result.status().message();
  }
  Result<SkinnedCharacter> missing = read_skinned_character("/nonexistent/character.glb");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), StatusCode::kNotFound);
  // A truncated copy of a real file.
  std::ifstream in(kSkinned + "RiggedSimple.glb", std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), {});
  for (std::size_t cut : {std::size_t{12}, std::size_t{100}, bytes.size() / 2}) {
    Result<SkinnedCharacter> t = parse_skinned_character(bytes.substr(0, cut), "glb", "cut.glb");
    ASSERT_FALSE(t.ok()) << cut;
    EXPECT_EQ(t.status().code(), StatusCode::kInvalidArgument);
  }
}

}  // namespace
}  // namespace hc::articulation
