// OpenMP helpers: the rasteriser is correct (and bit-identical) without OpenMP.
#pragma once

#ifdef _OPENMP
#include <omp.h>
#endif

namespace atex::render_internal {

// Below these sizes a parallel region costs more than it saves (tiny test images).
inline constexpr long long kMinParallelGaussians = 2048;
inline constexpr int kMinParallelTiles = 8;

inline int MaxThreads() {
#ifdef _OPENMP
  return omp_get_max_threads();
#else
  return 1;
#endif
}

inline int ThreadIndex() {
#ifdef _OPENMP
  return omp_get_thread_num();
#else
  return 0;
#endif
}

}  // namespace atex::render_internal
