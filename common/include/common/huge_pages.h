// Transparent huge pages for large buffers. On virtual machines first-touch page faults are
// expensive (~5 µs each here): reading a 50 MB STL spent ~190 ms of 222 in them, and the default
// Hertz scene's `simulate` took 68k of them, most in its sparse factor. Where the kernel's THP mode
// is "madvise" (Debian's default) a buffer must ask for 2 MiB pages itself — glibc does so only
// when started with GLIBC_TUNABLES=glibc.malloc.hugetlb=1, which a library cannot set.
#pragma once

#include <cstddef>

namespace hc {

// Best effort: asks the kernel to back the 2 MiB-aligned interior of [p, p + bytes) with
// transparent huge pages. Ignored by kernels without THP; on memory already touched it applies to
// later faults only.
void advise_huge_pages(void* p, std::size_t bytes);

// malloc / calloc / realloc that advise huge pages for blocks of at least 4 MiB (smaller ones
// would mostly waste a huge page); free() releases them. Their signatures are SuiteSparse's
// allocator hooks.
void* malloc_huge(std::size_t bytes);
void* calloc_huge(std::size_t count, std::size_t size);
void* realloc_huge(void* p, std::size_t bytes);

}  // namespace hc
