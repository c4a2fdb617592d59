#include "fabrication/articulation/collisions.h"

#include <fmt/format.h>

#include <algorithm>
#include <map>
#include <memory>
#include <set>
#include <utility>

#include "geometry/mesh_distance.h"
#include "geometry/mesh_proximity.h"

namespace hc::articulation {
namespace {

using Edge = std::pair<int, int>;
// Shrink steps computed per group at most: 0.9^200 of r_max is far below any feasible joint.
constexpr std::size_t kMaxSteps = 200;

struct Group {
  std::vector<int> members;
  int origin = 0;  // index of the initial group it descends from
};

class Resolver {
 public:
  Resolver(std::vector<Joint>* joints, std::vector<JointHull>* hulls, const RedesignFn& redesign,
           const HullFn& build, const CollisionOptions& options, CollisionSummary* summary)
      : joints_(*joints),
        hulls_(*hulls),
        redesign_(redesign),
        build_(build),
        o_(options),
        s_(*summary),
        distance_(joints->size()),
        proximity_(joints->size()) {}

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
  struct Built {
    JointHull hull;
    std::shared_ptr<geometry::MeshDistance> distance;
    std::shared_ptr<geometry::MeshProximity> proximity;
  };
  std::map<std::pair<int, double>, Built> built_;  // by joint and r_max
  std::vector<std::shared_ptr<geometry::MeshDistance>> distance_;
  std::vector<std::shared_ptr<geometry::MeshProximity>> proximity_;
  std::vector<double> initial_area_, initial_r_;
};

Status Resolver::refresh(int i) {
  // A joint's design, and so its hull, depends only on its r_max: hulls met before are reused.
  auto [it, fresh] = built_.try_emplace({i, J(i).r_max});
  Built& b = it->second;
  if (fresh) {
    HC_ASSIGN_OR_RETURN(b.hull, build_(J(i)));
    HC_ASSIGN_OR_RETURN(geometry::MeshDistance d, geometry::MeshDistance::build(b.hull.hull));
    HC_ASSIGN_OR_RETURN(geometry::MeshProximity p, geometry::MeshProximity::build(b.hull.hull));
    b.distance = std::make_shared<geometry::MeshDistance>(std::move(d));
    b.proximity = std::make_shared<geometry::MeshProximity>(std::move(p));
  }
  hulls_[static_cast<std::size_t>(i)] = b.hull;
  distance_[static_cast<std::size_t>(i)] = b.distance;
  proximity_[static_cast<std::size_t>(i)] = b.proximity;
  return {};
}

bool Resolver::collide(int i, int j) {
  const Joint &a = J(i), &b = J(j);
  const double d = o_.clearance_m;
  const double gap = (a.centre - b.centre).norm();
  const double ra = hulls_[static_cast<std::size_t>(i)].reach_m,
               rb = hulls_[static_cast<std::size_t>(j)].reach_m;
  if (gap > std::max(ra, a.r_max) + std::max(rb, b.r_max) + d) return false;
  if (gap < a.r_max + b.r_max + d) return true;  // mechanism spheres
  if (distance_[static_cast<std::size_t>(j)]->signed_distance(a.centre) < a.r_max + d) return true;
  if (distance_[static_cast<std::size_t>(i)]->signed_distance(b.centre) < b.r_max + d) return true;
  Result<geometry::ClosestApproach> c = proximity_[static_cast<std::size_t>(j)]->closest_approach(
      hulls_[static_cast<std::size_t>(i)].hull, d);
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
  for (std::size_t k = 0; k < origins.size(); ++k)
    stack.push_back({origins[k], static_cast<int>(k)});
  ProgressTask task(o_.progress, "collisions", 0);
  while (!stack.empty()) {
    Group g = stack.back();
    stack.pop_back();
    std::vector<Edge> edges = edges_among(g.members);
    if (edges.empty()) continue;
    const std::set<int> inside(g.members.begin(), g.members.end());
    // The shrink sequence: each step shrinks the group's strongest member (largest smallest
    // critical area) by o_.shrink, until a collision is resolved or a step fails. It depends on
    // the designs alone, so it is computed first, cheaply; hulls are built only at the steps a
    // search probes for the first one that resolves a collision (hulls were 95 % of this stage
    // when built at every step).
    std::vector<std::vector<Joint>> states{{}};
    for (int m : g.members) states[0].push_back(J(m));
    std::size_t last = 0;  // last feasible step
    bool infeasible = false;
    while (!infeasible && states.size() < kMaxSteps) {
      std::vector<Joint> next = states.back();
      const auto strong =
          std::max_element(next.begin(), next.end(),
                           [](const Joint& x, const Joint& y) { return x.min_area < y.min_area; });
      strong->r_max *= o_.shrink;
      redesign_(&*strong);
      infeasible = !strong->feasible() || strong->min_area < o_.min_area_m2;
      if (!infeasible) states.push_back(std::move(next)), last = states.size() - 1;
    }
    // Step k's outcome: 1 resolved, 0 still colliding, -1 a shrunk member hits a joint outside
    // the group (which fails the group, as an infeasible step does).
    const auto probe = [&](std::size_t k) -> Result<int> {
      for (std::size_t x = 0; x < g.members.size(); ++x) {
        const int m = g.members[x];
        if (J(m).r_max == states[k][x].r_max) continue;
        J(m) = states[k][x];
        HC_RETURN_IF_ERROR(refresh(m));
      }
      for (std::size_t x = 0; x < g.members.size(); ++x) {
        const int m = g.members[x];
        if (states[k][x].r_max == states[0][x].r_max) continue;
        for (std::size_t o = 0; o < joints_.size(); ++o) {
          const int other = static_cast<int>(o);
          if (!J(other).excluded && !inside.count(other) && collide(m, other)) return -1;
        }
      }
      return edges_among(g.members).size() < edges.size() ? 1 : 0;
    };
    // The first resolving step: doubling, then bisection (more shrinking resolves more).
    std::size_t lo = 0, hi = 0;  // lo: known not to resolve; hi: resolves (0: none found)
    int outcome = 0;
    for (std::size_t k = 1; last > 0; k = std::min(2 * k, last)) {
      HC_ASSIGN_OR_RETURN(outcome, probe(k));
      if (outcome != 0) {
        hi = k;
        break;
      }
      lo = k;
      if (k == last) break;
    }
    while (outcome == 1 && hi - lo > 1) {
      const std::size_t mid = (lo + hi) / 2;
      HC_ASSIGN_OR_RETURN(const int at, probe(mid));
      if (at == 0) {
        lo = mid;
      } else {
        hi = mid, outcome = at;
      }
    }
    if (outcome == 1) {
      HC_ASSIGN_OR_RETURN(outcome, probe(hi));  // the joints as at step hi
    }
    const std::size_t steps = outcome == 1 ? hi : last + 1;  // taken, or up to the failing one
    s_.shrink_steps += static_cast<int>(steps);
    task.advance(steps);
    if (outcome != 1) {
      const int weak = *std::min_element(g.members.begin(), g.members.end(), [&](int x, int y) {
        return initial_area_[static_cast<std::size_t>(x)] <
               initial_area_[static_cast<std::size_t>(y)];
      });
      exclude(weak,
              "its collisions with neighbouring joints could not be resolved (weakest "
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
      continue;
    }
    const std::vector<Edge> now = edges_among(g.members);
    s_.collisions_resolved += static_cast<int>(edges.size() - now.size());
    for (auto& comp : components(g.members, now)) stack.push_back({comp, g.origin});
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
