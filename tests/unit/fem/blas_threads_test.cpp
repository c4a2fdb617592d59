// SingleThreadedBlasScope (processing/fem/blas_threads.h): OpenBLAS runs single-threaded while any
// scope lives, on any thread, and gets its previous thread count back when the last one ends.
#include "processing/fem/blas_threads.h"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>

extern "C" void openblas_set_num_threads(int num_threads);  // OpenBLAS, linked with hardcopy_fem

namespace hc::fem {
namespace {

TEST(SingleThreadedBlasScope, NestsAcrossThreadsAndRestores) {
  openblas_set_num_threads(2);  // what a 2-core machine starts with
  ASSERT_EQ(blas_threads(), 2);
  {
    const SingleThreadedBlasScope outer;
    EXPECT_EQ(blas_threads(), 1);
    {
      const SingleThreadedBlasScope inner;
      EXPECT_EQ(blas_threads(), 1);
    }
    EXPECT_EQ(blas_threads(), 1);  // the outer scope still lives
    // A scope on another thread that ends first leaves the count at 1.
    std::atomic<int> seen{0};
    std::thread other([&seen] {
      const SingleThreadedBlasScope s;
      seen = blas_threads();
    });
    other.join();
    EXPECT_EQ(seen.load(), 1);
    EXPECT_EQ(blas_threads(), 1);
  }
  EXPECT_EQ(blas_threads(), 2);
  // The scope outliving the one that started first restores too.
  auto* first = new SingleThreadedBlasScope;
  std::atomic<bool> started{false}, release{false};
  std::thread second([&] {
    const SingleThreadedBlasScope s;
    started = true;
    while (!release) std::this_thread::yield();
  });
  while (!started) std::this_thread::yield();
  delete first;
  EXPECT_EQ(blas_threads(), 1);
  release = true;
  second.join();
  EXPECT_EQ(blas_threads(), 2);
}

}  // namespace
}  // namespace hc::fem
