// Synthetic skinned characters for the articulation tests: closed tubes along +Y skinned to a
// chain of bones, with clips that rotate one bone about a known axis and centre, so that joint
// positions, hinge axes and ranges have exact expected values.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "fabrication/articulation/skinned_character.h"

namespace hc::testing {

struct SyntheticLimb {
  double radius_m = 0.008;
  double length_m = 0.09;
  int bones = 2;          // equal-length bones along +Y; bone b starts at y = b * length / bones
  int segments = 32;      // vertices per ring
  int rings = 37;         // rings from y = 0 to y = length (caps close both ends)
  double blend_m = 0.01;  // width of the weight ramp centred on each joint
  // Optional x offset of the tube per bone (0: straight). Unused by default.
  std::string name = "synthetic_limb";
};

// Smooth 0 -> 1 ramp over [-w/2, w/2] (C1 smoothstep).
inline double ramp(double x, double w) {
  const double s = std::clamp(x / w + 0.5, 0.0, 1.0);
  return s * s * (3 - 2 * s);
}

// A closed tube (rings + two cap fans) skinned to a chain of bones along +Y. Every bone's rest
// global is a translation to its start; no clips.
inline articulation::SkinnedCharacter skinned_limb(const SyntheticLimb& o) {
  using articulation::Influence;
  articulation::SkinnedCharacter c;
  c.source = o.name;
  const int nv = o.rings * o.segments + 2;
  c.mesh.vertices.resize(nv, 3);
  for (int r = 0; r < o.rings; ++r) {
    const double y = o.length_m * r / (o.rings - 1);
    for (int s = 0; s < o.segments; ++s) {
      const double a = 2 * std::numbers::pi * s / o.segments;
      c.mesh.vertices.row(r * o.segments + s) << o.radius_m * std::cos(a), y,
          o.radius_m * std::sin(a);
    }
  }
  const int bottom = nv - 2, top = nv - 1;
  c.mesh.vertices.row(bottom) << 0, 0, 0;
  c.mesh.vertices.row(top) << 0, o.length_m, 0;
  std::vector<Eigen::Vector3i> tris;
  for (int r = 0; r + 1 < o.rings; ++r)
    for (int s = 0; s < o.segments; ++s) {
      const int a = r * o.segments + s, b = r * o.segments + (s + 1) % o.segments;
      const int a2 = a + o.segments, b2 = b + o.segments;
      // Outward: the ring runs counter-clockwise seen from -Y... checked by signed volume > 0.
      tris.emplace_back(a, a2, b);
      tris.emplace_back(b, a2, b2);
    }
  const int last = (o.rings - 1) * o.segments;
  for (int s = 0; s < o.segments; ++s) {
    tris.emplace_back(bottom, s, (s + 1) % o.segments);
    tris.emplace_back(top, last + (s + 1) % o.segments, last + s);
  }
  c.mesh.triangles.resize(static_cast<Eigen::Index>(tris.size()), 3);
  for (std::size_t t = 0; t < tris.size(); ++t)
    c.mesh.triangles.row(static_cast<Eigen::Index>(t)) = tris[t].transpose();
  c.vertex_mesh.assign(static_cast<std::size_t>(nv), 0);

  const double bone_len = o.length_m / o.bones;
  for (int b = 0; b < o.bones; ++b) {
    articulation::Bone bone;
    bone.name = "bone" + std::to_string(b);
    bone.parent = b - 1;
    bone.depth = b + 1;
    bone.rest_origin_m = Eigen::Vector3d(0, b * bone_len, 0);
    c.bones.push_back(bone);
    c.rest_bone_globals.push_back(Eigen::Affine3d(Eigen::Translation3d(bone.rest_origin_m)));
  }
  c.influence_start.assign(1, 0);
  for (int v = 0; v < nv; ++v) {
    const Eigen::Vector3d p = c.mesh.vertices.row(v).transpose();
    // Membership of each bone: product of ramps up at its start and down at its end.
    std::vector<double> w(static_cast<std::size_t>(o.bones), 1.0);
    for (int j = 1; j < o.bones; ++j) {
      const double s = ramp(p.y() - j * bone_len, o.blend_m);
      for (int b = 0; b < o.bones; ++b) w[static_cast<std::size_t>(b)] *= (b < j ? 1 - s : s);
    }
    double sum = 0;
    for (double x : w) sum += x;
    for (int b = 0; b < o.bones; ++b) {
      const double wb = w[static_cast<std::size_t>(b)] / sum;
      if (wb <= 1e-12) continue;
      c.influences.push_back(
          Influence{b, wb, c.rest_bone_globals[static_cast<std::size_t>(b)].inverse() * p});
    }
    // Drop what was skipped from the normalisation.
    double kept = 0;
    for (auto k = static_cast<std::size_t>(c.influence_start.back()); k < c.influences.size(); ++k)
      kept += c.influences[k].weight;
    for (auto k = static_cast<std::size_t>(c.influence_start.back()); k < c.influences.size(); ++k)
      c.influences[k].weight /= kept;
    c.influence_start.push_back(static_cast<std::int64_t>(c.influences.size()));
  }
  c.report.meshes = 1;
  c.report.input_vertices = nv;
  return c;
}

// A clip rotating bone `bone` (and with it its descendants) about `axis` through `centre` (model
// frame, m) by angle(t) = mid + amplitude * sin(2 pi t / period), sampled at `frames` frames over
// one period. Other bones stay at rest.
inline articulation::Clip rotation_clip(const articulation::SkinnedCharacter& c, int bone,
                                        const Eigen::Vector3d& axis, const Eigen::Vector3d& centre,
                                        double mid_rad, double amplitude_rad, int frames = 41,
                                        double period_s = 2.0, std::string name = "swing") {
  articulation::Clip clip;
  clip.name = std::move(name);
  for (int f = 0; f < frames; ++f) {
    const double t = period_s * f / (frames - 1);
    const double angle = mid_rad + amplitude_rad * std::sin(2 * std::numbers::pi * t / period_s);
    const Eigen::Affine3d motion = Eigen::Translation3d(centre) *
                                   Eigen::AngleAxisd(angle, axis.normalized()) *
                                   Eigen::Translation3d(-centre);
    std::vector<Eigen::Affine3d> g = c.rest_bone_globals;
    for (std::size_t b = 0; b < c.bones.size(); ++b) {
      bool moves = false;
      for (int a = static_cast<int>(b); a >= 0; a = c.bones[static_cast<std::size_t>(a)].parent)
        moves = moves || a == bone;
      if (moves) g[b] = motion * g[b];
    }
    clip.times_s.push_back(t);
    clip.bone_globals.push_back(std::move(g));
  }
  return clip;
}

}  // namespace hc::testing
