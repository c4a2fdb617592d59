// Joint-joint collisions (thesis Sec. 6.4.4). Each joint occupies its mechanism's sphere (radius
// r_max about its centre) and its hull's cut surfaces; two joints collide when these come closer
// than d (each inflated by d/2). Colliding joints form a collision graph; its connected groups go
// on a stack. For the top group, the strongest member (largest smallest critical area) is shrunk
// (r_max reduced, design re-optimised, hull rebuilt) until a collision is resolved (the group is
// split into what still collides and pushed back), or it becomes infeasible (below A_min) or hits
// a joint outside its group: then the group's weakest member at initialisation is excluded, every
// group descended from the same initial group is dropped, and that initial group is pushed back
// without it and with its radii reset. Radii only shrink and every failure excludes a joint, so
// the loop ends. The shrink steps depend on the designs alone, so they are computed first and
// hulls are built only at the steps a doubling-then-bisection search probes for the first one
// that resolves a collision (outside collisions are checked at those steps); hulls are reused by
// r_max.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "common/progress.h"
#include "common/status.h"
#include "fabrication/articulation/joint.h"
#include "fabrication/articulation/joint_hull.h"

namespace hc::articulation {

struct CollisionOptions {
  double clearance_m = 0.3e-3;
  double min_area_m2 = 10e-6;
  double shrink = 0.9;  // r_max factor per step
  ProgressReporter* progress = nullptr;
};

struct CollisionSummary {
  int initial_collisions = 0;   // colliding pairs before resolution
  int collisions_resolved = 0;  // pairs separated by shrinking
  int shrink_steps = 0;
  int excluded = 0;
  int groups = 0;  // initial collision groups
  std::vector<std::string> log;
};

// Re-optimises a joint's design at its current r_max (sets ball/hinge and min_area).
using RedesignFn = std::function<void(Joint*)>;
// Builds a joint's hull.
using HullFn = std::function<Result<JointHull>(const Joint&)>;

// Resolves the collisions among the joints that are not excluded; `hulls` (one per joint, built
// for the non-excluded ones) is updated with the joints. Excluded joints get their reason.
Status resolve_collisions(std::vector<Joint>* joints, std::vector<JointHull>* hulls,
                          const RedesignFn& redesign, const HullFn& build_hull,
                          const CollisionOptions& options, CollisionSummary* summary);

}  // namespace hc::articulation
