#include "common/file_io.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <mutex>
#include <random>
#include <set>

#include "common/huge_pages.h"

namespace hc {
namespace {

std::string errno_text() { return std::strerror(errno); }

class Fd {
 public:
  explicit Fd(int fd) : fd_(fd) {}
  ~Fd() {
    if (fd_ >= 0) ::close(fd_);
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int get() const { return fd_; }
  int release() { return std::exchange(fd_, -1); }

 private:
  int fd_;
};

// "….tmp-PID-XXXXXXXX[.ext]": the process id, or 0 when `name` is not such a temporary.
long temporary_owner(const std::string& name) {
  const std::size_t at = name.rfind(".tmp-");
  if (at == std::string::npos || at == 0) return 0;
  std::size_t i = at + 5;
  long pid = 0;
  std::size_t digits = 0;
  for (; i < name.size() && name[i] >= '0' && name[i] <= '9' && digits < 10; ++i, ++digits)
    pid = pid * 10 + (name[i] - '0');
  if (digits == 0 || i >= name.size() || name[i] != '-') return 0;
  std::size_t hex = 0;
  for (++i; i < name.size() && std::isxdigit(static_cast<unsigned char>(name[i])); ++i) ++hex;
  if (hex != 8 || (i < name.size() && name[i] != '.')) return 0;
  return pid;
}

bool process_alive(long pid) { return ::kill(static_cast<pid_t>(pid), 0) == 0 || errno == EPERM; }

}  // namespace

std::filesystem::path temp_path_for(const std::filesystem::path& path) {
  std::random_device rd;
  return path.string() + fmt::format(".tmp-{}-{:08x}", ::getpid(), rd());
}

std::size_t remove_stale_temporaries(const std::filesystem::path& dir) {
  static std::mutex mutex;
  static std::set<std::string> done;
  std::error_code ec;
  const std::filesystem::path d = dir.empty() ? std::filesystem::path(".") : dir;
  {
    std::lock_guard lock(mutex);
    if (!done.insert(std::filesystem::absolute(d, ec).lexically_normal().string()).second) return 0;
  }
  std::size_t removed = 0;
  for (std::filesystem::directory_iterator it(d, ec), end; !ec && it != end; it.increment(ec)) {
    const long pid = temporary_owner(it->path().filename().string());
    if (pid <= 0 || pid == ::getpid() || process_alive(pid)) continue;
    std::error_code rm;
    if (std::filesystem::remove_all(it->path(), rm) > 0 && !rm) ++removed;
  }
  return removed;
}

AtomicFileGroup::AtomicFileGroup(std::filesystem::path base, std::vector<std::string> extensions)
    : base_(std::move(base)), staged_(temp_path_for(base_)), extensions_(std::move(extensions)) {
  remove_stale_temporaries(base_.parent_path());
}

AtomicFileGroup::~AtomicFileGroup() {
  if (committed_) return;
  for (std::size_t i = 0; i < extensions_.size(); ++i) ::unlink(staged(i).c_str());
}

std::filesystem::path AtomicFileGroup::staged(std::size_t i) const {
  return staged_.string() + extensions_.at(i);
}

std::filesystem::path AtomicFileGroup::final_path(std::size_t i) const {
  return base_.string() + extensions_.at(i);
}

Status AtomicFileGroup::commit() {
  for (std::size_t i = 0; i < extensions_.size(); ++i) {
    Fd fd(::open(staged(i).c_str(), O_RDONLY | O_CLOEXEC));
    if (fd.get() < 0 || ::fsync(fd.get()) != 0)
      return io_error(fmt::format("{}: cannot sync: {}", staged(i).string(), errno_text()));
  }
  for (std::size_t i = 0; i < extensions_.size(); ++i) {
    if (::rename(staged(i).c_str(), final_path(i).c_str()) != 0) {
      const std::string why = errno_text();
      // Take back the ones already in place: the set is whole or absent.
      for (std::size_t k = 0; k < i; ++k) ::unlink(final_path(k).c_str());
      return io_error(fmt::format("{}: cannot rename into place: {}", final_path(i).string(), why));
    }
  }
  committed_ = true;
  return {};
}

Result<std::string> read_file(const std::filesystem::path& path, std::size_t max_bytes) {
  Fd fd(::open(path.c_str(), O_RDONLY | O_CLOEXEC));
  if (fd.get() < 0) {
    if (errno == ENOENT) return not_found(fmt::format("{}: no such file", path.string()));
    return io_error(fmt::format("{}: cannot open: {}", path.string(), errno_text()));
  }
  struct stat st {};
  if (::fstat(fd.get(), &st) != 0)
    return io_error(fmt::format("{}: cannot stat: {}", path.string(), errno_text()));
  if (S_ISDIR(st.st_mode))
    return invalid_argument(fmt::format("{}: is a directory", path.string()));
  const auto size = static_cast<std::size_t>(st.st_size);
  if (size > max_bytes)
    return invalid_argument(fmt::format("{}: file is {} bytes, more than the limit of {}",
                                        path.string(), size, max_bytes));
  std::string data;
  data.reserve(size);
  advise_huge_pages(data.data(), size);
  data.resize(size);
  std::size_t got = 0;
  while (got < size) {
    const ssize_t n = ::read(fd.get(), data.data() + got, size - got);
    if (n < 0) {
      if (errno == EINTR) continue;
      return io_error(fmt::format("{}: read failed: {}", path.string(), errno_text()));
    }
    if (n == 0) break;  // file shrank while we read it
    got += static_cast<std::size_t>(n);
  }
  data.resize(got);
  // Non-regular files (pipes, /dev/stdin) report size 0: read them to the end.
  if (!S_ISREG(st.st_mode)) {
    char buf[1 << 16];
    for (;;) {
      const ssize_t n = ::read(fd.get(), buf, sizeof buf);
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) return io_error(fmt::format("{}: read failed: {}", path.string(), errno_text()));
      if (n == 0) break;
      if (data.size() + static_cast<std::size_t>(n) > max_bytes)
        return invalid_argument(fmt::format("{}: more than {} bytes", path.string(), max_bytes));
      data.append(buf, static_cast<std::size_t>(n));
    }
  }
  return data;
}

Status write_file_atomic(const std::filesystem::path& path,
                         const std::function<Status(const std::filesystem::path& tmp)>& produce) {
  remove_stale_temporaries(path.parent_path());
  const auto tmp = temp_path_for(path);
  Status s = produce(tmp);
  if (s.ok()) {
    // Flush the data to disk before the rename makes it visible under the final name.
    Fd fd(::open(tmp.c_str(), O_RDONLY | O_CLOEXEC));
    if (fd.get() < 0 || ::fsync(fd.get()) != 0)
      s = io_error(fmt::format("{}: cannot sync: {}", tmp.string(), errno_text()));
  }
  if (s.ok() && ::rename(tmp.c_str(), path.c_str()) != 0)
    s = io_error(fmt::format("{}: cannot rename into place: {}", path.string(), errno_text()));
  if (!s.ok()) ::unlink(tmp.c_str());
  return s;
}

Status write_file_atomic(const std::filesystem::path& path, std::string_view bytes) {
  return write_file_atomic(path, [&](const std::filesystem::path& tmp) -> Status {
    Fd fd(::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644));
    if (fd.get() < 0)
      return io_error(fmt::format("{}: cannot create: {}", path.string(), errno_text()));
    std::size_t done = 0;
    while (done < bytes.size()) {
      const ssize_t n = ::write(fd.get(), bytes.data() + done, bytes.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) return io_error(fmt::format("{}: write failed: {}", path.string(), errno_text()));
      done += static_cast<std::size_t>(n);
    }
    if (::close(fd.release()) != 0)
      return io_error(fmt::format("{}: close failed: {}", path.string(), errno_text()));
    return {};
  });
}

}  // namespace hc
