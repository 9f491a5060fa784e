// ATEX_HD marks functions shared by the CPU reference engine and the CUDA
// kernels: plain host functions for g++, __host__ __device__ under nvcc. The
// per-Gaussian and per-pixel mathematics is written once (atex/detail/*.h) and
// the two backends differ only in how they schedule it.
#pragma once

#if defined(__CUDACC__)
#define ATEX_HD __host__ __device__ __forceinline__
#else
#define ATEX_HD inline
#endif
