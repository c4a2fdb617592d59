#include "fabrication/articulation/skinned_character.h"

#include <fmt/format.h>

#include <cmath>

namespace hc::articulation {

Eigen::MatrixXd SkinnedCharacter::dense_weights() const {
  Eigen::MatrixXd w = Eigen::MatrixXd::Zero(mesh.num_vertices(), num_bones());
  for (Eigen::Index v = 0; v < mesh.num_vertices(); ++v)
    for (std::int64_t k = influence_start[static_cast<std::size_t>(v)];
         k < influence_start[static_cast<std::size_t>(v) + 1]; ++k) {
      const Influence& inf = influences[static_cast<std::size_t>(k)];
      w(v, inf.bone) += inf.weight;
    }
  return w;
}

MatrixX3d SkinnedCharacter::pose(const std::vector<Eigen::Affine3d>& bone_globals) const {
  MatrixX3d out(mesh.num_vertices(), 3);
  for (Eigen::Index v = 0; v < mesh.num_vertices(); ++v) {
    Eigen::Vector3d p = Eigen::Vector3d::Zero();
    for (std::int64_t k = influence_start[static_cast<std::size_t>(v)];
         k < influence_start[static_cast<std::size_t>(v) + 1]; ++k) {
      const Influence& inf = influences[static_cast<std::size_t>(k)];
      p += inf.weight * (bone_globals[static_cast<std::size_t>(inf.bone)] * inf.local);
    }
    out.row(v) = scale * p + shift;
  }
  return out;
}

Status validate(const SkinnedCharacter& c) {
  const auto fail = [&c](const std::string& what) {
    return invalid_argument(fmt::format("{}: {}", c.source, what));
  };
  const Eigen::Index nv = c.mesh.num_vertices();
  if (nv == 0 || c.mesh.num_triangles() == 0) return fail("no triangles");
  if (!c.mesh.vertices.allFinite()) return fail("a vertex is not finite");
  if (c.mesh.triangles.minCoeff() < 0 || c.mesh.triangles.maxCoeff() >= nv)
    return fail("a triangle indexes a vertex out of range");
  if (c.bones.empty()) return fail("no bones");
  const int nb = static_cast<int>(c.bones.size());
  for (int b = 0; b < nb; ++b) {
    const int p = c.bones[static_cast<std::size_t>(b)].parent;
    // Parents first rules out cycles: following parents strictly decreases the index.
    if (p >= b || p < -1)
      return fail(fmt::format("bone '{}': parent {} is not an earlier bone (a bone cycle?)",
                              c.bones[static_cast<std::size_t>(b)].name, p));
  }
  if (c.rest_bone_globals.size() != c.bones.size()) return fail("rest transforms per bone");
  if (c.influence_start.size() != static_cast<std::size_t>(nv) + 1 ||
      c.influence_start.front() != 0 ||
      c.influence_start.back() != static_cast<std::int64_t>(c.influences.size()))
    return fail("influence rows do not match the vertices");
  for (Eigen::Index v = 0; v < nv; ++v) {
    const std::int64_t b = c.influence_start[static_cast<std::size_t>(v)];
    const std::int64_t e = c.influence_start[static_cast<std::size_t>(v) + 1];
    if (e <= b) return fail(fmt::format("vertex {} has no skinning weight", v));
    double sum = 0.0;
    for (std::int64_t k = b; k < e; ++k) {
      const Influence& inf = c.influences[static_cast<std::size_t>(k)];
      if (inf.bone < 0 || inf.bone >= nb) return fail(fmt::format("vertex {}: bone index", v));
      if (!(inf.weight > 0) || !inf.local.allFinite())
        return fail(fmt::format("vertex {}: weight {} (expected > 0)", v, inf.weight));
      sum += inf.weight;
    }
    if (std::abs(sum - 1.0) > 1e-9)
      return fail(fmt::format("vertex {}: weights sum to {} (expected 1)", v, sum));
  }
  for (const Clip& clip : c.clips) {
    if (clip.times_s.size() != clip.bone_globals.size() || clip.times_s.size() < 2)
      return fail(fmt::format("clip '{}': frames and times differ", clip.name));
    for (const auto& frame : clip.bone_globals)
      if (frame.size() != c.bones.size())
        return fail(fmt::format("clip '{}': a frame does not pose every bone", clip.name));
  }
  return {};
}

}  // namespace hc::articulation
