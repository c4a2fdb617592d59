// Single-threaded OpenBLAS while a scope lives (process-wide).
//
// The material fit and evaluation (processing/material) factorise one stiffness matrix per
// example on every core at once (TBB). OpenBLAS's own worker threads then oversubscribe the cores,
// and its idle workers spin in sched_yield against the busy ones: perf on bench_material_fit
// (1,800 tets, 48 examples) showed ~26 % of all samples in sched_yield and exec_blas_async, and
// the evaluation took 71 s against 11.7 s with OPENBLAS_NUM_THREADS=1. Work that is parallel over
// many independent factorisations runs inside a SingleThreadedBlasScope. So do every solve with a
// sparse factor and the factorisations of factors below 3e7 entries (sparse_cholesky.cpp): their
// many small BLAS calls each wait for OpenBLAS's worker, which another busy process keeps off the
// core. The default Hertz scene's `simulate` with two other processes spinning on this 2-core
// machine: 66-98 s with OpenBLAS's threads, 3.0-4.1 s without (idle: 2.43 s against 2.57 s, mean
// of 5 each). One large factorisation (a 100k-tet step, 3.2e7 entries) keeps the threads.
//
// OpenBLAS's thread count is a process-wide setting (openblas_set_num_threads), so the scope is
// too: the first live scope sets it to 1 and the last one to end restores the previous count.
// Scopes nest and may live on several threads at once.
#pragma once

namespace hc::fem {

class SingleThreadedBlasScope {
 public:
  SingleThreadedBlasScope();
  ~SingleThreadedBlasScope();
  SingleThreadedBlasScope(const SingleThreadedBlasScope&) = delete;
  SingleThreadedBlasScope& operator=(const SingleThreadedBlasScope&) = delete;
};

// OpenBLAS's current thread count (for tests).
int blas_threads();

}  // namespace hc::fem
