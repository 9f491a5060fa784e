// Scalar functions for the ATEX_HD mathematics, written once for host and
// device. Overloads on float and double call the C library names (sqrtf, expf,
// ...), which both g++ (<cmath>) and nvcc device code provide, so nothing here
// depends on std:: functions that nvcc rejects in __device__ code.
#pragma once

#include <cmath>

#include "atex/hd.h"

namespace atex::detail {

ATEX_HD float Sqrt(float x) { return sqrtf(x); }
ATEX_HD double Sqrt(double x) { return sqrt(x); }
ATEX_HD float Exp(float x) { return expf(x); }
ATEX_HD double Exp(double x) { return exp(x); }
ATEX_HD float Log(float x) { return logf(x); }
ATEX_HD double Log(double x) { return log(x); }
ATEX_HD float Tanh(float x) { return tanhf(x); }
ATEX_HD double Tanh(double x) { return tanh(x); }
ATEX_HD float Floor(float x) { return floorf(x); }
ATEX_HD double Floor(double x) { return floor(x); }
ATEX_HD float Ceil(float x) { return ceilf(x); }
ATEX_HD double Ceil(double x) { return ceil(x); }

template <typename T>
ATEX_HD T Min(T a, T b) {
  return b < a ? b : a;
}
template <typename T>
ATEX_HD T Max(T a, T b) {
  return a < b ? b : a;
}
template <typename T>
ATEX_HD T Abs(T a) {
  return a < T(0) ? -a : a;
}

// 1 / (1 + e^−x): opacity from its logit (conventions §2).
template <typename T>
ATEX_HD T Sigmoid(T x) {
  return T(1) / (T(1) + Exp(-x));
}

// False for NaN and +-Inf (x - x is NaN for both; no -ffast-math in this project).
template <typename T>
ATEX_HD bool IsFinite(T x) {
  return x - x == T(0);
}

// Clamps to [lo, hi]; NaN maps to lo, so that an index derived from the result is
// always in range.
template <typename T>
ATEX_HD T ClampNanLow(T x, T lo, T hi) {
  return x >= hi ? hi : (x > lo ? x : lo);
}

}  // namespace atex::detail
