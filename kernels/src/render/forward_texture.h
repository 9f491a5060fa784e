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
// activations the hardware tanh and exponential). The per-splat and per-pixel functions are
// host and device code: forward_texture_test checks them against the reference on the CPU
// (in CI, without a GPU); the render parity tests check the whole kernel on a GPU.
// The backward kernel keeps the reference form (it needs the coordinates' Jacobian).
#pragma once

#include <cmath>
#include <cstdint>

#include <cuda_runtime.h>

#include "atex/detail/composite.h"
#include "atex/detail/projection.h"
#include "atex/detail/texture.h"
#include "render/render_cuda.h"
#ifdef __CUDACC__
#include "render/render_kernels.h"
#endif

namespace atex::cuda::render {

// ---- per splat and view (host and device, so that a CPU test checks them) ----------
// The plane of a texture of ≥ 2 texels in the camera frame, for pixels given by their
// normalised image coordinates c = ((px − cx)/fx, (py − cy)/fy, 1):
//   u = ClampNanLow(λ (a_u·c) − o_u), v likewise, λ = o_n / SafePlaneDenominator(n·c).
struct ForwardPlane {
  float4 row_u;  // xyz = W axis_u / s_u, w = offset_n
  float4 row_v;  // xyz = W axis_v / s_v, w = offset_u / s_u
  float4 row_n;  // xyz = W normal,       w = offset_v / s_v
};

// `camera_rotation`: W (world → camera) of the view; `f`: the splat's TextureFrame.
ATEX_HD ForwardPlane MakeForwardPlane(const detail::Mat3<float>& camera_rotation,
                                      const detail::TextureFrame<float>& f) {
  const detail::Vec3<float> a = camera_rotation * (f.inv_scale_u * f.axis_u);
  const detail::Vec3<float> b = camera_rotation * (f.inv_scale_v * f.axis_v);
  const detail::Vec3<float> n = camera_rotation * f.normal;
  return {make_float4(a[0], a[1], a[2], f.offset_n), make_float4(b[0], b[1], b[2], f.offset_u * f.inv_scale_u),
          make_float4(n[0], n[1], n[2], f.offset_v * f.inv_scale_v)};
}

// The texel grid of an h × w texture whose first texel is `first_texel` of the pool.
struct ForwardGrid {
  float4 extent;  // (½(w − 1), ½(h − 1), last x0, last y0): x0 ≤ max(w − 2, 0) so that x1 = x0 + 1
  uint4 index;    // (first texel, then row stride, x step, y step in floats); step 0 on a side of 1
};

ATEX_HD ForwardGrid MakeForwardGrid(int h, int w, uint32_t first_texel) {
  return {make_float4(0.5f * float(w - 1), 0.5f * float(h - 1), float(w > 1 ? w - 2 : 0), float(h > 1 ? h - 2 : 0)),
          make_uint4(first_texel, uint32_t(4 * w), w > 1 ? 4u : 0u, h > 1 ? uint32_t(4 * w) : 0u)};
}

// ---- per pixel ---------------------------------------------------------------------
// a / b: the fast division on the device (two instructions; b is at least 1e-10 in
// magnitude here), IEEE division on the host.
ATEX_HD float FastDivide(float a, float b) {
#ifdef __CUDA_ARCH__
  return __fdividef(a, b);
#else
  return a / b;
#endif
}

// ClampNanLow(x, −1, 1) in two min/max instructions: fmaxf returns −1 for NaN.
ATEX_HD float ClampToUnit(float x) { return fminf(fmaxf(x, -1.0f), 1.0f); }

// The clamped texture coordinates (u, v) of the pixel with normalised image coordinates (c_x, c_y).
ATEX_HD void ForwardTexCoord(const ForwardPlane& plane, float c_x, float c_y, float* u, float* v) {
  const float4 ru = plane.row_u, rv = plane.row_v, rn = plane.row_n;
  bool replaced;
  const float denominator = detail::SafePlaneDenominator(fmaf(rn.x, c_x, fmaf(rn.y, c_y, rn.z)), &replaced);
  const float lambda = FastDivide(ru.w, denominator);
  *u = ClampToUnit(fmaf(lambda, fmaf(ru.x, c_x, fmaf(ru.y, c_y, ru.z)), -rv.w));
  *v = ClampToUnit(fmaf(lambda, fmaf(rv.x, c_x, fmaf(rv.y, c_y, rv.z)), -rn.w));
}

// One axis of the corner-aligned bilinear taps for a clamped coordinate in [−1, 1]:
// the grid coordinate g = (c + 1)·½(size − 1), origin x0 = min(floor g, max(size − 2, 0))
// and weight g − x0 of x0 + 1. The same sample as MakeTexelTap's: the two differ only at
// g = size − 1, where MakeTexelTap weighs the last texel 1 as its i0 and this weighs it 1 as
// x0 + 1 (and the one before it 0). A side of 1 gives x0 = 0, weight 0 and a step of 0.
ATEX_HD float TapOrigin(float coordinate, float half_extent, float last_origin, float* frac) {
  const float g = (coordinate + 1.0f) * half_extent;
  const float origin = fminf(floorf(g), last_origin);
  *frac = g - origin;
  return origin;
}

// Bilinear raw RGBA at clamped (u, v) from the pool `texels` ([T][4]); SampleTexels'
// value at MakeBilinearTaps' taps.
ATEX_HD detail::Vec4<float> ForwardSample(const float* texels, const ForwardGrid& grid, float u, float v) {
  float fx, fy;
  const float x0 = TapOrigin(u, grid.extent.x, grid.extent.z, &fx);
  const float y0 = TapOrigin(v, grid.extent.y, grid.extent.w, &fy);
  const uint4 index = grid.index;
  const float* t00 = texels + size_t(index.x) * 4 + (uint32_t(y0) * index.y + uint32_t(x0) * 4u);
  const detail::Vec4<float> a = detail::LoadTexel(t00), b = detail::LoadTexel(t00 + index.z);
  const detail::Vec4<float> c = detail::LoadTexel(t00 + index.w), d = detail::LoadTexel(t00 + index.z + index.w);
  const float w00 = (1.0f - fx) * (1.0f - fy), w01 = fx * (1.0f - fy), w10 = (1.0f - fx) * fy, w11 = fx * fy;
  detail::Vec4<float> out;
  for (int ch = 0; ch < 4; ++ch) out[ch] = w00 * a[ch] + w01 * b[ch] + w10 * c[ch] + w11 * d[ch];
  return out;
}

// ---- the kernel's side ----------------------------------------------------------------
#ifdef __CUDACC__
// What the forward pass needs of the splats of a batch, in shared memory: ≥ 2 texels, the
// plane and the grid; 1×1, the texel's colour residuals and opacity factor (no coordinates).
template <int kSlots>
struct ForwardTextureBatch {
  ForwardPlane plane[kSlots];  // 1×1: plane.row_u = (0.1 tanh r, exp(0.1 tanh a)), the rest unset
  ForwardGrid grid[kSlots];
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
      plane[slot].row_u = make_float4(t.color_residual[0], t.color_residual[1], t.color_residual[2], t.alpha_factor);
      return;
    }
    plane[slot] = MakeForwardPlane(cam.rotation, p.frames[id]);
    grid[slot] = MakeForwardGrid(h, w, first);
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

// The textured part of EvaluateSplat for a contributing candidate: multiplies *alpha
// (α·G on entry) by the opacity factor and adds the colour residuals to *color.
// `c_x`, `c_y`: the pixel's normalised image coordinates.
template <int kSlots>
__device__ __forceinline__ void ApplyForwardTexture(const ForwardTextureBatch<kSlots>& batch, int slot,
                                                    const float* __restrict__ texels, float c_x, float c_y,
                                                    float* alpha, detail::Vec3<float>* color) {
  if (batch.constant[slot]) {
    const float4 constant = batch.plane[slot].row_u;
    *alpha *= constant.w;
    (*color)[0] += constant.x;
    (*color)[1] += constant.y;
    (*color)[2] += constant.z;
    return;
  }
  float u, v;
  ForwardTexCoord(batch.plane[slot], c_x, c_y, &u, &v);
  const detail::Vec4<float> raw = ForwardSample(texels, batch.grid[slot], u, v);
  constexpr float kColor = float(detail::kTextureColorScale), kAlpha = float(detail::kTextureAlphaScale);
  *alpha *= __expf(kAlpha * ForwardTanh(raw[3]));  // argument in [−0.1, 0.1]: ex2.approx is exact to ~1e-7
  for (int ch = 0; ch < 3; ++ch) (*color)[ch] += kColor * ForwardTanh(raw[ch]);
}
#endif  // __CUDACC__

}  // namespace atex::cuda::render
