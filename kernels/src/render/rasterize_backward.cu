// Stage 3 backward: per pixel back to front from its last contributor, T_i
// recovered by division (composite.h, as the CPU engine). Per-splat gradients are
// reduced across each warp and added to the Gaussian's accumulator with one atomic
// per warp; texel gradients go straight to the texel gradient array.
#include "cuda_check.h"
#include "render/render_kernels.h"

namespace atex::cuda::render {
namespace {

using detail::Vec3;
using detail::Vec4;
constexpr int kBlock = detail::kTileSize * detail::kTileSize;

// EvaluateSplatVjp (composite.h) with the texel gradients added atomically to the
// global array instead of a per-Gaussian buffer; the rest calls the same pieces.
__device__ void SplatVjpAtomic(const detail::SplatParams<float>& s, const Vec3<float>& ray,
                               const detail::SplatSample<float>& smp, const Vec3<float>& g_color, float g_alpha,
                               detail::SplatGrad<float>* g, float* g_texels /* this Gaussian's [h][w][4] */) {
  g->color += g_color;
  const bool textured = s.frame != nullptr;
  const float factor =
      !textured ? 1.0f : (s.constant != nullptr ? s.constant->alpha_factor : detail::TextureAlphaFactor(smp.texel[3]));
  Vec4<float> g_rgba{{0.f, 0.f, 0.f, 0.f}};
  if (textured) {
    for (int ch = 0; ch < 3; ++ch) g_rgba[ch] = detail::TextureColorResidualVjp(smp.texel[ch], g_color[ch]);
  }
  if (!smp.alpha_clamped) {
    const float base = s.opacity * smp.falloff;
    g->opacity += g_alpha * smp.falloff * factor;
    const float g_falloff = g_alpha * s.opacity * factor;
    detail::GaussianPowerVjp(s.conic, smp.dx, smp.dy, g_falloff * smp.falloff, &g->conic, &g->mean2d);
    if (textured) g_rgba[3] = detail::TextureAlphaFactorVjp(smp.texel[3], g_alpha * base);
  }
  if (!textured) return;
  if (s.tex_h == 1 && s.tex_w == 1) {
    // One texel: its weight is 1 and the coordinates get no gradient (EvaluateSplat).
    for (int c = 0; c < 4; ++c) {
      if (g_rgba[c] != 0.f) atomicAdd(&g_texels[c], g_rgba[c]);
    }
    return;
  }
  // SampleTexelsVjp with atomics; taps of zero weight (a side of 1, or a knot hit exactly)
  // add nothing and are skipped.
  const auto& taps = smp.taps;
  const float fx = taps.x.frac, fy = taps.y.frac;
  const float w00 = (1.f - fx) * (1.f - fy), w01 = fx * (1.f - fy), w10 = (1.f - fx) * fy, w11 = fx * fy;
  const int i00 = (taps.y.i0 * s.tex_w + taps.x.i0) * 4, i01 = (taps.y.i0 * s.tex_w + taps.x.i1) * 4;
  const int i10 = (taps.y.i1 * s.tex_w + taps.x.i0) * 4, i11 = (taps.y.i1 * s.tex_w + taps.x.i1) * 4;
  float g_fx = 0.f, g_fy = 0.f;
  const float* t = s.texels;
  for (int c = 0; c < 4; ++c) {
    const float gc = g_rgba[c];
    if (gc != 0.f) {
      if (w00 != 0.f) atomicAdd(&g_texels[i00 + c], w00 * gc);
      if (w01 != 0.f) atomicAdd(&g_texels[i01 + c], w01 * gc);
      if (w10 != 0.f) atomicAdd(&g_texels[i10 + c], w10 * gc);
      if (w11 != 0.f) atomicAdd(&g_texels[i11 + c], w11 * gc);
    }
    g_fx += gc * ((1.f - fy) * (t[i01 + c] - t[i00 + c]) + fy * (t[i11 + c] - t[i10 + c]));
    g_fy += gc * ((1.f - fx) * (t[i10 + c] - t[i00 + c]) + fx * (t[i11 + c] - t[i01 + c]));
  }
  const float g_u = g_fx * 0.5f * float(s.tex_w - 1);
  const float g_v = g_fy * 0.5f * float(s.tex_h - 1);
  detail::ComputeTexCoordVjp(*s.frame, ray, smp.tc, g_u, g_v, &g->frame);
}

__device__ inline float WarpSum(float v) {
  for (int offset = 16; offset > 0; offset /= 2) v += __shfl_xor_sync(0xffffffffu, v, offset);
  return v;
}

template <bool kTextured>
__global__ void __launch_bounds__(kBlock) RasterBackwardKernel(
    detail::CameraModel<float> cam, RenderInputs in, Projected p, const uint2* __restrict__ ranges,
    const uint32_t* __restrict__ sorted_ids, const float* __restrict__ final_transmittance,
    const uint32_t* __restrict__ contributor_end, const float* __restrict__ grad_color,
    const float* __restrict__ grad_alpha, float* __restrict__ splat_grads, float* __restrict__ grad_texels) {
  __shared__ uint32_t s_id[kBlock];
  __shared__ float2 s_mean[kBlock];
  __shared__ float3 s_conic[kBlock];
  __shared__ float s_opacity[kBlock];
  __shared__ float3 s_color[kBlock];
  __shared__ TextureBatch<kTextured ? kBlock : 1> s_tex;
  __shared__ uint32_t s_max_end;

  const int tile = blockIdx.y * cam.tiles_x + blockIdx.x;
  const int x = blockIdx.x * detail::kTileSize + threadIdx.x % detail::kTileSize;
  const int y = blockIdx.y * detail::kTileSize + threadIdx.x / detail::kTileSize;
  const bool inside = x < cam.width && y < cam.height;
  const size_t pixel = inside ? size_t(y) * cam.width + x : 0;
  const float px = float(x) + 0.5f, py = float(y) + 0.5f;
  const Vec3<float> ray = kTextured ? detail::PixelRayDirection(cam, px, py) : Vec3<float>{{0.f, 0.f, 1.f}};

  const uint2 range = ranges[tile];
  const uint32_t last = inside ? contributor_end[pixel] : 0;
  if (threadIdx.x == 0) s_max_end = 0;
  __syncthreads();
  atomicMax(&s_max_end, last);
  __syncthreads();
  const int end_all = static_cast<int>(s_max_end);

  const float t_final = inside ? final_transmittance[pixel] : 1.0f;
  float transmittance = t_final;
  Vec3<float> back{{0.f, 0.f, 0.f}};
  Vec3<float> g_pixel{{0.f, 0.f, 0.f}};
  float g_pixel_alpha = 0.f;
  if (inside) {
    for (int ch = 0; ch < 3; ++ch) {
      back[ch] = t_final * in.background[ch];
      g_pixel[ch] = grad_color[3 * pixel + ch];
    }
    if (grad_alpha) g_pixel_alpha = grad_alpha[pixel];
  }
  const int lane = threadIdx.x % 32;

  for (int end = end_all; end > 0; end -= kBlock) {
    const int start = max(0, end - kBlock);
    const int in_batch = end - start;
    __syncthreads();  // the previous batch is no longer read
    if (threadIdx.x < in_batch) {
      const uint32_t id = sorted_ids[range.x + end - 1 - threadIdx.x];  // deepest first
      s_id[threadIdx.x] = id;
      s_mean[threadIdx.x] = make_float2(p.mean2d[2 * id], p.mean2d[2 * id + 1]);
      s_conic[threadIdx.x] = make_float3(p.conic[3 * id], p.conic[3 * id + 1], p.conic[3 * id + 2]);
      s_opacity[threadIdx.x] = p.opacity[id];
      s_color[threadIdx.x] = make_float3(p.color[3 * id], p.color[3 * id + 1], p.color[3 * id + 2]);
      if constexpr (kTextured) s_tex.Load(in, p, id, threadIdx.x);
    }
    __syncthreads();
    for (int j = 0; j < in_batch; ++j) {
      const uint32_t entry = static_cast<uint32_t>(end - 1 - j);
      const uint32_t id = s_id[j];
      detail::SplatParams<float> s;
      s.mean2d = {{s_mean[j].x, s_mean[j].y}};
      s.conic = {{s_conic[j].x, s_conic[j].y, s_conic[j].z}};
      s.opacity = s_opacity[j];
      s.color = {{s_color[j].x, s_color[j].y, s_color[j].z}};
      float* g_texels = nullptr;
      if constexpr (kTextured) {
        s_tex.Fill(in, j, &s);
        g_texels = grad_texels + size_t(s_tex.texel_offset[j]) * 4;
      } else {
        s.frame = nullptr;
        s.texels = nullptr;
        s.tex_h = s.tex_w = 0;
      }
      bool valid = inside && entry < last;
      detail::SplatSample<float> smp;
      if (valid) {
        smp = detail::EvaluateSplat(s, px, py, ray);
        valid = smp.contributes;
      }
      detail::SplatGrad<float> g = detail::ZeroSplatGrad<float>();
      if (valid) {
        const float before = transmittance / (1.0f - smp.alpha);
        Vec3<float> g_c;
        const float g_a = detail::BlendStepVjp(smp.alpha, smp.color, before, back, t_final, g_pixel, g_pixel_alpha,
                                               &g_c);
        for (int ch = 0; ch < 3; ++ch) back[ch] += smp.color[ch] * smp.alpha * before;
        transmittance = before;
        SplatVjpAtomic(s, ray, smp, g_c, g_a, &g, g_texels);
      }
      if (!__any_sync(0xffffffffu, valid)) continue;
      float values[SplatGradLayout::kWidth];
      SplatGradLayout::Store(g, values);
      // Untextured splats have no frame gradient.
      constexpr int kWidth = kTextured ? SplatGradLayout::kWidth : SplatGradLayout::kUntexturedWidth;
#pragma unroll
      for (int k = 0; k < kWidth; ++k) values[k] = WarpSum(values[k]);
      if (lane == 0) {
        float* dst = splat_grads + size_t(id) * SplatGradLayout::kWidth;
#pragma unroll
        for (int k = 0; k < kWidth; ++k) {
          if (values[k] != 0.f) atomicAdd(&dst[k], values[k]);
        }
      }
    }
  }
}

}  // namespace

Status LaunchRasterBackward(const detail::CameraModel<float>& cam, const RenderInputs& in, const Projected& p,
                            const uint2* ranges, const uint32_t* sorted_ids, const float* final_transmittance,
                            const uint32_t* contributor_end, const float* grad_color, const float* grad_alpha,
                            const SplatGrads& splat_grads, float* grad_texels, cudaStream_t stream) {
  const dim3 grid(cam.tiles_x, cam.tiles_y);
  if (in.textured()) {
    RasterBackwardKernel<true><<<grid, kBlock, 0, stream>>>(cam, in, p, ranges, sorted_ids, final_transmittance,
                                                            contributor_end, grad_color, grad_alpha,
                                                            splat_grads.values, grad_texels);
  } else {
    RasterBackwardKernel<false><<<grid, kBlock, 0, stream>>>(cam, in, p, ranges, sorted_ids, final_transmittance,
                                                             contributor_end, grad_color, grad_alpha,
                                                             splat_grads.values, grad_texels);
  }
  ATEX_CUDA_CHECK_LAUNCH("RasterBackwardKernel");
  return Status::Ok();
}

}  // namespace atex::cuda::render
