// Paths for tests: the shared third-party corpus (../shared/data), the build's bin/ and a scratch
// directory that is removed when the test ends.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <span>
#include <string>
#include <vector>

namespace hc::testing {

inline std::filesystem::path shared_data() { return HARDCOPY_SHARED_DATA; }
inline std::filesystem::path shared_data(const std::string& rel) { return shared_data() / rel; }
inline std::filesystem::path bin_dir() { return HARDCOPY_BIN_DIR; }
inline std::filesystem::path source_dir() { return HARDCOPY_SOURCE_DIR; }
// One of the daemon's example rigs and plans (rig_daemon/examples/).
inline std::filesystem::path rig_example(const std::string& name) {
  return source_dir() / "rig_daemon/examples" / name;
}

// Every file in ../shared/data/meshes (the corpus for property tests), sorted by name.
inline std::vector<std::filesystem::path> corpus_meshes() {
  std::vector<std::filesystem::path> out;
  for (const auto& e : std::filesystem::directory_iterator(shared_data("meshes")))
    if (e.is_regular_file()) out.push_back(e.path());
  std::sort(out.begin(), out.end());
  return out;
}

// A fresh directory under the system temp dir, deleted with everything in it on destruction.
class ScratchDir {
 public:
  ScratchDir() {
    std::random_device rd;
    path_ = std::filesystem::temp_directory_path() /
            ("hardcopy-test-" + std::to_string(rd()) + "-" + std::to_string(rd()));
    std::filesystem::create_directories(path_);
  }
  ~ScratchDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

// A whole file's bytes (empty when it cannot be read), and bytes written to a file.
inline std::vector<std::uint8_t> read_bytes(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}
inline void write_bytes(const std::filesystem::path& p, std::span<const std::uint8_t> b) {
  std::ofstream out(p, std::ios::binary);
  out.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
}

}  // namespace hc::testing
