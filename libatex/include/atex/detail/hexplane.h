// Per-sample HexPlane mathematics shared by the CPU reference engine
// (libatex/src/deform) and the CUDA kernels: coordinate normalisation, the
// bilinear tap of one plane (PyTorch grid_sample with align_corners=True,
// padding_mode='border'), the product of the six plane samples of one scale,
// and the vector-Jacobian products of all of them (docs/conventions.md §3).
//
// Everything here is ATEX_HD, templated on the scalar type, allocation-free and
// independent of the rest of libatex (no std::vector, no Eigen), so that nvcc
// compiles it for the device unchanged. Scheduling (which thread samples what,
// how plane gradients are accumulated) is the caller's business: the functions
// that touch plane gradients take an `add(index, value)` functor, so the CPU
// engine can gather deterministically and a kernel can use atomicAdd.
#pragma once

#include "atex/hd.h"

namespace atex::detail {

inline constexpr int kHexPlanes = 6;  // xy, xz, xt, yz, yt, zt

// Coordinate index (0..3 = x, y, z, t) of the first (`which` = 0, the plane's
// width axis a) or second (`which` = 1, its height axis b) coordinate of plane
// `plane`, in itertools.combinations(range(4), 2) order. Must agree with
// atex::kHexPlaneAxes (checked by a static_assert in libatex/src/deform).
ATEX_HD constexpr int HexPlaneAxis(int plane, int which) {
  constexpr int kAxes[kHexPlanes][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
  return kAxes[plane][which];
}

// True for the three planes that involve time (xt, yt, zt).
ATEX_HD constexpr bool IsTimePlane(int plane) { return HexPlaneAxis(plane, 1) == 3; }

// Spatial normalisation x_norm = (x - lo) * scale - 1 with scale = 2 / (hi - lo),
// evaluated in this order (as 4DGaussians' normalize_aabb) so that imported
// fields reproduce PyTorch to the last bits where possible. lo > hi is allowed
// (4DGaussians stores its AABB as (max, min)); lo == hi gives an infinite
// scale, which callers reject.
template <typename T>
ATEX_HD T AabbScale(T lo, T hi) {
  return T(2) / (hi - lo);
}
template <typename T>
ATEX_HD T NormalizeCoordinate(T x, T lo, T scale) {
  return (x - lo) * scale - T(1);
}

// One axis of a bilinear tap: knots i0 <= i1 and the weight of i1.
template <typename T>
struct AxisTap {
  int i0 = 0;     // lower knot, in [0, res - 1]
  int i1 = 0;     // upper knot, min(i0 + 1, res - 1)
  T w1 = T(0);    // weight of i1 (i0 has 1 - w1), in [0, 1); 0 when clamped
  T dg_dc = T(0); // d(continuous index)/d(normalised coordinate); 0 where clamped
};

// Continuous index g = (c + 1) / 2 * (res - 1), clamped to [0, res - 1]. At and
// beyond the border the coordinate gradient is zero (PyTorch's
// clip_coordinates_set_grad treats the border itself as clamped). A NaN
// coordinate samples knot 0 with zero gradient instead of indexing garbage.
// Precondition: res >= 1.
template <typename T>
ATEX_HD AxisTap<T> MakeAxisTap(T c, int res) {
  AxisTap<T> tap;
  const T last = static_cast<T>(res - 1);
  T g = (c + T(1)) / T(2) * last;
  tap.dg_dc = last / T(2);
  if (!(g > T(0))) {  // also NaN
    g = T(0);
    tap.dg_dc = T(0);
  } else if (g >= last) {
    g = last;
    tap.dg_dc = T(0);
  }
  int i0 = static_cast<int>(g);  // g >= 0, so truncation is floor
  if (i0 > res - 1) i0 = res - 1;
  tap.i0 = i0;
  tap.i1 = i0 + 1 < res ? i0 + 1 : res - 1;
  tap.w1 = g - static_cast<T>(i0);
  return tap;
}

// Bilinear tap of one plane stored as [C][res_b][res_a].
template <typename T>
struct PlaneTap {
  AxisTap<T> a;   // width axis (plane coordinate 0)
  AxisTap<T> b;   // height axis (plane coordinate 1)
  int res_a = 1;
  int res_b = 1;

  // Offsets of the four corners within one channel ([res_b][res_a]) and their
  // weights, in the order (a0,b0), (a1,b0), (a0,b1), (a1,b1).
  ATEX_HD int corner(int k) const {
    const int ai = (k & 1) ? a.i1 : a.i0;
    const int bi = (k & 2) ? b.i1 : b.i0;
    return bi * res_a + ai;
  }
  ATEX_HD T weight(int k) const {
    const T wa = (k & 1) ? a.w1 : T(1) - a.w1;
    const T wb = (k & 2) ? b.w1 : T(1) - b.w1;
    return wa * wb;
  }
  ATEX_HD int channel_size() const { return res_a * res_b; }
};

template <typename T>
ATEX_HD PlaneTap<T> MakePlaneTap(T ca, T cb, int res_a, int res_b) {
  PlaneTap<T> tap;
  tap.a = MakeAxisTap(ca, res_a);
  tap.b = MakeAxisTap(cb, res_b);
  tap.res_a = res_a;
  tap.res_b = res_b;
  return tap;
}

// Value of one channel ([res_b][res_a]) at the tap.
template <typename T>
ATEX_HD T SampleChannel(const T* channel, const PlaneTap<T>& tap) {
  T value = T(0);
  for (int k = 0; k < 4; ++k) value += tap.weight(k) * channel[tap.corner(k)];
  return value;
}

// out[c] = plane channel c at the tap, for c < channels. plane: [C][res_b][res_a].
template <typename T>
ATEX_HD void SamplePlane(const T* plane, int channels, const PlaneTap<T>& tap, T* out) {
  const int stride = tap.channel_size();
  for (int c = 0; c < channels; ++c) out[c] = SampleChannel(plane + static_cast<long long>(c) * stride, tap);
}

// Gradient of one channel's sample with respect to the plane coordinates
// (ca, cb), scaled by the upstream gradient `grad`; added to *grad_ca, *grad_cb.
template <typename T>
ATEX_HD void SampleChannelCoordVjp(const T* channel, const PlaneTap<T>& tap, T grad, T* grad_ca, T* grad_cb) {
  const T v00 = channel[tap.corner(0)];
  const T v10 = channel[tap.corner(1)];
  const T v01 = channel[tap.corner(2)];
  const T v11 = channel[tap.corner(3)];
  const T wa = tap.a.w1;
  const T wb = tap.b.w1;
  // d value / d g_a and d value / d g_b of the bilinear form.
  const T dga = (T(1) - wb) * (v10 - v00) + wb * (v11 - v01);
  const T dgb = (T(1) - wa) * (v01 - v00) + wa * (v11 - v10);
  *grad_ca += grad * dga * tap.a.dg_dc;
  *grad_cb += grad * dgb * tap.b.dg_dc;
}

// Vector-Jacobian product of SamplePlane: grad_out[C] is dL/d(out). Adds
// dL/d(plane coordinates) to *grad_ca, *grad_cb and, through
// add_to_plane(index into [C][res_b][res_a], value), dL/d(plane). Pass a
// no-op functor to skip plane gradients.
template <typename T, typename AddToPlane>
ATEX_HD void SamplePlaneVjp(const T* plane, int channels, const PlaneTap<T>& tap, const T* grad_out,
                            AddToPlane&& add_to_plane, T* grad_ca, T* grad_cb) {
  const int stride = tap.channel_size();
  for (int c = 0; c < channels; ++c) {
    const long long base = static_cast<long long>(c) * stride;
    SampleChannelCoordVjp(plane + base, tap, grad_out[c], grad_ca, grad_cb);
    for (int k = 0; k < 4; ++k) add_to_plane(base + tap.corner(k), tap.weight(k) * grad_out[c]);
  }
}

// The six planes of one scale. planes[p]: [C][res_b][res_a] with (a, b) =
// (HexPlaneAxis(p, 0), HexPlaneAxis(p, 1)); resolution[axis] for x, y, z, t.
template <typename T>
struct HexPlaneScale {
  const T* planes[kHexPlanes] = {};
  int resolution[4] = {1, 1, 1, 1};
  int channels = 0;

  ATEX_HD int res_a(int p) const { return resolution[HexPlaneAxis(p, 0)]; }
  ATEX_HD int res_b(int p) const { return resolution[HexPlaneAxis(p, 1)]; }
  ATEX_HD PlaneTap<T> tap(int p, const T* coord) const {
    return MakePlaneTap(coord[HexPlaneAxis(p, 0)], coord[HexPlaneAxis(p, 1)], res_a(p), res_b(p));
  }
};

// Samples the six planes of a scale at the normalised coordinate coord[4]
// (x, y, z, t) and multiplies them channel-wise: feature[c] = prod_p samples[p][c].
// samples: [6][C] (kept for the backward pass); feature: [C].
template <typename T>
ATEX_HD void SampleHexPlaneScale(const HexPlaneScale<T>& scale, const T* coord, T* samples, T* feature) {
  const int channels = scale.channels;
  for (int c = 0; c < channels; ++c) feature[c] = T(1);
  for (int p = 0; p < kHexPlanes; ++p) {
    T* row = samples + p * channels;
    SamplePlane(scale.planes[p], channels, scale.tap(p, coord), row);
    for (int c = 0; c < channels; ++c) feature[c] *= row[c];
  }
}

// dL/d(sample p, channel c) = dL/d(feature c) * product of the other five
// samples, computed without division (samples may be zero).
// samples, grad_samples: [6][C]; grad_feature: [C].
template <typename T>
ATEX_HD void HexPlaneProductVjp(const T* samples, int channels, const T* grad_feature, T* grad_samples) {
  for (int c = 0; c < channels; ++c) {
    T prefix[kHexPlanes];  // prefix[p] = prod_{q < p} samples[q][c]
    T running = T(1);
    for (int p = 0; p < kHexPlanes; ++p) {
      prefix[p] = running;
      running *= samples[p * channels + c];
    }
    T suffix = T(1);  // prod_{q > p} samples[q][c]
    for (int p = kHexPlanes - 1; p >= 0; --p) {
      grad_samples[p * channels + c] = grad_feature[c] * prefix[p] * suffix;
      suffix *= samples[p * channels + c];
    }
  }
}

// Adds dL/d(coord) (4 values, x y z t) of one scale given grad_samples[6][C]
// (from HexPlaneProductVjp). Plane gradients are NOT touched (see
// SamplePlaneVjp / the caller's gather).
template <typename T>
ATEX_HD void HexPlaneCoordVjp(const HexPlaneScale<T>& scale, const T* coord, const T* grad_samples, T* grad_coord) {
  const int channels = scale.channels;
  for (int p = 0; p < kHexPlanes; ++p) {
    const PlaneTap<T> tap = scale.tap(p, coord);
    const int stride = tap.channel_size();
    T ga = T(0), gb = T(0);
    for (int c = 0; c < channels; ++c) {
      SampleChannelCoordVjp(scale.planes[p] + static_cast<long long>(c) * stride, tap, grad_samples[p * channels + c],
                            &ga, &gb);
    }
    grad_coord[HexPlaneAxis(p, 0)] += ga;
    grad_coord[HexPlaneAxis(p, 1)] += gb;
  }
}

}  // namespace atex::detail
