// libFuzzer target: the skinned-character reader (Assimp and our decoder behind it) on arbitrary
// bytes. The first byte picks the format the rest is read as (glb, gltf, fbx, dae, x). Beyond the
// sanitizers it checks the reader's contract: an error is kInvalidArgument, and an accepted
// character passes validate() (weights sum to 1, indices in range, bones parents first).
// Not run by ctest (tests/CMakeLists.txt): within seconds it finds inputs on which Assimp 5.2.5
// itself allocates ~3 GB in one operator new or runs past 10 s inside BaseImporter::ReadFile, so
// a bounded CI run fails on the library, not on our decoder. Run it by hand:
//   tests/fuzz/run_fuzzer build-sanitize/bin/fuzz_skinned_reader 600 tests/fuzz/corpus/fuzz_skinned_reader ../shared/data
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "fabrication/articulation/skinned_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  static const char* const kFormats[] = {"glb", "gltf", "fbx", "dae", "x"};
  const std::string_view bytes(reinterpret_cast<const char*>(data + 1), size - 1);
  hc::articulation::SkinnedReadOptions options;
  options.max_frames_per_clip = 8;  // clip sampling is not what is fuzzed; keep runs fast
  const hc::Result<hc::articulation::SkinnedCharacter> c =
      hc::articulation::parse_skinned_character(bytes, kFormats[data[0] % 5], "fuzz", options);
  if (!c.ok()) {
    if (c.status().code() != hc::StatusCode::kInvalidArgument) std::abort();
    return 0;
  }
  if (!hc::articulation::validate(*c).ok()) std::abort();
  return 0;
}
