#include "common/openmp.h"

// The two OpenMP runtime entry points, declared here rather than through <omp.h>: clang (the
// sanitizer build) has no omp.h without libomp-dev, and we need only libgomp, the runtime CHOLMOD
// itself loads (linked explicitly in common/CMakeLists.txt).
extern "C" {
void omp_set_max_active_levels(int max_levels);
int omp_get_max_active_levels(void);
}

namespace hc {

SerialOpenMpScope::SerialOpenMpScope() : saved_levels_(omp_get_max_active_levels()) {
  omp_set_max_active_levels(0);
}

SerialOpenMpScope::~SerialOpenMpScope() { omp_set_max_active_levels(saved_levels_); }

}  // namespace hc
