#include "processing/fem/blas_threads.h"

#include <mutex>

// OpenBLAS's two thread-count entry points, declared here rather than through its cblas.h, whose
// Debian path depends on the OpenBLAS variant installed (pthread / openmp / serial); every variant
// exports both. OpenBLAS comes with SuiteSparse::CHOLMOD (cmake/Dependencies.cmake).
extern "C" {
void openblas_set_num_threads(int num_threads);
int openblas_get_num_threads(void);
}

namespace hc::fem {
namespace {

std::mutex& scope_mutex() {
  static std::mutex m;
  return m;
}
int live_scopes = 0;    // guarded by scope_mutex()
int saved_threads = 1;  // guarded by scope_mutex()

}  // namespace

SingleThreadedBlasScope::SingleThreadedBlasScope() {
  const std::lock_guard<std::mutex> lock(scope_mutex());
  if (live_scopes++ == 0) {
    saved_threads = openblas_get_num_threads();
    if (saved_threads != 1) openblas_set_num_threads(1);
  }
}

SingleThreadedBlasScope::~SingleThreadedBlasScope() {
  const std::lock_guard<std::mutex> lock(scope_mutex());
  if (--live_scopes == 0 && saved_threads != 1) openblas_set_num_threads(saved_threads);
}

int blas_threads() { return openblas_get_num_threads(); }

}  // namespace hc::fem
