// The Assimp decoder behind skinned_reader.h: the only translation unit that includes Assimp.
#include "fabrication/articulation/skinned_io.h"

#include <assimp/anim.h>
#include <assimp/config.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <fmt/format.h>
#include <assimp/Exporter.hpp>
#include <assimp/Importer.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iterator>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace hc::articulation {
namespace {

// Limits on what a file may declare, so a hostile header cannot make us allocate without bound.
constexpr std::size_t kMaxNodes = 1 << 20;
constexpr int kMaxNodeDepth = 4096;
constexpr std::size_t kMaxVertices = std::size_t{1} << 26;
// Assimp's own fallback when a file gives no tick rate (aiAnimation::mTicksPerSecond == 0).
constexpr double kDefaultTicksPerSecond = 25.0;
// A weight sum this far from 1 counts as renormalised in the report.
constexpr double kWeightSumTolerance = 1e-3;

Eigen::Affine3d to_eigen(const aiMatrix4x4& m) {
  Eigen::Matrix4d e;
  e << m.a1, m.a2, m.a3, m.a4, m.b1, m.b2, m.b3, m.b4, m.c1, m.c2, m.c3, m.c4, m.d1, m.d2, m.d3,
      m.d4;
  return Eigen::Affine3d(e);
}

bool finite(const aiMatrix4x4& m) {
  const float* p = &m.a1;
  return std::all_of(p, p + 16, [](float v) { return std::isfinite(v); });
}

struct Node {
  const aiNode* node = nullptr;
  int parent = -1;
  int depth = 0;
  int bone = -1;  // index into the bone list when the node is a skin joint
  Eigen::Affine3d local = Eigen::Affine3d::Identity();
};

// The node tree flattened parents first (depth-first), with its limits checked.
Result<std::vector<Node>> flatten_nodes(const aiNode* root, const std::string& name) {
  std::vector<Node> nodes;
  std::vector<std::pair<const aiNode*, int>> stack{{root, -1}};
  while (!stack.empty()) {
    auto [n, parent] = stack.back();
    stack.pop_back();
    if (n == nullptr) return invalid_argument(fmt::format("{}: null node in the scene", name));
    if (nodes.size() >= kMaxNodes)
      return invalid_argument(fmt::format("{}: more than {} nodes", name, kMaxNodes));
    Node node;
    node.node = n;
    node.parent = parent;
    node.depth = parent < 0 ? 0 : nodes[static_cast<std::size_t>(parent)].depth + 1;
    if (node.depth > kMaxNodeDepth)
      return invalid_argument(
          fmt::format("{}: node tree deeper than {} (a cycle?)", name, kMaxNodeDepth));
    if (!finite(n->mTransformation))
      return invalid_argument(
          fmt::format("{}: node '{}': transformation is not finite", name, n->mName.C_Str()));
    node.local = to_eigen(n->mTransformation);
    const int index = static_cast<int>(nodes.size());
    nodes.push_back(node);
    if (n->mNumChildren > 0 && n->mChildren == nullptr)
      return invalid_argument(
          fmt::format("{}: node '{}' lists children it does not hold", name, n->mName.C_Str()));
    for (unsigned c = n->mNumChildren; c-- > 0;) stack.emplace_back(n->mChildren[c], index);
  }
  return nodes;
}

std::vector<Eigen::Affine3d> globals_of(const std::vector<Node>& nodes,
                                        const std::vector<Eigen::Affine3d>& locals) {
  std::vector<Eigen::Affine3d> g(nodes.size());
  for (std::size_t i = 0; i < nodes.size(); ++i)
    g[i] =
        nodes[i].parent < 0 ? locals[i] : g[static_cast<std::size_t>(nodes[i].parent)] * locals[i];
  return g;
}

// Index of the key segment holding `t` (keys sorted by time): the last key with time <= t.
template <typename Key>
std::size_t key_before(const Key* keys, unsigned count, double t) {
  const Key* end = keys + count;
  const Key* it =
      std::upper_bound(keys, end, t, [](double v, const Key& k) { return v < k.mTime; });
  return it == keys ? 0 : static_cast<std::size_t>(it - keys - 1);
}

aiVector3D lerp_keys(const aiVectorKey* keys, unsigned count, double t) {
  const std::size_t i = key_before(keys, count, t);
  if (i + 1 >= count || keys[i + 1].mTime <= keys[i].mTime || t <= keys[i].mTime)
    return keys[i].mValue;
  const double a = (t - keys[i].mTime) / (keys[i + 1].mTime - keys[i].mTime);
  return keys[i].mValue + static_cast<float>(a) * (keys[i + 1].mValue - keys[i].mValue);
}

aiQuaternion slerp_keys(const aiQuatKey* keys, unsigned count, double t) {
  const std::size_t i = key_before(keys, count, t);
  if (i + 1 >= count || keys[i + 1].mTime <= keys[i].mTime || t <= keys[i].mTime)
    return keys[i].mValue;
  const double a = (t - keys[i].mTime) / (keys[i + 1].mTime - keys[i].mTime);
  aiQuaternion q;
  aiQuaternion::Interpolate(q, keys[i].mValue, keys[i + 1].mValue, static_cast<float>(a));
  return q.Normalize();
}

Eigen::Affine3d channel_transform(const aiNodeAnim& ch, double t) {
  const aiVector3D p = lerp_keys(ch.mPositionKeys, ch.mNumPositionKeys, t);
  const aiQuaternion q = slerp_keys(ch.mRotationKeys, ch.mNumRotationKeys, t);
  const aiVector3D s = lerp_keys(ch.mScalingKeys, ch.mNumScalingKeys, t);
  Eigen::Affine3d m = Eigen::Affine3d::Identity();
  m.translate(Eigen::Vector3d(p.x, p.y, p.z));
  m.rotate(Eigen::Quaterniond(q.w, q.x, q.y, q.z).normalized());
  m.scale(Eigen::Vector3d(s.x, s.y, s.z));
  return m;
}

template <typename Key>
bool keys_valid(const Key* keys, unsigned count) {
  if (count == 0 || keys == nullptr) return false;
  for (unsigned k = 0; k < count; ++k) {
    if (!std::isfinite(keys[k].mTime)) return false;
    if (k > 0 && keys[k].mTime < keys[k - 1].mTime) return false;
  }
  return true;
}

bool values_finite(const aiNodeAnim& ch) {
  for (unsigned k = 0; k < ch.mNumPositionKeys; ++k) {
    const aiVector3D& v = ch.mPositionKeys[k].mValue;
    if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z)) return false;
  }
  for (unsigned k = 0; k < ch.mNumScalingKeys; ++k) {
    const aiVector3D& v = ch.mScalingKeys[k].mValue;
    if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z)) return false;
  }
  for (unsigned k = 0; k < ch.mNumRotationKeys; ++k) {
    const aiQuaternion& q = ch.mRotationKeys[k].mValue;
    const double n2 = double(q.w) * q.w + double(q.x) * q.x + double(q.y) * q.y + double(q.z) * q.z;
    if (!std::isfinite(n2) || n2 < 1e-12) return false;
  }
  return true;
}

class SceneDecoder {
 public:
  SceneDecoder(const aiScene& scene, std::string name, const SkinnedReadOptions& options)
      : scene_(scene), name_(std::move(name)), options_(options) {}

  Result<SkinnedCharacter> decode();

 private:
  Status collect_bones();
  Status read_meshes(const std::vector<Eigen::Affine3d>& rest_globals);
  Status read_mesh(unsigned mesh_index, int node, const std::vector<Eigen::Affine3d>& rest_globals);
  void give_unweighted_vertices_a_neighbour(const std::vector<Eigen::Affine3d>& rest_globals);
  Status read_clips();
  int ancestor_bone(int node) const;
  Status fail(const std::string& what) const {
    return invalid_argument(fmt::format("{}: {}", name_, what));
  }

  const aiScene& scene_;
  std::string name_;
  const SkinnedReadOptions& options_;
  std::vector<Node> nodes_;
  std::map<std::string, int> node_by_name_;
  std::vector<int> bone_nodes_;  // node index of each bone, parents first
  // Per vertex: rest position (file units) and its raw influences.
  std::vector<Eigen::Vector3d> rest_;
  std::vector<std::vector<Influence>> raw_;
  std::vector<int> vertex_mesh_;
  std::vector<Eigen::Vector3i> triangles_;
  std::vector<int> meshes_of_bone_;  // how many meshes each bone influences
  SkinnedCharacter out_;
};

int SceneDecoder::ancestor_bone(int node) const {
  for (int n = nodes_[static_cast<std::size_t>(node)].parent; n >= 0;
       n = nodes_[static_cast<std::size_t>(n)].parent)
    if (nodes_[static_cast<std::size_t>(n)].bone >= 0)
      return nodes_[static_cast<std::size_t>(n)].bone;
  return -1;
}

Status SceneDecoder::collect_bones() {
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    const std::string node_name = nodes_[i].node->mName.C_Str();
    node_by_name_.emplace(node_name, static_cast<int>(i));  // first node of a name wins
    if (node_name.find("$AssimpFbx$") != std::string::npos) ++out_.report.pivot_nodes;
  }
  std::vector<char> is_bone(nodes_.size(), 0);
  for (unsigned m = 0; m < scene_.mNumMeshes; ++m) {
    const aiMesh* mesh = scene_.mMeshes[m];
    if (mesh == nullptr) return fail(fmt::format("mesh {} is missing", m));
    if (mesh->mNumBones > 0 && mesh->mBones == nullptr)
      return fail(fmt::format("mesh {} lists bones it does not hold", m));
    for (unsigned b = 0; b < mesh->mNumBones; ++b) {
      const aiBone* bone = mesh->mBones[b];
      if (bone == nullptr) return fail(fmt::format("mesh {}: bone {} is missing", m, b));
      auto it = node_by_name_.find(bone->mName.C_Str());
      if (it == node_by_name_.end())
        return fail(
            fmt::format("mesh {}: bone '{}' names no node of the scene", m, bone->mName.C_Str()));
      is_bone[static_cast<std::size_t>(it->second)] = 1;
    }
  }
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    if (!is_bone[i]) continue;
    nodes_[i].bone = static_cast<int>(bone_nodes_.size());
    bone_nodes_.push_back(static_cast<int>(i));
  }
  if (bone_nodes_.empty())
    return fail("no skin: no mesh has bones (a skinned character needs skinning weights)");
  for (std::size_t b = 0; b < bone_nodes_.size(); ++b) {
    const Node& n = nodes_[static_cast<std::size_t>(bone_nodes_[b])];
    Bone bone;
    bone.name = n.node->mName.C_Str();
    bone.parent = ancestor_bone(bone_nodes_[b]);  // parents come first in depth-first order
    bone.depth = n.depth;
    out_.bones.push_back(bone);
  }
  meshes_of_bone_.assign(bone_nodes_.size(), 0);
  return {};
}

Status SceneDecoder::read_mesh(unsigned mesh_index, int node,
                               const std::vector<Eigen::Affine3d>& rest_globals) {
  const aiMesh& mesh = *scene_.mMeshes[mesh_index];
  if (!(mesh.mPrimitiveTypes & aiPrimitiveType_TRIANGLE) || mesh.mNumFaces == 0) return {};
  if (mesh.mVertices == nullptr || mesh.mFaces == nullptr)
    return fail(fmt::format("mesh {} has no vertex or face array", mesh_index));
  if (rest_.size() + mesh.mNumVertices > kMaxVertices)
    return fail(fmt::format("more than {} vertices", kMaxVertices));
  const std::size_t base = rest_.size();
  const int mesh_id = static_cast<int>(out_.report.meshes++);
  const Eigen::Affine3d& g_mesh = rest_globals[static_cast<std::size_t>(node)];
  for (unsigned v = 0; v < mesh.mNumVertices; ++v) {
    const aiVector3D& p = mesh.mVertices[v];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      return fail(fmt::format("mesh {}: vertex {} is not finite", mesh_index, v));
    rest_.push_back(g_mesh * Eigen::Vector3d(p.x, p.y, p.z));
    raw_.emplace_back();
    vertex_mesh_.push_back(mesh_id);
  }
  for (unsigned f = 0; f < mesh.mNumFaces; ++f) {
    const aiFace& face = mesh.mFaces[f];
    if (face.mNumIndices != 3) continue;  // points and lines of a mixed mesh
    Eigen::Vector3i t;
    for (int k = 0; k < 3; ++k) {
      if (face.mIndices[k] >= mesh.mNumVertices)
        return fail(fmt::format("mesh {}: face {} indexes vertex {} of {}", mesh_index, f,
                                face.mIndices[k], mesh.mNumVertices));
      t[k] = static_cast<int>(base + face.mIndices[k]);
    }
    triangles_.push_back(t);
  }
  if (mesh.mNumBones == 0) {
    // A rigid prop under a bone (a helmet on the head): weight 1 to that bone.
    const int bone = ancestor_bone(node);
    if (bone < 0) return {};
    const Eigen::Affine3d to_bone =
        rest_globals[static_cast<std::size_t>(bone_nodes_[static_cast<std::size_t>(bone)])]
            .inverse();
    for (std::size_t v = base; v < rest_.size(); ++v)
      raw_[v].push_back({bone, 1.0, to_bone * rest_[v]});
    ++meshes_of_bone_[static_cast<std::size_t>(bone)];
    return {};
  }
  for (unsigned b = 0; b < mesh.mNumBones; ++b) {
    const aiBone& ai_bone = *mesh.mBones[b];
    const int bone = nodes_[static_cast<std::size_t>(node_by_name_.at(ai_bone.mName.C_Str()))].bone;
    if (!finite(ai_bone.mOffsetMatrix))
      return fail(fmt::format("mesh {}: bone '{}': offset matrix is not finite", mesh_index,
                              ai_bone.mName.C_Str()));
    if (ai_bone.mNumWeights > 0 && ai_bone.mWeights == nullptr)
      return fail(fmt::format("mesh {}: bone '{}' lists weights it does not hold", mesh_index,
                              ai_bone.mName.C_Str()));
    const Eigen::Affine3d offset = to_eigen(ai_bone.mOffsetMatrix);
    ++meshes_of_bone_[static_cast<std::size_t>(bone)];
    for (unsigned w = 0; w < ai_bone.mNumWeights; ++w) {
      const aiVertexWeight& vw = ai_bone.mWeights[w];
      if (vw.mVertexId >= mesh.mNumVertices)
        return fail(fmt::format("mesh {}: bone '{}': weight {} names vertex {} of {}", mesh_index,
                                ai_bone.mName.C_Str(), w, vw.mVertexId, mesh.mNumVertices));
      if (!std::isfinite(vw.mWeight) || vw.mWeight < 0)
        return fail(
            fmt::format("mesh {}: bone '{}': weight {} is {} (expected a finite number "
                        ">= 0)",
                        mesh_index, ai_bone.mName.C_Str(), w, vw.mWeight));
      if (vw.mWeight == 0) continue;
      const aiVector3D& p = mesh.mVertices[vw.mVertexId];
      raw_[base + vw.mVertexId].push_back(
          {bone, static_cast<double>(vw.mWeight), offset * Eigen::Vector3d(p.x, p.y, p.z)});
    }
  }
  return {};
}

Status SceneDecoder::read_meshes(const std::vector<Eigen::Affine3d>& rest_globals) {
  for (std::size_t n = 0; n < nodes_.size(); ++n) {
    const aiNode& node = *nodes_[n].node;
    if (node.mNumMeshes > 0 && node.mMeshes == nullptr)
      return fail(fmt::format("node '{}' lists meshes it does not hold", node.mName.C_Str()));
    for (unsigned k = 0; k < node.mNumMeshes; ++k) {
      if (node.mMeshes[k] >= scene_.mNumMeshes)
        return fail(fmt::format("node '{}' names mesh {} of {}", node.mName.C_Str(),
                                node.mMeshes[k], scene_.mNumMeshes));
      HC_RETURN_IF_ERROR(read_mesh(node.mMeshes[k], static_cast<int>(n), rest_globals));
    }
  }
  if (triangles_.empty()) return fail("no triangles in any mesh");
  // Renormalise, and pose the weighted vertices by their skin (what a player shows at rest).
  bool any_weight = false;
  out_.report.min_weight_sum = std::numeric_limits<double>::infinity();
  out_.report.max_weight_sum = 0.0;
  for (std::size_t v = 0; v < raw_.size(); ++v) {
    double sum = 0.0;
    for (const Influence& inf : raw_[v]) sum += inf.weight;
    if (sum <= 0.0) continue;
    any_weight = true;
    out_.report.min_weight_sum = std::min(out_.report.min_weight_sum, sum);
    out_.report.max_weight_sum = std::max(out_.report.max_weight_sum, sum);
    if (std::abs(sum - 1.0) > kWeightSumTolerance) ++out_.report.renormalised_vertices;
    Eigen::Vector3d p = Eigen::Vector3d::Zero();
    for (Influence& inf : raw_[v]) {
      inf.weight /= sum;
      p +=
          inf.weight *
          (rest_globals[static_cast<std::size_t>(bone_nodes_[static_cast<std::size_t>(inf.bone)])] *
           inf.local);
    }
    rest_[v] = p;
  }
  if (!any_weight) return fail("every skinning weight is zero");
  give_unweighted_vertices_a_neighbour(rest_globals);
  for (int count : meshes_of_bone_)
    if (count > 1) ++out_.report.bones_shared_by_meshes;
  return {};
}

// Vertices no bone weights (a mesh with no skin beside skinned ones) follow the bone that
// dominates their nearest weighted vertex, rigidly. Brute force: such vertices are rare.
void SceneDecoder::give_unweighted_vertices_a_neighbour(
    const std::vector<Eigen::Affine3d>& rest_globals) {
  std::vector<std::size_t> weighted;
  for (std::size_t v = 0; v < raw_.size(); ++v)
    if (!raw_[v].empty()) weighted.push_back(v);
  for (std::size_t v = 0; v < raw_.size(); ++v) {
    if (!raw_[v].empty()) continue;
    ++out_.report.unweighted_vertices;
    std::size_t best = weighted.front();
    double best_d = std::numeric_limits<double>::infinity();
    for (std::size_t w : weighted) {
      const double d = (rest_[w] - rest_[v]).squaredNorm();
      if (d < best_d) best_d = d, best = w;
    }
    const Influence& top = *std::max_element(
        raw_[best].begin(), raw_[best].end(),
        [](const Influence& a, const Influence& b) { return a.weight < b.weight; });
    const Eigen::Affine3d& g =
        rest_globals[static_cast<std::size_t>(bone_nodes_[static_cast<std::size_t>(top.bone)])];
    raw_[v].push_back({top.bone, 1.0, g.inverse() * rest_[v]});
  }
  if (out_.report.unweighted_vertices > 0)
    out_.report.warnings.push_back(fmt::format(
        "{} vertices had no skinning weight: they follow their nearest weighted vertex's bone",
        out_.report.unweighted_vertices));
}

Status SceneDecoder::read_clips() {
  if (!options_.read_animations || scene_.mNumAnimations == 0) return {};
  if (scene_.mAnimations == nullptr) return fail("animations listed but not held");
  std::vector<Eigen::Affine3d> default_locals(nodes_.size());
  for (std::size_t i = 0; i < nodes_.size(); ++i) default_locals[i] = nodes_[i].local;
  for (unsigned a = 0; a < scene_.mNumAnimations; ++a) {
    const aiAnimation* anim = scene_.mAnimations[a];
    if (anim == nullptr) return fail(fmt::format("animation {} is missing", a));
    const double tps = anim->mTicksPerSecond > 0 ? anim->mTicksPerSecond : kDefaultTicksPerSecond;
    if (!std::isfinite(anim->mDuration) || anim->mDuration < 0 || !std::isfinite(tps))
      return fail(fmt::format("animation {}: duration {} ticks at {} ticks/s is not valid", a,
                              anim->mDuration, tps));
    std::vector<std::pair<int, const aiNodeAnim*>> channels;
    for (unsigned c = 0; c < anim->mNumChannels; ++c) {
      const aiNodeAnim* ch = anim->mChannels ? anim->mChannels[c] : nullptr;
      if (ch == nullptr) return fail(fmt::format("animation {}: channel {} is missing", a, c));
      if (!keys_valid(ch->mPositionKeys, ch->mNumPositionKeys) ||
          !keys_valid(ch->mRotationKeys, ch->mNumRotationKeys) ||
          !keys_valid(ch->mScalingKeys, ch->mNumScalingKeys) || !values_finite(*ch))
        return fail(
            fmt::format("animation {}: channel '{}' has missing, unsorted or non-finite "
                        "keys",
                        a, ch->mNodeName.C_Str()));
      auto it = node_by_name_.find(ch->mNodeName.C_Str());
      if (it == node_by_name_.end()) {
        out_.report.warnings.push_back(
            fmt::format("animation {}: channel '{}' names no node", a, ch->mNodeName.C_Str()));
        continue;
      }
      channels.emplace_back(it->second, ch);
    }
    if (channels.empty()) continue;
    Clip clip;
    clip.name = anim->mName.length > 0 ? anim->mName.C_Str() : fmt::format("clip{}", a);
    const double duration_s = anim->mDuration / tps;
    const int frames =
        std::clamp(static_cast<int>(std::ceil(duration_s * options_.sample_rate_hz)) + 1, 2,
                   options_.max_frames_per_clip);
    std::vector<Eigen::Affine3d> locals = default_locals;
    for (int f = 0; f < frames; ++f) {
      const double t_s = duration_s * f / (frames - 1);
      for (auto [node, ch] : channels)
        locals[static_cast<std::size_t>(node)] = channel_transform(*ch, t_s * tps);
      const std::vector<Eigen::Affine3d> g = globals_of(nodes_, locals);
      std::vector<Eigen::Affine3d> bones(bone_nodes_.size());
      for (std::size_t b = 0; b < bones.size(); ++b)
        bones[b] = g[static_cast<std::size_t>(bone_nodes_[b])];
      clip.times_s.push_back(t_s);
      clip.bone_globals.push_back(std::move(bones));
    }
    out_.clips.push_back(std::move(clip));
  }
  return {};
}

Result<SkinnedCharacter> SceneDecoder::decode() {
  if (scene_.mRootNode == nullptr) return fail("the scene has no node tree");
  HC_ASSIGN_OR_RETURN(nodes_, flatten_nodes(scene_.mRootNode, name_));
  if (scene_.mNumMeshes == 0 || scene_.mMeshes == nullptr) return fail("no mesh in the file");
  HC_RETURN_IF_ERROR(collect_bones());
  std::vector<Eigen::Affine3d> locals(nodes_.size());
  for (std::size_t i = 0; i < nodes_.size(); ++i) locals[i] = nodes_[i].local;
  const std::vector<Eigen::Affine3d> rest_globals = globals_of(nodes_, locals);
  HC_RETURN_IF_ERROR(read_meshes(rest_globals));
  HC_RETURN_IF_ERROR(read_clips());

  // Model frame: metres, +Y up, feet on y = 0, centred in x and z.
  Eigen::AlignedBox3d box;
  for (const Eigen::Vector3d& p : rest_) box.extend(p);
  const double height = box.sizes().y();
  if (!(height > 0) || !std::isfinite(height))
    return fail(fmt::format("the rest pose has no height along +Y ({})", height));
  out_.report.file_height = height;
  out_.scale = options_.target_height_m > 0 ? options_.target_height_m / height : 1.0;
  out_.report.scale = out_.scale;
  const Eigen::Vector3d anchor(box.center().x(), box.min().y(), box.center().z());
  out_.shift = -out_.scale * anchor;

  out_.source = name_;
  out_.mesh.vertices.resize(static_cast<Eigen::Index>(rest_.size()), 3);
  for (std::size_t v = 0; v < rest_.size(); ++v)
    out_.mesh.vertices.row(static_cast<Eigen::Index>(v)) = out_.scale * rest_[v] + out_.shift;
  out_.mesh.triangles.resize(static_cast<Eigen::Index>(triangles_.size()), 3);
  for (std::size_t t = 0; t < triangles_.size(); ++t)
    out_.mesh.triangles.row(static_cast<Eigen::Index>(t)) = triangles_[t].transpose();
  out_.vertex_mesh = std::move(vertex_mesh_);
  out_.influence_start.assign(1, 0);
  for (std::vector<Influence>& infl : raw_) {
    for (Influence& i : infl) out_.influences.push_back(i);
    out_.influence_start.push_back(static_cast<std::int64_t>(out_.influences.size()));
  }
  out_.report.input_vertices = static_cast<std::int64_t>(rest_.size());
  for (int node : bone_nodes_)
    out_.rest_bone_globals.push_back(rest_globals[static_cast<std::size_t>(node)]);
  for (std::size_t b = 0; b < out_.bones.size(); ++b)
    out_.bones[b].rest_origin_m = out_.scale * out_.rest_bone_globals[b].translation() + out_.shift;
  HC_RETURN_IF_ERROR(validate(out_));
  return std::move(out_);
}

constexpr unsigned kImportFlags = aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
                                  aiProcess_SortByPType | aiProcess_ValidateDataStructure |
                                  aiProcess_FindInvalidData;

void configure(Assimp::Importer& importer) {
  importer.SetPropertyBool(AI_CONFIG_IMPORT_FBX_PRESERVE_PIVOTS, false);
  importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE,
                              aiPrimitiveType_POINT | aiPrimitiveType_LINE);
}

// The format's usual name, from the extension the importer was chosen by.
std::string format_name(const std::string& ext) {
  if (ext == "gltf" || ext == "glb") return "glTF2";
  if (ext == "fbx") return "FBX";
  if (ext == "dae") return "COLLADA";
  return "DirectX";
}

Result<SkinnedCharacter> finish(Assimp::Importer& importer, const aiScene* scene,
                                const std::string& name, const std::string& ext,
                                const SkinnedReadOptions& options) {
  if (scene == nullptr)
    return invalid_argument(
        fmt::format("{}: not a readable skinned character: {}", name, importer.GetErrorString()));
  if (scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE)
    return invalid_argument(fmt::format("{}: the file holds an incomplete scene", name));
  SceneDecoder decoder(*scene, name, options);
  HC_ASSIGN_OR_RETURN(SkinnedCharacter c, decoder.decode());
  c.report.format = format_name(ext);
  return c;
}

std::string lower_extension(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  if (!ext.empty() && ext[0] == '.') ext.erase(0, 1);
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
  return ext;
}

Status check_extension(const std::string& ext, const std::string& name) {
  static const char* const kKnown[] = {"gltf", "glb", "fbx", "dae", "x"};
  for (const char* k : kKnown)
    if (ext == k) return {};
  return unsupported(fmt::format(
      "{}: unknown skinned-character format '.{}' (expected .gltf, .glb, .fbx, .dae or .x)", name,
      ext));
}

aiMatrix4x4 to_assimp(const Eigen::Affine3d& a) {
  const Eigen::Matrix4d& m = a.matrix();
  return aiMatrix4x4(
      static_cast<float>(m(0, 0)), static_cast<float>(m(0, 1)), static_cast<float>(m(0, 2)),
      static_cast<float>(m(0, 3)), static_cast<float>(m(1, 0)), static_cast<float>(m(1, 1)),
      static_cast<float>(m(1, 2)), static_cast<float>(m(1, 3)), static_cast<float>(m(2, 0)),
      static_cast<float>(m(2, 1)), static_cast<float>(m(2, 2)), static_cast<float>(m(2, 3)),
      static_cast<float>(m(3, 0)), static_cast<float>(m(3, 1)), static_cast<float>(m(3, 2)),
      static_cast<float>(m(3, 3)));
}

// Each bone's transform relative to its parent bone (or the scene root).
Eigen::Affine3d bone_local(const SkinnedCharacter& c, const std::vector<Eigen::Affine3d>& globals,
                           std::size_t b) {
  const int p = c.bones[b].parent;
  return p < 0 ? globals[b] : globals[static_cast<std::size_t>(p)].inverse() * globals[b];
}

aiNodeAnim* channel_of(const SkinnedCharacter& c, const Clip& clip, std::size_t b) {
  auto* ch = new aiNodeAnim;
  ch->mNodeName = aiString(c.bones[b].name);
  const unsigned n = static_cast<unsigned>(clip.times_s.size());
  ch->mNumPositionKeys = ch->mNumRotationKeys = ch->mNumScalingKeys = n;
  ch->mPositionKeys = new aiVectorKey[n];
  ch->mRotationKeys = new aiQuatKey[n];
  ch->mScalingKeys = new aiVectorKey[n];
  for (unsigned f = 0; f < n; ++f) {
    const Eigen::Affine3d local = bone_local(c, clip.bone_globals[f], b);
    Eigen::Matrix3d rotation, scaling;
    local.computeRotationScaling(&rotation, &scaling);
    const Eigen::Quaterniond q(rotation);
    const Eigen::Vector3d t = local.translation();
    const double time = clip.times_s[f];  // exported at 1 tick per second
    ch->mPositionKeys[f] =
        aiVectorKey(time, aiVector3D(static_cast<float>(t.x()), static_cast<float>(t.y()),
                                     static_cast<float>(t.z())));
    ch->mRotationKeys[f] =
        aiQuatKey(time, aiQuaternion(static_cast<float>(q.w()), static_cast<float>(q.x()),
                                     static_cast<float>(q.y()), static_cast<float>(q.z())));
    ch->mScalingKeys[f] = aiVectorKey(
        time, aiVector3D(static_cast<float>(scaling(0, 0)), static_cast<float>(scaling(1, 1)),
                         static_cast<float>(scaling(2, 2))));
  }
  return ch;
}

// The scene Assimp's exporters read: root -> bone nodes (by parent) and one mesh node.
std::unique_ptr<aiScene> scene_of(const SkinnedCharacter& c) {
  auto scene = std::make_unique<aiScene>();
  scene->mRootNode = new aiNode("root");
  std::vector<aiNode*> nodes(c.bones.size());
  std::vector<std::vector<aiNode*>> children(c.bones.size() + 1);  // last: the root's
  for (std::size_t b = 0; b < c.bones.size(); ++b) {
    nodes[b] = new aiNode(c.bones[b].name);
    nodes[b]->mTransformation = to_assimp(bone_local(c, c.rest_bone_globals, b));
    const int p = c.bones[b].parent;
    children[p < 0 ? c.bones.size() : static_cast<std::size_t>(p)].push_back(nodes[b]);
  }
  auto* mesh_node = new aiNode("skin");
  mesh_node->mNumMeshes = 1;
  mesh_node->mMeshes = new unsigned[1]{0};
  children.back().push_back(mesh_node);
  const auto attach = [](aiNode* parent, const std::vector<aiNode*>& kids) {
    if (kids.empty()) return;
    parent->mNumChildren = static_cast<unsigned>(kids.size());
    parent->mChildren = new aiNode*[kids.size()];
    for (std::size_t k = 0; k < kids.size(); ++k) {
      parent->mChildren[k] = kids[k];
      kids[k]->mParent = parent;
    }
  };
  for (std::size_t b = 0; b < c.bones.size(); ++b) attach(nodes[b], children[b]);
  attach(scene->mRootNode, children.back());

  scene->mNumMaterials = 1;
  scene->mMaterials = new aiMaterial* [1] { new aiMaterial };
  auto* mesh = new aiMesh;
  mesh->mName = aiString("skin");
  mesh->mPrimitiveTypes = aiPrimitiveType_TRIANGLE;
  const auto nv = static_cast<unsigned>(c.mesh.num_vertices());
  mesh->mNumVertices = nv;
  mesh->mVertices = new aiVector3D[nv];
  for (unsigned v = 0; v < nv; ++v) {
    const Eigen::Vector3d p = (c.mesh.vertices.row(v).transpose() - c.shift) / c.scale;
    mesh->mVertices[v] =
        aiVector3D(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()));
  }
  mesh->mNumFaces = static_cast<unsigned>(c.mesh.num_triangles());
  mesh->mFaces = new aiFace[mesh->mNumFaces];
  for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
    mesh->mFaces[f].mNumIndices = 3;
    mesh->mFaces[f].mIndices = new unsigned[3];
    for (int k = 0; k < 3; ++k)
      mesh->mFaces[f].mIndices[k] = static_cast<unsigned>(c.mesh.triangles(f, k));
  }
  std::vector<std::vector<aiVertexWeight>> weights(c.bones.size());
  for (unsigned v = 0; v < nv; ++v)
    for (std::int64_t k = c.influence_start[v]; k < c.influence_start[v + 1]; ++k) {
      const Influence& inf = c.influences[static_cast<std::size_t>(k)];
      weights[static_cast<std::size_t>(inf.bone)].emplace_back(v, static_cast<float>(inf.weight));
    }
  std::vector<aiBone*> bones;
  for (std::size_t b = 0; b < c.bones.size(); ++b) {
    if (weights[b].empty()) continue;
    auto* bone = new aiBone;
    bone->mName = aiString(c.bones[b].name);
    bone->mOffsetMatrix = to_assimp(c.rest_bone_globals[b].inverse());
    bone->mNumWeights = static_cast<unsigned>(weights[b].size());
    bone->mWeights = new aiVertexWeight[weights[b].size()];
    std::copy(weights[b].begin(), weights[b].end(), bone->mWeights);
    bones.push_back(bone);
  }
  mesh->mNumBones = static_cast<unsigned>(bones.size());
  mesh->mBones = new aiBone*[bones.size()];
  std::copy(bones.begin(), bones.end(), mesh->mBones);
  scene->mNumMeshes = 1;
  scene->mMeshes = new aiMesh* [1] { mesh };

  scene->mNumAnimations = static_cast<unsigned>(c.clips.size());
  if (!c.clips.empty()) scene->mAnimations = new aiAnimation*[c.clips.size()];
  for (std::size_t a = 0; a < c.clips.size(); ++a) {
    auto* anim = new aiAnimation;
    anim->mName = aiString(c.clips[a].name);
    anim->mTicksPerSecond = 1.0;
    anim->mDuration = c.clips[a].times_s.back();
    anim->mNumChannels = static_cast<unsigned>(c.bones.size());
    anim->mChannels = new aiNodeAnim*[c.bones.size()];
    for (std::size_t b = 0; b < c.bones.size(); ++b)
      anim->mChannels[b] = channel_of(c, c.clips[a], b);
    scene->mAnimations[a] = anim;
  }
  return scene;
}

}  // namespace

Status write_skinned_character(const std::filesystem::path& path,
                               const SkinnedCharacter& character) {
  HC_RETURN_IF_ERROR(validate(character));
  const std::string ext = lower_extension(path);
  // FBX as ASCII: Assimp 5.2.5 cannot read back its own binary FBX ("FBX-Tokenize ... block
  // offset is out of range"). DirectX is left out: Assimp's .x writer drops the skin.
  static const std::map<std::string, std::string> kFormat = {
      {"glb", "glb2"}, {"gltf", "gltf2"}, {"fbx", "fbxa"}, {"dae", "collada"}};
  auto it = kFormat.find(ext);
  if (it == kFormat.end())
    return unsupported(
        fmt::format("{}: cannot write skinned characters as '.{}'", path.string(), ext));
  const std::unique_ptr<aiScene> scene = scene_of(character);
  Assimp::Exporter exporter;
  if (exporter.Export(scene.get(), it->second, path.string()) != aiReturn_SUCCESS)
    return io_error(
        fmt::format("{}: Assimp could not write it: {}", path.string(), exporter.GetErrorString()));
  return {};
}

Status SkinnedReadOptions::validate() const {
  if (!(target_height_m >= 0) || !std::isfinite(target_height_m))
    return invalid_argument(fmt::format("target_height_m must be >= 0, got {}", target_height_m));
  if (!(sample_rate_hz > 0) || !std::isfinite(sample_rate_hz))
    return invalid_argument(fmt::format("sample_rate_hz must be > 0, got {}", sample_rate_hz));
  if (max_frames_per_clip < 2)
    return invalid_argument(
        fmt::format("max_frames_per_clip must be >= 2, got {}", max_frames_per_clip));
  return {};
}

Result<SkinnedCharacter> read_skinned_character(const std::filesystem::path& path,
                                                const SkinnedReadOptions& options) {
  HC_RETURN_IF_ERROR(options.validate());
  const std::string name = path.string();
  const std::string ext = lower_extension(path);
  if (Status s = check_extension(ext, name); !s.ok()) return invalid_argument(s.message());
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  if (ec) return not_found(fmt::format("{}: cannot read: {}", name, ec.message()));
  if (size > options.max_file_bytes)
    return invalid_argument(fmt::format("{}: {} bytes is larger than the limit of {}", name, size,
                                        options.max_file_bytes));
  Assimp::Importer importer;
  configure(importer);
  const aiScene* scene = importer.ReadFile(path.string(), kImportFlags);
  return finish(importer, scene, name, ext, options);
}

Result<SkinnedCharacter> parse_skinned_character(std::string_view bytes,
                                                 std::string_view extension_hint,
                                                 std::string_view name,
                                                 const SkinnedReadOptions& options) {
  HC_RETURN_IF_ERROR(options.validate());
  const std::string ext =
      lower_extension(std::filesystem::path("x." + std::string(extension_hint)));
  if (Status s = check_extension(ext, std::string(name)); !s.ok())
    return invalid_argument(s.message());
  if (bytes.empty()) return invalid_argument(fmt::format("{}: empty input", name));
  if (bytes.size() > options.max_file_bytes)
    return invalid_argument(fmt::format("{}: {} bytes is larger than the limit of {}", name,
                                        bytes.size(), options.max_file_bytes));
  Assimp::Importer importer;
  configure(importer);
  const aiScene* scene =
      importer.ReadFileFromMemory(bytes.data(), bytes.size(), kImportFlags, ext.c_str());
  return finish(importer, scene, std::string(name), ext, options);
}

}  // namespace hc::articulation
