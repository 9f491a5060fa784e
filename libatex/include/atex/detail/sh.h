// View-dependent colour from real spherical harmonics, 3DGS basis and constants
// (docs/conventions.md §2), and its vector-Jacobian product.
//
// Coefficients are [K][3] (coefficient-major, RGB innermost). The view direction is
// v = normalize(μ − o); the functions take the unnormalised μ − o and return its
// gradient, so the caller adds it straight to dL/dμ.
#pragma once

#include "atex/detail/math.h"
#include "atex/detail/vec.h"
#include "atex/hd.h"

namespace atex::detail {

inline constexpr double kShC0 = 0.28209479177387814;
inline constexpr double kShC1 = 0.4886025119029199;
inline constexpr double kShC2_0 = 1.0925484305920792;
inline constexpr double kShC2_1 = -1.0925484305920792;
inline constexpr double kShC2_2 = 0.31539156525252005;
inline constexpr double kShC2_3 = -1.0925484305920792;
inline constexpr double kShC2_4 = 0.5462742152960396;
inline constexpr double kShC3_0 = -0.5900435899266435;
inline constexpr double kShC3_1 = 2.890611442640554;
inline constexpr double kShC3_2 = -0.4570457994644658;
inline constexpr double kShC3_3 = 0.3731763325901154;
inline constexpr double kShC3_4 = -0.4570457994644658;
inline constexpr double kShC3_5 = 1.445305721320277;
inline constexpr double kShC3_6 = -0.5900435899266435;
inline constexpr int kMaxShCoeffs = 16;

// Y_k(v) for k < (degree+1)², v a unit vector; basis[k] for larger k is untouched.
template <typename T>
ATEX_HD void ShBasis(int degree, const Vec3<T>& v, T* basis /* [(degree+1)²] */) {
  basis[0] = T(kShC0);
  if (degree < 1) return;
  const T x = v[0], y = v[1], z = v[2];
  basis[1] = -T(kShC1) * y;
  basis[2] = T(kShC1) * z;
  basis[3] = -T(kShC1) * x;
  if (degree < 2) return;
  const T xx = x * x, yy = y * y, zz = z * z;
  basis[4] = T(kShC2_0) * x * y;
  basis[5] = T(kShC2_1) * y * z;
  basis[6] = T(kShC2_2) * (T(2) * zz - xx - yy);
  basis[7] = T(kShC2_3) * x * z;
  basis[8] = T(kShC2_4) * (xx - yy);
  if (degree < 3) return;
  basis[9] = T(kShC3_0) * y * (T(3) * xx - yy);
  basis[10] = T(kShC3_1) * x * y * z;
  basis[11] = T(kShC3_2) * y * (T(4) * zz - xx - yy);
  basis[12] = T(kShC3_3) * z * (T(2) * zz - T(3) * xx - T(3) * yy);
  basis[13] = T(kShC3_4) * x * (T(4) * zz - xx - yy);
  basis[14] = T(kShC3_5) * z * (xx - yy);
  basis[15] = T(kShC3_6) * x * (xx - T(3) * yy);
}

// ∂Y_k/∂(x, y, z) of the polynomials above (x, y, z treated as independent).
template <typename T>
ATEX_HD void ShBasisGradient(int degree, const Vec3<T>& v, Vec3<T>* d_basis /* [(degree+1)²] */) {
  d_basis[0] = {{T(0), T(0), T(0)}};
  if (degree < 1) return;
  const T x = v[0], y = v[1], z = v[2];
  const T c1 = T(kShC1);
  d_basis[1] = {{T(0), -c1, T(0)}};
  d_basis[2] = {{T(0), T(0), c1}};
  d_basis[3] = {{-c1, T(0), T(0)}};
  if (degree < 2) return;
  const T xx = x * x, yy = y * y, zz = z * z;
  d_basis[4] = {{T(kShC2_0) * y, T(kShC2_0) * x, T(0)}};
  d_basis[5] = {{T(0), T(kShC2_1) * z, T(kShC2_1) * y}};
  d_basis[6] = {{-T(2) * T(kShC2_2) * x, -T(2) * T(kShC2_2) * y, T(4) * T(kShC2_2) * z}};
  d_basis[7] = {{T(kShC2_3) * z, T(0), T(kShC2_3) * x}};
  d_basis[8] = {{T(2) * T(kShC2_4) * x, -T(2) * T(kShC2_4) * y, T(0)}};
  if (degree < 3) return;
  d_basis[9] = {{T(kShC3_0) * T(6) * x * y, T(kShC3_0) * (T(3) * xx - T(3) * yy), T(0)}};
  d_basis[10] = {{T(kShC3_1) * y * z, T(kShC3_1) * x * z, T(kShC3_1) * x * y}};
  d_basis[11] = {{-T(kShC3_2) * T(2) * x * y, T(kShC3_2) * (T(4) * zz - xx - T(3) * yy), T(kShC3_2) * T(8) * y * z}};
  d_basis[12] = {
      {-T(kShC3_3) * T(6) * x * z, -T(kShC3_3) * T(6) * y * z, T(kShC3_3) * (T(6) * zz - T(3) * xx - T(3) * yy)}};
  d_basis[13] = {{T(kShC3_4) * (T(4) * zz - T(3) * xx - yy), -T(kShC3_4) * T(2) * x * y, T(kShC3_4) * T(8) * x * z}};
  d_basis[14] = {{T(kShC3_5) * T(2) * x * z, -T(kShC3_5) * T(2) * y * z, T(kShC3_5) * (xx - yy)}};
  d_basis[15] = {{T(kShC3_6) * (T(3) * xx - T(3) * yy), -T(kShC3_6) * T(6) * x * y, T(0)}};
}

// c = max(0, Σ_k c_k Y_k(v) + 0.5) per channel over the first (degree+1)² coefficients.
// `clamped[ch]` is set where the max chose 0 (no gradient there).
// Precondition: dir = μ − o is not zero (guaranteed for Gaussians in front of the near plane).
template <typename T>
ATEX_HD Vec3<T> ShColor(int degree, const T* coeffs /* [K][3] */, const Vec3<T>& dir, bool clamped[3]) {
  const T inv_len = T(1) / Sqrt(Dot(dir, dir));
  const Vec3<T> v = inv_len * dir;
  T basis[kMaxShCoeffs];
  ShBasis(degree, v, basis);
  const int count = (degree + 1) * (degree + 1);
  Vec3<T> color{{T(0), T(0), T(0)}};
  for (int k = 0; k < count; ++k)
    for (int ch = 0; ch < 3; ++ch) color[ch] += coeffs[k * 3 + ch] * basis[k];
  for (int ch = 0; ch < 3; ++ch) {
    color[ch] += T(0.5);
    clamped[ch] = color[ch] < T(0);
    if (clamped[ch]) color[ch] = T(0);
  }
  return color;
}

// Given dL/dc, accumulates dL/dcoeffs (first (degree+1)² rows) and returns dL/d(μ − o).
template <typename T>
ATEX_HD Vec3<T> ShColorVjp(int degree, const T* coeffs /* [K][3] */, const Vec3<T>& dir, const bool clamped[3],
                           const Vec3<T>& g_color, T* g_coeffs /* [K][3], accumulated */) {
  const T inv_len = T(1) / Sqrt(Dot(dir, dir));
  const Vec3<T> v = inv_len * dir;
  Vec3<T> g{{clamped[0] ? T(0) : g_color[0], clamped[1] ? T(0) : g_color[1], clamped[2] ? T(0) : g_color[2]}};
  T basis[kMaxShCoeffs];
  ShBasis(degree, v, basis);
  const int count = (degree + 1) * (degree + 1);
  for (int k = 0; k < count; ++k)
    for (int ch = 0; ch < 3; ++ch) g_coeffs[k * 3 + ch] += g[ch] * basis[k];
  if (degree < 1) return {{T(0), T(0), T(0)}};
  Vec3<T> d_basis[kMaxShCoeffs];
  ShBasisGradient(degree, v, d_basis);
  Vec3<T> g_v{{T(0), T(0), T(0)}};
  for (int k = 1; k < count; ++k) {
    const T gk = coeffs[k * 3 + 0] * g[0] + coeffs[k * 3 + 1] * g[1] + coeffs[k * 3 + 2] * g[2];
    g_v += gk * d_basis[k];
  }
  // v = dir/|dir|: dL/ddir = (g_v − v (v·g_v)) / |dir|.
  const T along = Dot(v, g_v);
  return inv_len * (g_v - along * v);
}

}  // namespace atex::detail
