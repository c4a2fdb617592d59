// Reading skinned characters through Assimp 5.2.5 (Debian libassimp-dev): glTF 2.0 (.gltf,
// .glb), FBX, COLLADA (.dae) and DirectX (.x). Meshes, skins, the bone tree and the animation
// clips become one SkinnedCharacter in metres, scaled to a target height.
//
// Assimp 5.2.5's traps, and what this reader does about them:
//  * aiScene::mSkeletons crashes on some FBX files: never read; bones come from aiMesh::mBones
//    and the node tree.
//  * FBX pivots become "$AssimpFbx$" helper nodes between a bone and its parent: they are
//    collapsed on import (AI_CONFIG_IMPORT_FBX_PRESERVE_PIVOTS off) and skipped when looking for a
//    bone's parent bone if any remain.
//  * A bone split across meshes appears once per mesh with its own offset matrix: bones are
//    merged by node, each influence keeps its own mesh's bind position.
//  * Weights rarely sum to 1 in real files (0.19 to 1.38 seen): they are renormalised and the
//    report says how many.
// Every malformed input is a kInvalidArgument naming the file: Assimp's own error, no mesh, no
// skin, weights all zero, an index or a number out of range, a bone cycle.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string_view>

#include "common/status.h"
#include "fabrication/articulation/skinned_character.h"

namespace hc::articulation {

struct SkinnedReadOptions {
  // Rest-pose extent along +Y the model is scaled to, in metres (> 0); 0 keeps the file's units
  // (taken as metres).
  double target_height_m = 0.0;
  bool read_animations = true;
  // Frames per second clips are sampled at (each clip also gets its first and last key).
  double sample_rate_hz = 30.0;
  int max_frames_per_clip = 240;
  // Files larger than this are refused before Assimp sees them.
  std::uintmax_t max_file_bytes = std::uintmax_t{256} << 20;

  Status validate() const;
};

// Reads a character from a file (format from the extension and content).
Result<SkinnedCharacter> read_skinned_character(const std::filesystem::path& path,
                                                const SkinnedReadOptions& options = {});

// Reads a character held in memory; `extension_hint` is e.g. "glb" or "fbx", `name` names it in
// messages. Formats whose files reference others (.gltf with external buffers) need the path form.
Result<SkinnedCharacter> parse_skinned_character(std::string_view bytes,
                                                 std::string_view extension_hint,
                                                 std::string_view name,
                                                 const SkinnedReadOptions& options = {});

// Writes `character` through Assimp's exporter, bound at its rest pose (vertices in file units,
// each bone's offset matrix the inverse of its rest global), with its clips as node animations.
// The format comes from the extension: .glb, .gltf, .fbx (ASCII) or .dae (Assimp's DirectX writer
// drops skins). For making test files in the input formats from synthetic rigs; reading the
// result back gives the character again. Not atomic; tests write to temp folders.
Status write_skinned_character(const std::filesystem::path& path,
                               const SkinnedCharacter& character);

}  // namespace hc::articulation
