// Where McapReader's bytes come from (a file read with pread(2), or memory) and the linear scan
// over them, shared by the reader's fallback and scan_records (mcap_reader.cpp, mcap_source.cpp).
// Not a public header: the public interface is mcap_reader.h.
#pragma once

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>

#include <fmt/format.h>

#include "rig_daemon/recording/mcap_reader.h"

namespace hc::recording {

// Where the bytes come from: a file (pread) or memory.
class Source {
 public:
  virtual ~Source() = default;
  virtual std::uint64_t size() const = 0;
  // Reads exactly n bytes at `offset` into `out` (resized). The caller checked the range.
  virtual Status read(std::uint64_t offset, std::uint64_t n, Bytes& out) const = 0;
  virtual const std::string& name() const = 0;
};

class FileSource final : public Source {
 public:
  static Result<std::unique_ptr<FileSource>> open(const std::filesystem::path& path) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0)
      return (errno == ENOENT ? not_found(fmt::format("{}: no such file", path.string()))
                              : io_error(fmt::format("{}: cannot open: {}", path.string(),
                                                     std::strerror(errno))));
    struct stat st {};
    if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
      ::close(fd);
      return invalid_argument(fmt::format("{}: not a regular file", path.string()));
    }
    auto s =
        std::unique_ptr<FileSource>(new FileSource(fd, static_cast<std::uint64_t>(st.st_size)));
    s->name_ = path.string();
    return s;
  }
  ~FileSource() override { ::close(fd_); }
  std::uint64_t size() const override { return size_; }
  const std::string& name() const override { return name_; }
  Status read(std::uint64_t offset, std::uint64_t n, Bytes& out) const override {
    out.resize(static_cast<std::size_t>(n));
    std::uint64_t done = 0;
    while (done < n) {
      const ssize_t r = ::pread(fd_, out.data() + done, static_cast<std::size_t>(n - done),
                                static_cast<off_t>(offset + done));
      if (r < 0) {
        if (errno == EINTR) continue;
        return io_error(
            fmt::format("{}: read at offset {}: {}", name_, offset + done, std::strerror(errno)));
      }
      if (r == 0)
        return io_error(
            fmt::format("{}: unexpected end of file at offset {}", name_, offset + done));
      done += static_cast<std::uint64_t>(r);
    }
    return {};
  }

 private:
  FileSource(int fd, std::uint64_t size) : fd_(fd), size_(size) {}
  int fd_;
  std::uint64_t size_;
  std::string name_;
};

class MemorySource final : public Source {
 public:
  explicit MemorySource(ByteSpan bytes) : bytes_(bytes.begin(), bytes.end()) {}
  std::uint64_t size() const override { return bytes_.size(); }
  const std::string& name() const override { return name_; }
  Status read(std::uint64_t offset, std::uint64_t n, Bytes& out) const override {
    if (offset > bytes_.size() || n > bytes_.size() - offset)
      return internal_error("MemorySource: read out of range");
    out.assign(bytes_.begin() + static_cast<std::ptrdiff_t>(offset),
               bytes_.begin() + static_cast<std::ptrdiff_t>(offset + n));
    return {};
  }

 private:
  Bytes bytes_;
  std::string name_ = "<memory>";
};

inline std::uint64_t read_u64(const std::uint8_t* p) {
  std::uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}

inline bool is_magic(ByteSpan b) {
  return b.size() >= kMagic.size() && std::equal(kMagic.begin(), kMagic.end(), b.begin());
}

inline Status at_offset(const Source& src, std::uint64_t offset, const Status& s) {
  return Status(s.code(), fmt::format("{}: offset {}: {}", src.name(), offset, s.message()));
}

// Linear scan over a Source (shared by scan_records and the reader's fallback).
Result<LinearScanResult> scan_source(const Source& src,
                                     const std::function<Status(const LinearRecord&)>& on_record,
                                     std::uint64_t max_record_size);

}  // namespace hc::recording
