// Rotation from an unnormalised quaternion (docs/conventions.md §2) and its
// vector-Jacobian product.
#pragma once

#include "atex/detail/math.h"
#include "atex/detail/vec.h"
#include "atex/hd.h"

namespace atex::detail {

// q = (w, x, y, z), any non-zero length; q̂ = q/‖q‖ and R(q̂) as in conventions §2.
// Column k of the result is local axis k in world coordinates.
// Precondition: ‖q‖ > 0 (the renderer validates its input).
template <typename T>
ATEX_HD Mat3<T> QuaternionToRotation(const Vec4<T>& q) {
  const T inv_norm = T(1) / Sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  const T w = q[0] * inv_norm, x = q[1] * inv_norm, y = q[2] * inv_norm, z = q[3] * inv_norm;
  Mat3<T> r;
  r(0, 0) = T(1) - T(2) * (y * y + z * z);
  r(0, 1) = T(2) * (x * y - w * z);
  r(0, 2) = T(2) * (x * z + w * y);
  r(1, 0) = T(2) * (x * y + w * z);
  r(1, 1) = T(1) - T(2) * (x * x + z * z);
  r(1, 2) = T(2) * (y * z - w * x);
  r(2, 0) = T(2) * (x * z - w * y);
  r(2, 1) = T(2) * (y * z + w * x);
  r(2, 2) = T(1) - T(2) * (x * x + y * y);
  return r;
}

// Given g_r = dL/dR (all nine entries), returns dL/dq for the UNnormalised q:
// first dL/dq̂ from the polynomial above, then through q̂ = q/‖q‖:
// dL/dq = (dL/dq̂ − q̂ (q̂·dL/dq̂)) / ‖q‖.
template <typename T>
ATEX_HD Vec4<T> QuaternionToRotationVjp(const Vec4<T>& q, const Mat3<T>& g_r) {
  const T norm = Sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  const T inv_norm = T(1) / norm;
  const T w = q[0] * inv_norm, x = q[1] * inv_norm, y = q[2] * inv_norm, z = q[3] * inv_norm;
  const Mat3<T>& g = g_r;
  Vec4<T> gh;  // dL/dq̂
  gh[0] = T(2) * (-z * g(0, 1) + y * g(0, 2) + z * g(1, 0) - x * g(1, 2) - y * g(2, 0) + x * g(2, 1));
  gh[1] = T(2) * (y * g(0, 1) + z * g(0, 2) + y * g(1, 0) - T(2) * x * g(1, 1) - w * g(1, 2) + z * g(2, 0) +
                  w * g(2, 1) - T(2) * x * g(2, 2));
  gh[2] = T(2) * (-T(2) * y * g(0, 0) + x * g(0, 1) + w * g(0, 2) + x * g(1, 0) + z * g(1, 2) - w * g(2, 0) +
                  z * g(2, 1) - T(2) * y * g(2, 2));
  gh[3] = T(2) * (-T(2) * z * g(0, 0) - w * g(0, 1) + x * g(0, 2) + w * g(1, 0) - T(2) * z * g(1, 1) +
                  y * g(1, 2) + x * g(2, 0) + y * g(2, 1));
  const T along = w * gh[0] + x * gh[1] + y * gh[2] + z * gh[3];
  return {{(gh[0] - w * along) * inv_norm, (gh[1] - x * along) * inv_norm, (gh[2] - y * along) * inv_norm,
           (gh[3] - z * along) * inv_norm}};
}

}  // namespace atex::detail
