#include "fabrication/articulation/collisions.h"

#include <fmt/format.h>

#include <algorithm>
#include <memory>
#include <set>
#include <utility>

#include "geometry/mesh_distance.h"
#include "geometry/mesh_proximity.h"

namespace hc::articulation {
namespace {

using Edge = std::pair<int, int>;

struct Group {
  std::vector<int> members;
  int origin = 0;  // index of the initial group it descends from
};

class Resolver {
 public:
  Resolver(std::vector<Joint>* joints, std::vector<JointHull>* hulls, const RedesignFn& redesign,
           const HullFn& build, const CollisionOptions& options, CollisionSummary* summary)
      : joints_(*joints), hulls_(*hulls), redesign_(redesign), build_(build), o_(options),
        s_(*summary), distance_(joints->size()), proximity_(joints->size()) {}

  Status run();

 private:
  Joint& J(int i) { return joints_[static_cast<std::size_t>(i)]; }
  Status refresh(int i);  // hull and its queries for joint i
  bool collide(int i, int j);
  std::vector<Edge> edges_among(const std::vector<int>& members);
  std::vector<std::vector<int>> components(const std::vector<int>& members,
                                           const std::vector<Edge>& edges);
  void exclude(int i, const std::string& why);

  std::vector<Joint>& joints_;
  std::vector<JointHull>& hulls_;
  const RedesignFn& redesign_;
  const HullFn& build_;
  const CollisionOptions& o_;
  CollisionSummary& s_;
  std::vector<std::unique_ptr<geometry::MeshDistance>> distance_;
  std::vector<std::unique_ptr<geometry::MeshProximity>> proximity_;
  std::vector<double> initial_area_, initial_r_;
};

Status Resolver::refresh(int i) {
  HC_ASSIGN_OR_RETURN(hulls_[static_cast<std::size_t>(i)], build_(J(i)));
  const TriangleMesh& h = hulls_[static_cast<std::size_t>(i)].hull;
  HC_ASSIGN_OR_RETURN(geometry::MeshDistance d, geometry::MeshDistance::build(h));
  HC_ASSIGN_OR_RETURN(geometry::MeshProximity p, geometry::MeshProximity::build(h));
  distance_[static_cast<std::size_t>(i)] = std::make_unique<geometry::MeshDistance>(std::move(d));
  proximity_[static_cast<std::size_t>(i)] = std::make_unique<geometry::MeshProximity>(std::move(p));
  return {};
}

bool Resolver::collide(int i, int j) {
  const Joint &a = J(i), &b = J(j);
  const double d = o_.clearance_m;
  const double gap = (a.centre - b.centre).norm();
  const double ra = hulls_[static_cast<std::size_t>(i)].reach_m, rb = hulls_[static_cast<std::size_t>(j)].reach_m;
  if (gap > std::max(ra, a.r_max) + std::max(rb, b.r_max) + d) return false;
  if (gap < a.r_max + b.r_max + d) return true;  // mechanism spheres
  if (distance_[static_cast<std::size_t>(j)]->signed_distance(a.centre) < a.r_max + d) return true;
  if (distance_[static_cast<std::size_t>(i)]->signed_distance(b.centre) < b.r_max + d) return true;
  Result<geometry::ClosestApproach> c =
      proximity_[static_cast<std::size_t>(j)]->closest_approach(hulls_[static_cast<std::size_t>(i)].hull, d);
  return !c.ok() || c->found;
}

std::vector<Edge> Resolver::edges_among(const std::vector<int>& members) {
  std::vector<Edge> out;
  for (std::size_t x = 0; x < members.size(); ++x)
    for (std::size_t y = x + 1; y < members.size(); ++y)
      if (collide(members[x], members[y])) out.emplace_back(members[x], members[y]);
  return out;
}

std::vector<std::vector<int>> Resolver::components(const std::vector<int>& members,
                                                   const std::vector<Edge>& edges) {
  std::vector<std::vector<int>> out;
  std::set<int> left(members.begin(), members.end());
  while (!left.empty()) {
    std::vector<int> comp{*left.begin()};
    left.erase(left.begin());
    for (std::size_t k = 0; k < comp.size(); ++k)
      for (const Edge& e : edges) {
        const int other = e.first == comp[k] ? e.second : e.second == comp[k] ? e.first : -1;
        if (other >= 0 && left.erase(other)) comp.push_back(other);
      }
    if (comp.size() > 1) out.push_back(comp);
  }
  return out;
}

void Resolver::exclude(int i, const std::string& why) {
  J(i).excluded = true;
  J(i).reason = why;
  ++s_.excluded;
  s_.log.push_back(fmt::format("excluded {} -> {}: {}", J(i).parent_name, J(i).child_name, why));
}

Status Resolver::run() {
  std::vector<int> active;
  initial_area_.assign(joints_.size(), 0.0);
  initial_r_.assign(joints_.size(), 0.0);
  for (std::size_t i = 0; i < joints_.size(); ++i) {
    if (joints_[i].excluded) continue;
    active.push_back(static_cast<int>(i));
    initial_area_[i] = joints_[i].min_area;
    initial_r_[i] = joints_[i].r_max;
    HC_RETURN_IF_ERROR(refresh(static_cast<int>(i)));
  }
  const std::vector<Edge> initial = edges_among(active);
  s_.initial_collisions = static_cast<int>(initial.size());
  std::vector<Group> stack;
  std::vector<std::vector<int>> origins = components(active, initial);
  s_.groups = static_cast<int>(origins.size());
  for (std::size_t k = 0; k < origins.size(); ++k) stack.push_back({origins[k], static_cast<int>(k)});
  ProgressTask task(o_.progress, "collisions", 0);
  while (!stack.empty()) {
    Group g = stack.back();
    stack.pop_back();
    std::vector<Edge> edges = edges_among(g.members);
    if (edges.empty()) continue;
    const std::set<int> inside(g.members.begin(), g.members.end());
    while (true) {
      const int strong = *std::max_element(g.members.begin(), g.members.end(),
                                           [&](int x, int y) { return J(x).min_area < J(y).min_area; });
      J(strong).r_max *= o_.shrink;
      redesign_(&J(strong));
      ++s_.shrink_steps;
      task.advance();
      bool fail = !J(strong).feasible() || J(strong).min_area < o_.min_area_m2;
      if (!fail) {
        HC_RETURN_IF_ERROR(refresh(strong));
        for (std::size_t k = 0; k < joints_.size() && !fail; ++k) {
          const int other = static_cast<int>(k);
          if (J(other).excluded || inside.count(other) || other == strong) continue;
          fail = collide(strong, other);
        }
      }
      if (fail) {
        const int weak = *std::min_element(g.members.begin(), g.members.end(), [&](int x, int y) {
          return initial_area_[static_cast<std::size_t>(x)] < initial_area_[static_cast<std::size_t>(y)];
        });
        exclude(weak, "its collisions with neighbouring joints could not be resolved (weakest "
                      "joint of its collision group)");
        // Drop every group descended from the same initial group; restart it without `weak`.
        std::erase_if(stack, [&](const Group& x) { return x.origin == g.origin; });
        std::vector<int> reset;
        for (int m : origins[static_cast<std::size_t>(g.origin)])
          if (!J(m).excluded) reset.push_back(m);
        origins[static_cast<std::size_t>(g.origin)] = reset;
        for (int m : reset) {
          J(m).r_max = initial_r_[static_cast<std::size_t>(m)];
          redesign_(&J(m));
          HC_RETURN_IF_ERROR(refresh(m));
        }
        for (auto& comp : components(reset, edges_among(reset))) stack.push_back({comp, g.origin});
        break;
      }
      const std::vector<Edge> now = edges_among(g.members);
      if (now.size() < edges.size()) {
        s_.collisions_resolved += static_cast<int>(edges.size() - now.size());
        for (auto& comp : components(g.members, now)) stack.push_back({comp, g.origin});
        break;
      }
      edges = now;
    }
  }
  return {};
}

}  // namespace

Status resolve_collisions(std::vector<Joint>* joints, std::vector<JointHull>* hulls,
                          const RedesignFn& redesign, const HullFn& build_hull,
                          const CollisionOptions& options, CollisionSummary* summary) {
  if (hulls->size() != joints->size()) hulls->resize(joints->size());
  Resolver r(joints, hulls, redesign, build_hull, options, summary);
  return r.run();
}

}  // namespace hc::articulation
