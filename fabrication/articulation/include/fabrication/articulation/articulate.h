// Skinned character -> posable, print-in-place articulated model (thesis Ch. 6), the whole
// pipeline: fabrication mesh, transitions and joint locations, joint types/axes/ranges/centres
// from the clips (or defaults, or the user's overrides), max-min joint designs, collision
// resolution, carving into interlocked parts, and the checks of the result.
#pragma once

#include <string>
#include <vector>

#include "common/mesh.h"
#include "common/progress.h"
#include "common/status.h"
#include "fabrication/articulation/carving.h"
#include "fabrication/articulation/collisions.h"
#include "fabrication/articulation/fabrication_mesh.h"
#include "fabrication/articulation/joint.h"
#include "fabrication/articulation/joint_locations.h"
#include "fabrication/articulation/printer_profile.h"
#include "fabrication/articulation/skinned_character.h"
#include "fabrication/articulation/verification.h"

namespace hc::articulation {

struct ArticulateOptions {
  PrinterProfile printer;
  JointOverrides overrides;
  bool use_animation = true;
  TransitionOptions transitions;
  MotionOptions motion;
  // A motion centre replaces the medial one when its inscribed sphere is at least this fraction
  // of the medial r_max (a centre near the surface would make a weak joint).
  double motion_centre_min_depth = 0.6;
  int hull_segments = 48;
  bool force_wrap = false;
  bool verify = true;
  VerificationOptions verification;
  ProgressReporter* progress = nullptr;
  Status validate() const;
};

struct StageTime {
  std::string stage;
  double seconds = 0.0;
};

struct ArticulateResult {
  std::vector<Joint> joints;  // every candidate, excluded ones with their reason
  std::vector<CarvedPart> parts;
  FabricationMeshSummary fabrication;
  CollisionSummary collisions;
  CarveSummary carving;
  VerificationReport verification;
  std::vector<StageTime> stages;
  std::vector<std::string> warnings;
  double time_s = 0.0;
  int accepted() const;
};

Result<ArticulateResult> articulate(const SkinnedCharacter& character,
                                    const ArticulateOptions& options);

}  // namespace hc::articulation
