// Serial OpenMP regions for the calling thread, while a scope lives.
//
// Debian's CHOLMOD (SuiteSparse 5.12) runs parts of its supernodal numeric factorisation on an
// OpenMP team of a size fixed at its build (a num_threads clause: OMP_NUM_THREADS does not change
// it). On this project's 2-vCPU machines those threads spin, yield and futex-wait against each
// other: a 10k-tet stiffness factorisation took ~2x as long as the same factorisation run serially
// (tests/bench/bench_fem_step, 100k context switches per second). Everything that calls CHOLMOD —
// our SparseCholesky and Ceres' sparse solvers — does so inside a SerialOpenMpScope.
//
// Mechanism: OpenMP's max-active-levels ICV is per thread (data environment); with it at 0 every
// parallel region the thread starts runs with a team of one. The previous value is restored on
// exit, so the scope nests and leaves other threads alone.
#pragma once

namespace hc {

class SerialOpenMpScope {
 public:
  SerialOpenMpScope();
  ~SerialOpenMpScope();
  SerialOpenMpScope(const SerialOpenMpScope&) = delete;
  SerialOpenMpScope& operator=(const SerialOpenMpScope&) = delete;

 private:
  int saved_levels_;
};

}  // namespace hc
