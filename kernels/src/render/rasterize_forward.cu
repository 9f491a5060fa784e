// Stage 3 forward: one 16×16 thread block per tile, one thread per pixel, splats
// streamed through shared memory in batches of 256 (gsplat's structure). The
// per-splat mathematics is EvaluateSplat's (atex/detail/composite.h), as in the CPU
// engine, with its textured branch in the per-pixel form of render/forward_texture.h.
#include "cuda_check.h"
#include "render/forward_texture.h"
#include "render/render_kernels.h"

namespace atex::cuda::render {
namespace {

using detail::Vec3;
constexpr int kBlock = detail::kTileSize * detail::kTileSize;  // 256 threads

template <bool kTextured, bool kImportance>
__global__ void __launch_bounds__(kBlock) RasterForwardKernel(
    detail::CameraModel<float> cam, RenderInputs in, Projected p, const uint2* __restrict__ ranges,
    const uint32_t* __restrict__ sorted_ids, float* __restrict__ out_color, float* __restrict__ out_alpha,
    float* __restrict__ final_transmittance, uint32_t* __restrict__ contributor_end, float* __restrict__ importance) {
  __shared__ uint32_t s_id[kBlock];
  __shared__ float2 s_mean[kBlock];
  __shared__ float3 s_conic[kBlock];
  __shared__ float s_opacity[kBlock];
  __shared__ float3 s_color[kBlock];
  __shared__ ForwardTextureBatch<kTextured ? kBlock : 1> s_tex;

  const int tile = blockIdx.y * cam.tiles_x + blockIdx.x;
  const int x = blockIdx.x * detail::kTileSize + threadIdx.x % detail::kTileSize;
  const int y = blockIdx.y * detail::kTileSize + threadIdx.x / detail::kTileSize;
  const bool inside = x < cam.width && y < cam.height;
  const float px = float(x) + 0.5f, py = float(y) + 0.5f;
  // Normalised image coordinates (the camera-frame ray is (c_x, c_y, 1)), for the texture planes.
  const float c_x = (px - cam.cx) / cam.fx, c_y = (py - cam.cy) / cam.fy;

  const uint2 range = ranges[tile];
  const int count = static_cast<int>(range.y - range.x);
  float transmittance = 1.0f;
  Vec3<float> color{{0.f, 0.f, 0.f}};
  uint32_t last = 0;
  bool done = !inside;

  for (int batch = 0; batch < count; batch += kBlock) {
    if (__syncthreads_count(done) == kBlock) break;
    const int k = batch + threadIdx.x;
    if (k < count) {
      const uint32_t id = sorted_ids[range.x + k];
      s_id[threadIdx.x] = id;
      s_mean[threadIdx.x] = make_float2(p.mean2d[2 * id], p.mean2d[2 * id + 1]);
      s_conic[threadIdx.x] = make_float3(p.conic[3 * id], p.conic[3 * id + 1], p.conic[3 * id + 2]);
      s_opacity[threadIdx.x] = p.opacity[id];
      s_color[threadIdx.x] = make_float3(p.color[3 * id], p.color[3 * id + 1], p.color[3 * id + 2]);
      if constexpr (kTextured) s_tex.Load(cam, in, p, id, threadIdx.x);
    }
    __syncthreads();
    const int in_batch = min(kBlock, count - batch);
    for (int j = 0; j < in_batch && !done; ++j) {
      // EvaluateSplat (composite.h) in the same order of operations.
      const float dx = px - s_mean[j].x, dy = py - s_mean[j].y;
      const float power = detail::GaussianPower(Vec3<float>{{s_conic[j].x, s_conic[j].y, s_conic[j].z}}, dx, dy);
      if (power > 0.0f) continue;
      const float base = s_opacity[j] * detail::Exp(power);
      float alpha = base;
      Vec3<float> splat_color{{s_color[j].x, s_color[j].y, s_color[j].z}};
      if constexpr (kTextured) {
        if (detail::TexturedSampleIsCut(base)) continue;
        ApplyForwardTexture(s_tex, j, in.texels, c_x, c_y, &alpha, &splat_color);
      }
      alpha = detail::ClampSplatAlpha(alpha);
      if (!detail::SplatAlphaKept(alpha)) continue;
      const float next = transmittance * (1.0f - alpha);
      if (next < float(detail::kMinTransmittance)) {
        done = true;
        break;
      }
      const float w = alpha * transmittance;
      for (int ch = 0; ch < 3; ++ch) color[ch] += splat_color[ch] * w;
      if constexpr (kImportance) atomicAdd(&importance[s_id[j]], w);
      transmittance = next;
      last = batch + j + 1;
    }
  }
  if (!inside) return;
  const size_t pixel = size_t(y) * cam.width + x;
  for (int ch = 0; ch < 3; ++ch) out_color[3 * pixel + ch] = color[ch] + transmittance * in.background[ch];
  if (out_alpha) out_alpha[pixel] = 1.0f - transmittance;
  final_transmittance[pixel] = transmittance;
  contributor_end[pixel] = last;
}

template <bool kTextured, bool kImportance>
void Launch(dim3 grid, cudaStream_t stream, const detail::CameraModel<float>& cam, const RenderInputs& in,
            const Projected& p, const uint2* ranges, const uint32_t* ids, float* color, float* alpha,
            float* final_t, uint32_t* contributor_end, float* importance) {
  RasterForwardKernel<kTextured, kImportance><<<grid, kBlock, 0, stream>>>(cam, in, p, ranges, ids, color, alpha,
                                                                          final_t, contributor_end, importance);
}

}  // namespace

Status LaunchRasterForward(const detail::CameraModel<float>& cam, const RenderInputs& in, const Projected& p,
                           const uint2* ranges, const uint32_t* sorted_ids, float* color, float* alpha,
                           float* final_transmittance, uint32_t* contributor_end, float* importance,
                           cudaStream_t stream) {
  const dim3 grid(cam.tiles_x, cam.tiles_y);
  const bool textured = in.textured(), with_importance = importance != nullptr;
  if (textured && with_importance) {
    Launch<true, true>(grid, stream, cam, in, p, ranges, sorted_ids, color, alpha, final_transmittance,
                       contributor_end, importance);
  } else if (textured) {
    Launch<true, false>(grid, stream, cam, in, p, ranges, sorted_ids, color, alpha, final_transmittance,
                        contributor_end, importance);
  } else if (with_importance) {
    Launch<false, true>(grid, stream, cam, in, p, ranges, sorted_ids, color, alpha, final_transmittance,
                        contributor_end, importance);
  } else {
    Launch<false, false>(grid, stream, cam, in, p, ranges, sorted_ids, color, alpha, final_transmittance,
                         contributor_end, importance);
  }
  ATEX_CUDA_CHECK_LAUNCH("RasterForwardKernel");
  return Status::Ok();
}

}  // namespace atex::cuda::render
