// Stage 1: per-Gaussian projection (EWA), SH colour, texture frame, tile count;
// and its backward with the training statistics.
#include "atex/detail/quaternion.h"
#include "atex/detail/sh.h"
#include "cuda_check.h"
#include "render/render_kernels.h"

namespace atex::cuda::render {
namespace {

using detail::Mat3;
using detail::Vec2;
using detail::Vec3;
using detail::Vec4;

__device__ inline Vec3<float> Load3(const float* a, int i) { return {{a[3 * i], a[3 * i + 1], a[3 * i + 2]}}; }
__device__ inline Vec4<float> Load4(const float* a, int i) {
  return {{a[4 * i], a[4 * i + 1], a[4 * i + 2], a[4 * i + 3]}};
}

__device__ inline bool UsableQuaternion(const Vec4<float>& q) {
  const float n2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
  return n2 > 0.0f && detail::IsFinite(n2);
}

__global__ void ProjectKernel(detail::CameraModel<float> cam, RenderInputs in, Projected out) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= in.count) return;
  const Vec3<float> mean = Load3(in.positions, i);
  const Vec3<float> log_scale = Load3(in.log_scales, i);
  const Vec4<float> q = Load4(in.rotations, i);
  out.opacity[i] = detail::Sigmoid(in.opacity[i]);
  out.radius[i] = 0;
  out.tiles_touched[i] = 0;
  if (!UsableQuaternion(q)) {
    out.depth[i] = 0.0f;
    out.mean2d[2 * i] = out.mean2d[2 * i + 1] = 0.0f;
    return;
  }
  const Mat3<float> rotation = detail::QuaternionToRotation(q);
  const detail::ProjectedGaussian<float> p = detail::ProjectGaussian(cam, mean, rotation, log_scale);
  out.depth[i] = p.depth;
  out.mean2d[2 * i] = p.mean2d[0];
  out.mean2d[2 * i + 1] = p.mean2d[1];
  if (!p.visible) return;
  out.radius[i] = p.radius;
  const float max_alpha = out.opacity[i] * (in.textured() ? float(detail::kTextureAlphaFactorBound) : 1.0f);
  const detail::TileRect rect = detail::ContributionTileRect(p.rect, p.mean2d, p.cov2d, max_alpha, cam.tiles_x,
                                                             cam.tiles_y);
  out.rects[i] = make_int4(rect.x0, rect.y0, rect.x1, rect.y1);
  out.tiles_touched[i] = static_cast<uint32_t>((rect.x1 - rect.x0) * (rect.y1 - rect.y0));
  for (int k = 0; k < 3; ++k) out.conic[3 * i + k] = p.conic[k];
  bool clamped[3];
  const Vec3<float> color =
      detail::ShColor(in.active_sh_degree, in.sh + size_t(i) * in.sh_coeffs * 3, mean - cam.center, clamped);
  for (int k = 0; k < 3; ++k) out.color[3 * i + k] = color[k];
  if (in.textured()) {
    const uint8_t* layout = in.texture_layout + 4 * i;
    out.frames[i] = detail::MakeTextureFrame(rotation, mean, log_scale, cam.center, layout[2], layout[3]);
  }
}

__global__ void ProjectBackwardKernel(detail::CameraModel<float> cam, RenderInputs in, Projected p,
                                      const float* __restrict__ splat_grads, RenderGradients grads,
                                      RenderStats stats, bool with_stats) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= in.count || p.radius[i] <= 0) return;
  using L = SplatGradLayout;
  const float* sg = splat_grads + size_t(i) * L::kWidth;
  const Vec2<float> g_mean2d{{sg[L::kMean2d], sg[L::kMean2d + 1]}};
  const Vec3<float> g_conic{{sg[L::kConic], sg[L::kConic + 1], sg[L::kConic + 2]}};
  const float g_opacity = sg[L::kOpacity];
  const Vec3<float> g_color{{sg[L::kColor], sg[L::kColor + 1], sg[L::kColor + 2]}};

  const Vec3<float> mean = Load3(in.positions, i);
  const Vec3<float> log_scale = Load3(in.log_scales, i);
  const Vec4<float> q = Load4(in.rotations, i);
  const Mat3<float> rotation = detail::QuaternionToRotation(q);
  Vec3<float> g_mean{{0, 0, 0}}, g_log_scale{{0, 0, 0}};
  Mat3<float> g_rotation = detail::ZeroMat3<float>();
  detail::ProjectGaussianVjp(cam, mean, rotation, log_scale, g_mean2d, g_conic, &g_mean, &g_rotation, &g_log_scale);

  const float* sh = in.sh + size_t(i) * in.sh_coeffs * 3;
  float* g_sh = grads.sh + size_t(i) * in.sh_coeffs * 3;
  const Vec3<float> dir = mean - cam.center;
  bool clamped[3];
  detail::ShColor(in.active_sh_degree, sh, dir, clamped);
  // One thread per Gaussian: accumulating straight into its own SH gradient rows is race-free.
  g_mean += detail::ShColorVjp(in.active_sh_degree, sh, dir, clamped, g_color, g_sh);

  const float alpha = p.opacity[i];
  grads.opacity[i] += g_opacity * alpha * (1.0f - alpha);
  if (in.textured()) {
    const detail::TextureFrame<float> g_frame = L::LoadFrame(sg);
    const uint8_t* layout = in.texture_layout + 4 * i;
    detail::MakeTextureFrameVjp(rotation, mean, log_scale, cam.center, layout[2], layout[3], g_frame, &g_rotation,
                                &g_mean, &g_log_scale);
  }
  const Vec4<float> g_q = detail::QuaternionToRotationVjp(q, g_rotation);
  for (int k = 0; k < 3; ++k) {
    grads.positions[3 * i + k] += g_mean[k];
    grads.log_scales[3 * i + k] += g_log_scale[k];
  }
  for (int k = 0; k < 4; ++k) grads.rotations[4 * i + k] += g_q[k];

  if (!with_stats) return;
  // Demand q = |dL_k/dm| in NDC units (conventions §6).
  const float gx = g_mean2d[0] * 0.5f * cam.width, gy = g_mean2d[1] * 0.5f * cam.height;
  const float demand = sqrtf(gx * gx + gy * gy) * stats.grad_scale;
  if (stats.grad_norm_sum) {
    stats.grad_norm_sum[i] += demand;
    stats.visible_count[i] += 1.0f;
    stats.max_radius[i] = fmaxf(stats.max_radius[i], static_cast<float>(p.radius[i]));
  }
  if (stats.demand_sum && in.textured()) {
    const uint8_t* layout = in.texture_layout + 4 * i;
    const size_t k = size_t(i) * stats.bins + stats.bin;
    stats.demand_sum[k] += demand;
    stats.bin_count[k] += 1.0f;
    stats.scale_u_sum[k] += expf(log_scale[layout[2]]);
    stats.scale_v_sum[k] += expf(log_scale[layout[3]]);
  }
}

}  // namespace

Status LaunchProject(const detail::CameraModel<float>& cam, const RenderInputs& in, const Projected& out,
                     cudaStream_t stream) {
  if (in.count == 0) return Status::Ok();
  ProjectKernel<<<GridFor(in.count, 256), 256, 0, stream>>>(cam, in, out);
  ATEX_CUDA_CHECK_LAUNCH("ProjectKernel");
  return Status::Ok();
}

Status LaunchProjectBackward(const detail::CameraModel<float>& cam, const RenderInputs& in, const Projected& p,
                             const SplatGrads& splat_grads, const RenderGradients& grads, const RenderStats* stats,
                             cudaStream_t stream) {
  if (in.count == 0) return Status::Ok();
  RenderStats s = stats ? *stats : RenderStats{};
  ProjectBackwardKernel<<<GridFor(in.count, 128), 128, 0, stream>>>(cam, in, p, splat_grads.values, grads, s,
                                                                    stats != nullptr);
  ATEX_CUDA_CHECK_LAUNCH("ProjectBackwardKernel");
  return Status::Ok();
}

}  // namespace atex::cuda::render
