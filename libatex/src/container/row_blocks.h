// Work on the rows of a large array in blocks, on several threads, whether or not the caller
// is already inside an OpenMP parallel region (the encoder's chunks run in one). Not part of
// the public API.
#pragma once

#include <algorithm>
#include <cstdint>
#ifdef _OPENMP
#include <omp.h>
#endif

namespace atex::container {

// Blocks of rows for work on `values` values: 1 (no threads) below a quarter million.
inline int64_t RowBlocks(uint64_t rows, uint64_t values) {
  constexpr uint64_t kParallelValues = uint64_t{1} << 18;
#ifdef _OPENMP
  if (values >= kParallelValues && rows > 1) return static_cast<int64_t>(std::min<uint64_t>(rows, 64));
#endif
  (void)values;
  return rows > 0 ? 1 : 0;
}

// Calls f(block, begin, end) for each of `blocks` blocks of [0, rows), which cover it in order,
// on several threads when there are several blocks: a parallel region of its own, or, inside
// one (the encoder's chunks run in one), tasks that the region's idle threads take. f must not
// throw.
template <typename F>
void ForRowBlocks(uint64_t rows, int64_t blocks, F&& f) {
  const auto block = [&](int64_t b) {
    f(b, rows * static_cast<uint64_t>(b) / static_cast<uint64_t>(blocks),
      rows * static_cast<uint64_t>(b + 1) / static_cast<uint64_t>(blocks));
  };
#ifdef _OPENMP
  if (blocks > 1) {
    if (omp_in_parallel()) {
#pragma omp taskloop grainsize(1)
      for (int64_t b = 0; b < blocks; ++b) block(b);
    } else {
#pragma omp parallel for schedule(static)
      for (int64_t b = 0; b < blocks; ++b) block(b);
    }
    return;
  }
#endif
  for (int64_t b = 0; b < blocks; ++b) block(b);
}

}  // namespace atex::container
