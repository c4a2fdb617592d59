// Whole-file reads with a size guard, and atomic writes (temp file + rename) so that a failed or
// interrupted write never leaves a half-written file behind.
#pragma once

#include <cstddef>
#include <filesystem>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "common/status.h"

namespace hc {

inline constexpr std::size_t kDefaultMaxFileBytes = std::size_t{8} << 30;  // 8 GiB

// Reads the whole file into memory. Fails with kNotFound, kIoError, or kInvalidArgument when the
// file is larger than max_bytes.
Result<std::string> read_file(const std::filesystem::path& path,
                              std::size_t max_bytes = kDefaultMaxFileBytes);

// Writes `bytes` to `path` atomically: into "path.tmp-PID-XXXXXXXX" in the same directory, fsync,
// rename. Temporaries that a killed process left there (remove_stale_temporaries) go first.
Status write_file_atomic(const std::filesystem::path& path, std::string_view bytes);

// As above, but `produce` streams into the open temporary file (for outputs too big to buffer, or
// produced by a library that wants a path). On any failure the temporary is removed.
Status write_file_atomic(const std::filesystem::path& path,
                         const std::function<Status(const std::filesystem::path& tmp)>& produce);

// A fresh temporary name next to `path`: "path.tmp-PID-XXXXXXXX" (the writer's process id, so
// that a later run can tell a dead writer's leftovers from a live one's work in progress).
std::filesystem::path temp_path_for(const std::filesystem::path& path);

// Removes, once per process and directory, the temporaries (files or folders named
// "NAME.tmp-PID-XXXXXXXX", with any extension after it) that processes no longer running left in
// `dir` (kill -9, power loss). Returns how many were removed.
std::size_t remove_stale_temporaries(const std::filesystem::path& dir);

// Several output files that appear together or not at all, e.g. BASE.node, BASE.ele and BASE.vtu:
// each is written as staged_base() + its extension, and commit() renames them all into place
// (after fsync) in the order given. Without commit() (a failure, an early return) the destructor
// removes what was staged. Between the renames a crash can still leave part of the set: the window
// is a few rename(2) calls long, not the minutes of writing.
class AtomicFileGroup {
 public:
  AtomicFileGroup(std::filesystem::path base, std::vector<std::string> extensions);
  ~AtomicFileGroup();
  AtomicFileGroup(const AtomicFileGroup&) = delete;
  AtomicFileGroup& operator=(const AtomicFileGroup&) = delete;
  const std::filesystem::path& staged_base() const { return staged_; }
  std::filesystem::path staged(std::size_t i) const;
  std::filesystem::path final_path(std::size_t i) const;
  Status commit();

 private:
  std::filesystem::path base_;
  std::filesystem::path staged_;
  std::vector<std::string> extensions_;
  bool committed_ = false;
};

}  // namespace hc
