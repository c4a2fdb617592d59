#include "fabrication/articulation/carving.h"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <map>
#include <memory>
#include <numeric>

#include "fabrication/articulation/primitives.h"
#include "geometry/csg_sequence.h"
#include "geometry/mesh_distance.h"
#include "geometry/mesh_proximity.h"

namespace hc::articulation {
namespace {

struct DisjointSets {
  std::vector<int> parent;
  explicit DisjointSets(int n) : parent(static_cast<std::size_t>(n)) {
    std::iota(parent.begin(), parent.end(), 0);
  }
  int find(int v) {
    while (parent[static_cast<std::size_t>(v)] != v)
      v = parent[static_cast<std::size_t>(v)] =
          parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(v)])];
    return v;
  }
  bool unite(int a, int b) {
    a = find(a), b = find(b);
    if (a == b) return false;
    parent[static_cast<std::size_t>(a)] = b;
    return true;
  }
};

// Adds to summary->severed the joints whose hull surface `piece` lies on (within 0.1 um: its
// vertices there are the rounded exact intersection points).
Status blame_severing_joints(const TriangleMesh& piece, const std::vector<Joint>& joints,
                             const std::vector<JointHull>& hulls,
                             std::vector<std::unique_ptr<geometry::MeshDistance>>* trees,
                             CarveSummary* summary) {
  constexpr double kOnSurface = 1e-7;
  for (std::size_t i = 0; i < joints.size(); ++i) {
    if (joints[i].excluded) continue;
    if (!(*trees)[i]) {
      HC_ASSIGN_OR_RETURN(geometry::MeshDistance d, geometry::MeshDistance::build(hulls[i].hull));
      (*trees)[i] = std::make_unique<geometry::MeshDistance>(std::move(d));
    }
    bool touches = false;
    for (Eigen::Index v = 0; v < piece.num_vertices() && !touches; ++v)
      touches = (*trees)[i]->distance(piece.vertices.row(v).transpose()) < kOnSurface;
    if (touches && std::find(summary->severed.begin(), summary->severed.end(),
                             static_cast<int>(i)) == summary->severed.end())
      summary->severed.push_back(static_cast<int>(i));
  }
  return {};
}

}  // namespace

std::vector<TriangleMesh> split_components(const TriangleMesh& m) {
  std::vector<int> parent(static_cast<std::size_t>(m.num_vertices()));
  std::iota(parent.begin(), parent.end(), 0);
  const auto find = [&](int v) {
    while (parent[static_cast<std::size_t>(v)] != v)
      v = parent[static_cast<std::size_t>(v)] =
          parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(v)])];
    return v;
  };
  for (Eigen::Index t = 0; t < m.num_triangles(); ++t)
    for (int k = 1; k < 3; ++k)
      parent[static_cast<std::size_t>(find(m.triangles(t, k)))] = find(m.triangles(t, 0));
  std::vector<int> component_of_root(parent.size(), -1);
  std::vector<std::vector<Eigen::Index>> tris;
  for (Eigen::Index t = 0; t < m.num_triangles(); ++t) {
    const int root = find(m.triangles(t, 0));
    int& c = component_of_root[static_cast<std::size_t>(root)];
    if (c < 0) c = static_cast<int>(tris.size()), tris.emplace_back();
    tris[static_cast<std::size_t>(c)].push_back(t);
  }
  std::vector<TriangleMesh> out;
  for (const auto& list : tris) {
    std::vector<int> index(parent.size(), -1);
    std::vector<int> used;
    TriangleMesh part;
    part.triangles.resize(static_cast<Eigen::Index>(list.size()), 3);
    for (std::size_t i = 0; i < list.size(); ++i)
      for (int k = 0; k < 3; ++k) {
        const int v = m.triangles(list[i], k);
        if (index[static_cast<std::size_t>(v)] < 0)
          index[static_cast<std::size_t>(v)] = static_cast<int>(used.size()), used.push_back(v);
        part.triangles(static_cast<Eigen::Index>(i), k) = index[static_cast<std::size_t>(v)];
      }
    part.vertices.resize(static_cast<Eigen::Index>(used.size()), 3);
    for (std::size_t i = 0; i < used.size(); ++i)
      part.vertices.row(static_cast<Eigen::Index>(i)) = m.vertices.row(used[i]);
    out.push_back(std::move(part));
  }
  return out;
}

Result<std::vector<Solid>> solids_of(const TriangleMesh& mesh, int* cavities) {
  std::vector<Solid> solids;
  std::vector<TriangleMesh> inward;
  for (TriangleMesh& shell : split_components(mesh)) {
    const double volume = enclosed_volume(shell);
    if (volume < 0) {
      inward.push_back(std::move(shell));
    } else {
      solids.push_back({std::move(shell), volume});
    }
  }
  if (inward.empty()) return solids;
  std::vector<std::unique_ptr<geometry::MeshProximity>> inside;
  for (const Solid& s : solids) {
    HC_ASSIGN_OR_RETURN(geometry::MeshProximity tree, geometry::MeshProximity::build(s.mesh));
    inside.push_back(std::make_unique<geometry::MeshProximity>(std::move(tree)));
  }
  std::vector<std::vector<TriangleMesh>> held(solids.size());
  for (TriangleMesh& cavity : inward) {
    const Eigen::Vector3d at = cavity.vertices.row(0).transpose();
    std::size_t host = 0;
    while (host < solids.size() && !inside[host]->contains(at)) ++host;
    if (host == solids.size()) continue;
    solids[host].volume_m3 += enclosed_volume(cavity);
    held[host].push_back(std::move(cavity));
    if (cavities != nullptr) ++*cavities;
  }
  for (std::size_t k = 0; k < solids.size(); ++k) {
    if (held[k].empty()) continue;
    held[k].insert(held[k].begin(), std::move(solids[k].mesh));
    solids[k].mesh = concatenated(held[k]);
  }
  return solids;
}

void exclude_unseparable_joints(const std::vector<LinkContact>& contacts, int links,
                                std::vector<Joint>* joints) {
  while (true) {
    // Links joined by a contact without a joint are one part.
    DisjointSets part(links);
    for (const LinkContact& c : contacts) {
      bool jointed = false;
      for (const Joint& j : *joints)
        jointed = jointed || (!j.excluded && ((j.parent_link == c.a && j.child_link == c.b) ||
                                              (j.parent_link == c.b && j.child_link == c.a)));
      if (!jointed) part.unite(c.a, c.b);
    }
    std::vector<std::size_t> order;
    for (std::size_t i = 0; i < joints->size(); ++i)
      if (!(*joints)[i].excluded) order.push_back(i);
    std::stable_sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) {
      return (*joints)[x].min_area > (*joints)[y].min_area;
    });
    DisjointSets tree = part;
    bool changed = false;
    for (std::size_t i : order) {
      Joint& j = (*joints)[i];
      if (part.find(j.parent_link) == part.find(j.child_link)) {
        j.excluded = true;
        j.reason = "its two links also touch where no joint is, so no cut can separate them";
      } else if (!tree.unite(j.parent_link, j.child_link)) {
        j.excluded = true;
        j.reason = "it would close a loop of jointed parts (a stronger joint already links them)";
      } else {
        continue;
      }
      changed = true;
      break;  // the excluded joint's contact now joins its links: recompute the parts
    }
    if (!changed) return;
  }
}

Eigen::Vector3d child_probe(const Joint& j) {
  if (j.type == JointType::kBall) return j.centre;
  return j.centre + j.n * 0.5 * (j.hinge.r + j.hinge.R - j.hinge.clearance);
}

Eigen::Vector3d parent_probe(const Joint& j) {
  if (j.type == JointType::kBall) return j.centre - j.n * 0.5 * (j.ball.r + j.r_max);
  return j.centre;
}

Result<std::vector<CarvedPart>> carve_parts(
    const TriangleMesh& fabrication, const std::vector<int>& vertex_link,
    const std::vector<std::string>& bone_names, const std::vector<int>& bone_depth,
    const std::vector<Joint>& joints, const std::vector<JointHull>& hulls, double debris_volume_m3,
    ProgressReporter* progress, CarveSummary* summary) {
  const auto start = std::chrono::steady_clock::now();
  // Hulls whose bounding boxes are apart are subtracted together, as one operand of several
  // closed components: each corefinement pass walks all of F (584,320 triangles for a wrapped
  // Testwuson), so fewer passes carve faster. Resolved joints' hulls are d apart anyway.
  struct Batch {
    std::vector<TriangleMesh> hulls;
    std::vector<Eigen::AlignedBox3d> boxes;
    std::string name;
  };
  std::vector<Batch> batches;
  for (std::size_t i = 0; i < joints.size(); ++i) {
    if (joints[i].excluded) continue;
    const TriangleMesh& h = hulls[i].hull;
    const Eigen::AlignedBox3d box(h.vertices.colwise().minCoeff().transpose(),
                                  h.vertices.colwise().maxCoeff().transpose());
    auto fits = std::find_if(batches.begin(), batches.end(), [&](const Batch& b) {
      return std::none_of(b.boxes.begin(), b.boxes.end(),
                          [&](const Eigen::AlignedBox3d& o) { return o.intersects(box); });
    });
    if (fits == batches.end()) fits = batches.insert(batches.end(), Batch{});
    fits->hulls.push_back(h);
    fits->boxes.push_back(box);
    fits->name += fmt::format("{}hull {} -> {}", fits->name.empty() ? "" : ", ",
                              joints[i].parent_name, joints[i].child_name);
  }
  std::vector<geometry::CsgStep> steps;
  for (Batch& b : batches)
    steps.push_back({geometry::BooleanOperation::kDifference, concatenated(b.hulls), b.name});
  geometry::CsgOptions options;
  options.check_operands = false;  // F is checked when built; hulls are exact CSG results
  options.progress = progress;
  geometry::CsgSummary csg;
  HC_ASSIGN_OR_RETURN(const TriangleMesh carved,
                      geometry::csg_sequence(fabrication, steps, options, &csg));
  summary->closed = csg.closed;
  summary->self_intersecting_pairs_after_rounding = csg.self_intersecting_pairs_after_rounding;
  // The solid pieces (each with its cavities: a wrapped soup's inner surfaces), and which of
  // them hold a joint's probe point; the others are F's unjointed parts, or debris.
  HC_ASSIGN_OR_RETURN(std::vector<Solid> pieces, solids_of(carved, &summary->cavities));
  summary->components = static_cast<int>(pieces.size()) + summary->cavities;
  std::vector<std::unique_ptr<geometry::MeshProximity>> inside;
  for (const Solid& piece : pieces) {
    HC_ASSIGN_OR_RETURN(geometry::MeshProximity tree, geometry::MeshProximity::build(piece.mesh));
    inside.push_back(std::make_unique<geometry::MeshProximity>(std::move(tree)));
  }
  const auto piece_of = [&](const Eigen::Vector3d& p) {
    for (std::size_t k = 0; k < inside.size(); ++k)
      if (inside[k]->contains(p)) return static_cast<int>(k);
    return -1;
  };
  std::vector<bool> probed(pieces.size(), false);
  for (std::size_t i = 0; i < joints.size(); ++i) {
    if (joints[i].excluded) continue;
    const int a = piece_of(child_probe(joints[i])), b = piece_of(parent_probe(joints[i]));
    if (a < 0 || b < 0 || a == b) summary->unseparated.push_back(static_cast<int>(i));
    for (int k : {a, b})
      if (k >= 0) probed[static_cast<std::size_t>(k)] = true;
  }

  std::vector<std::unique_ptr<geometry::MeshDistance>> hull_trees(joints.size());
  // Which links each piece holds: the link of F's nearest vertex, by majority.
  HC_ASSIGN_OR_RETURN(const geometry::MeshDistance f_tree,
                      geometry::MeshDistance::build(fabrication));
  std::vector<CarvedPart> parts;
  for (std::size_t k = 0; k < pieces.size(); ++k) {
    TriangleMesh& piece = pieces[k].mesh;
    // Debris: a sliver that a hull's faceted surface pinched off where it grazes F's surface.
    // It holds no joint and would print as a loose crumb among the parts.
    const double volume = pieces[k].volume_m3;
    if (!probed[k] && volume < debris_volume_m3) {
      ++summary->debris_pieces;
      summary->debris_volume_m3 += volume;
      continue;
    }
    // A larger piece without a joint that a hull's surface bounds was severed by that cut (an ear
    // beyond a neck's socket cone); pieces that touch no hull were apart in F already.
    if (!probed[k]) {
      HC_RETURN_IF_ERROR(blame_severing_joints(piece, joints, hulls, &hull_trees, summary));
    }
    std::map<int, int> votes;
    for (Eigen::Index v = 0; v < piece.num_vertices(); ++v) {
      Eigen::Index t = -1;
      const Eigen::Vector3d p = f_tree.closest_point(piece.vertices.row(v).transpose(), &t);
      int best = fabrication.triangles(t, 0);
      for (int c = 1; c < 3; ++c)
        if ((fabrication.vertices.row(fabrication.triangles(t, c)).transpose() - p).norm() <
            (fabrication.vertices.row(best).transpose() - p).norm())
          best = fabrication.triangles(t, c);
      ++votes[vertex_link[static_cast<std::size_t>(best)]];
    }
    CarvedPart part;
    int top = -1, top_votes = 0;
    for (const auto& [link, count] : votes) {
      part.links.push_back(link);
      if (count > top_votes) top = link, top_votes = count;
    }
    std::sort(part.links.begin(), part.links.end(), [&](int a, int b) {
      return bone_depth[static_cast<std::size_t>(a)] < bone_depth[static_cast<std::size_t>(b)];
    });
    // Named after the link most of its surface belongs to.
    part.name = top < 0 ? "part" : bone_names[static_cast<std::size_t>(top)];
    part.mesh = std::move(piece);
    parts.push_back(std::move(part));
  }
  summary->time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return parts;
}

}  // namespace hc::articulation
