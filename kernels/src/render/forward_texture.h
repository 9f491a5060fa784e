// The forward rasteriser's texture sample: the textured branch of detail::EvaluateSplat
// (ComputeTexCoord, MakeBilinearTaps, SampleTexels and the activations of
// atex/detail/texture.h) rearranged so that a pixel does as little as possible per
// Gaussian. The textured kernel is bound by instruction issue in this branch, not by
// memory (Nsight Compute, BENCHMARKS.md), so everything that depends only on the splat
// and the view moves to the batch load, once per splat and tile instead of once per
// splat and pixel:
//   - the plane's axes are rotated into the camera frame and divided by the scales, so
//     that a pixel's three dot products use its normalised image coordinates
//     c = ((px − cx)/fx, (py − cy)/fy, 1) (two FMAs each) instead of the world ray Wᵀc;
//   - the texel grid's half sizes, last tap origins and strides are stored as numbers,
//     so that the taps need no integer-to-float conversions or index clamps;
//   - a 1×1 texture keeps its four activations (it is the same texel at every pixel).
// Same mathematics as the reference up to float rounding (λ uses the fast division, the
// activations the hardware tanh and exponential);
// the render parity tests compare the CUDA forward against the CPU engine in double.
// The backward kernel keeps the reference form (it needs the coordinates' Jacobian).
#pragma once

#include <cstdint>

#include "atex/detail/composite.h"
#include "atex/detail/projection.h"
#include "atex/detail/texture.h"
#include "render/render_cuda.h"
#include "render/render_kernels.h"

namespace atex::cuda::render {

// What the forward pass needs of one splat's texture, per view, in shared memory.
//   ≥ 2 texels: u = ClampNanLow(λ (a_u·c) − o_u), v likewise, λ = o_n / SafePlaneDenominator(n·c)
//   1×1:        the texel's colour residuals and opacity factor (no coordinates needed).
template <int kSlots>
struct ForwardTextureBatch {
  float4 row_u[kSlots];   // ≥2 texels: xyz = W axis_u / s_u, w = offset_n;  1×1: (0.1 tanh r, exp(0.1 tanh a))
  float4 row_v[kSlots];   // xyz = W axis_v / s_v, w = offset_u / s_u
  float4 row_n[kSlots];   // xyz = W normal,       w = offset_v / s_v
  float4 grid[kSlots];    // (½(w − 1), ½(h − 1), last x0, last y0): x0 ≤ max(w − 2, 0) so that x1 = x0 + 1
  uint4 index[kSlots];    // (first texel, then row stride, x step, y step in floats); step 0 on a side of 1
  bool constant[kSlots];  // 1×1 texture

  // Gaussian `id` into `slot` (one thread per slot, before the block's __syncthreads).
  __device__ void Load(const detail::CameraModel<float>& cam, const RenderInputs& in, const Projected& p, uint32_t id,
                       int slot) {
    const uchar4 layout = reinterpret_cast<const uchar4*>(in.texture_layout)[id];  // [N][4] bytes (h, w, axes)
    const int h = layout.x, w = layout.y;
    const uint32_t first = in.texel_offsets[id];  // in texels: the pool may exceed 2^32 floats
    constant[slot] = h == 1 && w == 1;
    if (constant[slot]) {
      const detail::ConstantTexel<float> t = detail::MakeConstantTexel(in.texels + size_t(first) * 4);
      row_u[slot] = make_float4(t.color_residual[0], t.color_residual[1], t.color_residual[2], t.alpha_factor);
      return;
    }
    const detail::TextureFrame<float> f = p.frames[id];
    const detail::Vec3<float> a = cam.rotation * (f.inv_scale_u * f.axis_u);
    const detail::Vec3<float> b = cam.rotation * (f.inv_scale_v * f.axis_v);
    const detail::Vec3<float> n = cam.rotation * f.normal;
    row_u[slot] = make_float4(a[0], a[1], a[2], f.offset_n);
    row_v[slot] = make_float4(b[0], b[1], b[2], f.offset_u * f.inv_scale_u);
    row_n[slot] = make_float4(n[0], n[1], n[2], f.offset_v * f.inv_scale_v);
    grid[slot] = make_float4(0.5f * float(w - 1), 0.5f * float(h - 1), float(w > 1 ? w - 2 : 0),
                             float(h > 1 ? h - 2 : 0));
    index[slot] = make_uint4(first, uint32_t(4 * w), w > 1 ? 4u : 0u, h > 1 ? uint32_t(4 * w) : 0u);
  }
};

// The texture activations' tanh (colour residual 0.1 tanh r, opacity factor exp(0.1 tanh a)):
// the hardware approximation (MUFU.TANH, sm_75+; relative error below 2^-10.9), one
// instruction where libdevice's tanhf takes a polynomial or an exponential and a
// division, four times per pixel and splat. On the 1352×1014 Panoptic A/B it gave 7 %
// more frames per second (445 → 475 FPS, BENCHMARKS.md, sixth run). Its largest effect on
// a colour is 0.1 · 2^-10.9 ≈ 5e-5, about 1/80 of an 8-bit level; the backward pass keeps tanhf.
__device__ __forceinline__ float ForwardTanh(float x) {
  float y;
  asm("tanh.approx.f32 %0, %1;" : "=f"(y) : "f"(x));
  return y;
}

// ClampNanLow(x, lo, hi) in two min/max instructions: fmaxf returns lo for NaN.
__device__ __forceinline__ float ClampToUnit(float x) { return fminf(fmaxf(x, -1.0f), 1.0f); }

// One axis of the corner-aligned bilinear taps for a clamped coordinate in [−1, 1]:
// the grid coordinate g = (c + 1)·½(size − 1), origin x0 = min(floor g, max(size − 2, 0))
// and weight g − x0 of x0 + 1. The same sample as MakeTexelTap's: the two differ only at
// g = size − 1, where MakeTexelTap weighs the last texel 1 as its i0 and this weighs it 1 as
// x0 + 1 (and the one before it 0). A side of 1 gives x0 = 0, weight 0 and a step of 0.
__device__ __forceinline__ float TapOrigin(float coordinate, float half_extent, float last_origin, float* frac) {
  const float g = (coordinate + 1.0f) * half_extent;
  const float origin = fminf(floorf(g), last_origin);
  *frac = g - origin;
  return origin;
}

// The textured part of EvaluateSplat for a contributing candidate: multiplies *alpha
// (α·G on entry) by the opacity factor and adds the colour residuals to *color.
// `c_x`, `c_y`: the pixel's normalised image coordinates.
template <int kSlots>
__device__ __forceinline__ void ApplyForwardTexture(const ForwardTextureBatch<kSlots>& batch, int slot,
                                                    const float* __restrict__ texels, float c_x, float c_y,
                                                    float* alpha, detail::Vec3<float>* color) {
  const float4 ru = batch.row_u[slot];
  if (batch.constant[slot]) {
    *alpha *= ru.w;
    (*color)[0] += ru.x;
    (*color)[1] += ru.y;
    (*color)[2] += ru.z;
    return;
  }
  const float4 rv = batch.row_v[slot], rn = batch.row_n[slot];
  bool replaced;
  const float denominator = detail::SafePlaneDenominator(fmaf(rn.x, c_x, fmaf(rn.y, c_y, rn.z)), &replaced);
  const float lambda = __fdividef(ru.w, denominator);
  const float u = ClampToUnit(fmaf(lambda, fmaf(ru.x, c_x, fmaf(ru.y, c_y, ru.z)), -rv.w));
  const float v = ClampToUnit(fmaf(lambda, fmaf(rv.x, c_x, fmaf(rv.y, c_y, rv.z)), -rn.w));
  const float4 grid = batch.grid[slot];
  const uint4 index = batch.index[slot];
  float fx, fy;
  const float x0 = TapOrigin(u, grid.x, grid.z, &fx);
  const float y0 = TapOrigin(v, grid.y, grid.w, &fy);
  const float* t00 = texels + size_t(index.x) * 4 + (uint32_t(y0) * index.y + uint32_t(x0) * 4u);
  const float4 a = __ldg(reinterpret_cast<const float4*>(t00));
  const float4 b = __ldg(reinterpret_cast<const float4*>(t00 + index.z));
  const float4 c = __ldg(reinterpret_cast<const float4*>(t00 + index.w));
  const float4 d = __ldg(reinterpret_cast<const float4*>(t00 + index.z + index.w));
  const float w00 = (1.0f - fx) * (1.0f - fy), w01 = fx * (1.0f - fy), w10 = (1.0f - fx) * fy, w11 = fx * fy;
  const float r = w00 * a.x + w01 * b.x + w10 * c.x + w11 * d.x;
  const float g = w00 * a.y + w01 * b.y + w10 * c.y + w11 * d.y;
  const float bl = w00 * a.z + w01 * b.z + w10 * c.z + w11 * d.z;
  const float al = w00 * a.w + w01 * b.w + w10 * c.w + w11 * d.w;
  constexpr float kColor = float(detail::kTextureColorScale), kAlpha = float(detail::kTextureAlphaScale);
  *alpha *= __expf(kAlpha * ForwardTanh(al));  // argument in [−0.1, 0.1]: ex2.approx is exact to ~1e-7
  (*color)[0] += kColor * ForwardTanh(r);
  (*color)[1] += kColor * ForwardTanh(g);
  (*color)[2] += kColor * ForwardTanh(bl);
}

}  // namespace atex::cuda::render
