#include "common/huge_pages.h"

#include <sys/mman.h>

#include <cstdint>
#include <cstdlib>

namespace hc {
namespace {

constexpr std::size_t kAdviseFrom = std::size_t{4} << 20;

void advise_large(void* p, std::size_t bytes) {
  if (bytes >= kAdviseFrom) advise_huge_pages(p, bytes);
}

}  // namespace

void advise_huge_pages(void* p, std::size_t bytes) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  if (p == nullptr) return;
  constexpr std::uintptr_t kHugePage = std::uintptr_t{2} << 20;
  const auto begin = reinterpret_cast<std::uintptr_t>(p);
  const std::uintptr_t first = (begin + kHugePage - 1) & ~(kHugePage - 1);
  const std::uintptr_t last = (begin + bytes) & ~(kHugePage - 1);
  if (last > first) ::madvise(reinterpret_cast<void*>(first), last - first, MADV_HUGEPAGE);
#else
  (void)p;
  (void)bytes;
#endif
}

void* malloc_huge(std::size_t bytes) {
  void* p = std::malloc(bytes);
  advise_large(p, bytes);
  return p;
}

void* calloc_huge(std::size_t count, std::size_t size) {
  // A large calloc is a fresh mapping the kernel zeroes on first touch, so the advice still comes
  // before it.
  void* p = std::calloc(count, size);
  if (count != 0 && size <= SIZE_MAX / count) advise_large(p, count * size);
  return p;
}

void* realloc_huge(void* p, std::size_t bytes) {
  void* q = std::realloc(p, bytes);
  advise_large(q, bytes);
  return q;
}

}  // namespace hc
