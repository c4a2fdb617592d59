// Times `articulate` (thesis Ch. 6) per stage on real skinned characters and prints what became
// of every joint. Targets (issue 15): <= 60 s for a ~5k-triangle, ~20-joint character (CesiumMan:
// 4,672 triangles, 19 joints) and <= 2 min for a ~50-bone one (BCN_Epileptic.X: 54 bones); the
// thesis's baseline is 5.5 h for "Grumpy" (Sec. 6.5).
//
//   bench_articulate [--no-verify] [FILE HEIGHT_MM]...
//   defaults: every character of shared/data/skinned at 100 mm, and Debian assimp-testmodels'
//   BCN_Epileptic.X, Testwuson.X (150 mm), animation_with_skeleton.fbx, huesitos.fbx
#include <fmt/format.h>

#include <chrono>
#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "fabrication/articulation/articulate.h"
#include "fabrication/articulation/skinned_io.h"
#include "test_data.h"

namespace {

using namespace hc::articulation;

int run(const std::string& file, double height_mm, bool verify) {
  const auto start = std::chrono::steady_clock::now();
  SkinnedReadOptions read;
  read.target_height_m = height_mm * 1e-3;
  hc::Result<SkinnedCharacter> c = read_skinned_character(file, read);
  const double read_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!c.ok()) {
    fmt::print("{}: unreadable: {}\n", file, c.status().to_string());
    return 0;
  }
  ArticulateOptions options;
  options.verify = verify;
  hc::Result<ArticulateResult> r = articulate(*c, options);
  if (!r.ok()) {
    fmt::print("{}: failed: {}\n", file, r.status().to_string());
    return 1;
  }
  fmt::print("{} ({} triangles, {} bones, {} clips, {:.0f} mm): {} joints of {} candidates, {} "
             "parts, {} collisions resolved of {}, fabrication mesh by {} ({} triangles)\n",
             std::filesystem::path(file).filename().string(), c->mesh.num_triangles(),
             c->bones.size(), c->clips.size(), height_mm, r->accepted(), r->joints.size(),
             r->parts.size(), r->collisions.collisions_resolved,
             r->collisions.initial_collisions, r->fabrication.method, r->fabrication.triangles);
  fmt::print("  read {:.2f} s", read_s);
  for (const StageTime& s : r->stages) fmt::print(", {} {:.2f} s", s.stage, s.seconds);
  fmt::print("; total {:.2f} s\n", read_s + r->time_s);
  std::map<std::string, int> reasons;
  for (const Joint& j : r->joints) {
    if (!j.excluded) {
      fmt::print("  {} -> {}: {} ({}), r_max {:.2f} mm, A {:.1f} mm^2\n", j.parent_name,
                 j.child_name, to_string(j.type), to_string(j.source), j.r_max * 1e3,
                 j.min_area * 1e6);
      continue;
    }
    ++reasons[j.reason.substr(0, j.reason.find(':'))];
  }
  for (const auto& [reason, count] : reasons) fmt::print("  excluded x{}: {}\n", count, reason);
  if (verify) {
    const VerificationReport& v = r->verification;
    fmt::print("  check: parts valid {}, closest parts {:.3f} mm, replay {:.0f} % free{}\n",
               v.parts_valid, v.min_part_distance_m * 1e3, 100 * v.replay_share,
               v.problems.empty() ? "" : ", " + std::to_string(v.problems.size()) + " problems");
    for (const std::string& p : v.problems) fmt::print("    {}\n", p);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  bool verify = true;
  std::vector<std::pair<std::string, double>> inputs;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--no-verify") {
      verify = false;
    } else if (i + 1 < argc) {
      inputs.emplace_back(a, std::stod(argv[++i]));
    }
  }
  if (inputs.empty()) {
    for (const char* f : {"RiggedSimple.glb", "RiggedFigure.glb", "CesiumMan.glb", "Fox.glb",
                          "simple_skin.gltf"})
      inputs.emplace_back(hc::testing::shared_data(std::string("skinned/") + f).string(), 100.0);
    const std::string models = "/usr/share/assimp/models/";
    for (const char* f : {"X/BCN_Epileptic.X", "X/Testwuson.X", "FBX/animation_with_skeleton.fbx",
                          "FBX/huesitos.fbx"})
      if (std::filesystem::exists(models + f)) inputs.emplace_back(models + f, 150.0);
  }
  int failures = 0;
  for (const auto& [file, height] : inputs) failures += run(file, height, verify);
  return failures == 0 ? 0 : 1;
}
