// Compile-only check that every ATEX_HD function of atex/detail builds as device
// code. Not part of any library: the render module registers
//   nvcc -arch=sm_90 -std=c++20 --expt-relaxed-constexpr -Werror all-warnings -c
// of this file as a test when nvcc is on the machine (no GPU needed), so the
// shared mathematics cannot drift into host-only code before the CUDA backend
// uses it.
#include "atex/detail/composite.h"
#include "atex/detail/math.h"
#include "atex/detail/projection.h"
#include "atex/detail/quaternion.h"
#include "atex/detail/sh.h"
#include "atex/detail/texture.h"
#include "atex/detail/vec.h"

namespace {

using namespace atex::detail;

// in: [80] arbitrary values (16-byte aligned); out: [1]. Calls every forward function and its VJP.
template <typename T>
__global__ void EveryDetailFunction(const T* in, T* out, CameraModel<T> cam) {
  const Vec3<T> mean{{in[0], in[1], in[2]}};
  const Vec3<T> log_scale{{in[3], in[4], in[5]}};
  const Vec4<T> q{{in[6], in[7], in[8], in[9]}};
  const Mat3<T> rotation = QuaternionToRotation(q);
  const ProjectedGaussian<T> p = ProjectGaussian(cam, mean, rotation, log_scale);
  Vec3<T> g_mean{{T(0), T(0), T(0)}}, g_log_scale{{T(0), T(0), T(0)}};
  Mat3<T> g_rotation = ZeroMat3<T>();
  ProjectGaussianVjp(cam, mean, rotation, log_scale, p.mean2d, p.conic, &g_mean, &g_rotation, &g_log_scale);
  const TileRect rect = ContributionTileRect(
      ComputeTileRect(p.mean2d, Ceil(ProjectedExtent(p.conic)), cam.tiles_x, cam.tiles_y), p.mean2d, p.cov2d,
      in[58], cam.tiles_x, cam.tiles_y);

  bool clamped[3];
  const Vec3<T> dir = mean - cam.center;
  const Vec3<T> color = ShColor(3, in + 10, dir, clamped);
  T g_sh[48] = {};
  g_mean += ShColorVjp(3, in + 10, dir, clamped, color, g_sh);

  const TextureFrame<T> frame = MakeTextureFrame(rotation, mean, log_scale, cam.center, 0, 2);
  const Vec3<T> ray = PixelRayDirection(cam, T(threadIdx.x) + T(0.5), T(blockIdx.x) + T(0.5));
  SplatParams<T> splat;
  splat.mean2d = p.mean2d;
  splat.conic = p.conic;
  splat.opacity = Sigmoid(in[58]);
  splat.color = color;
  splat.frame = &frame;
  splat.texels = in + 60;  // 16-byte aligned, as LoadTexel needs on the device
  splat.tex_h = 2;
  splat.tex_w = 2;
  const SplatSample<T> sample = EvaluateSplat(splat, ray[0], ray[1], ray);
  const ConstantTexel<T> constant = MakeConstantTexel(in + 60);
  SplatParams<T> flat = splat;
  flat.tex_h = flat.tex_w = 1;
  flat.constant = &constant;
  const SplatSample<T> flat_sample = EvaluateSplat(flat, ray[0], ray[1], ray);
  const Vec3<T> back{{T(0), T(0), T(0)}};
  Vec3<T> g_color;
  const T g_alpha = BlendStepVjp(sample.alpha, sample.color, T(1), back, T(0.5), color, T(1), &g_color);
  SplatGrad<T> g_splat = ZeroSplatGrad<T>();
  T g_texels[16] = {};
  EvaluateSplatVjp(splat, ray, sample, g_color, g_alpha, &g_splat, g_texels);
  MakeTextureFrameVjp(rotation, mean, log_scale, cam.center, 0, 2, g_splat.frame, &g_rotation, &g_mean, &g_log_scale);
  const Vec4<T> g_q = QuaternionToRotationVjp(q, g_rotation);

  T grown[64];
  UpsampleTexture(in + 60, 2, 2, grown, 4, 4, 4);
  out[0] = g_q[0] + g_mean[0] + g_log_scale[0] + g_sh[5] + g_texels[3] + grown[7] + T(rect.x0 + p.radius) +
           T(IsFinite(g_alpha) ? 1 : 0) + flat_sample.alpha + Min(Abs(in[0]), Max(in[1], Tanh(in[2])));
}

template __global__ void EveryDetailFunction<float>(const float*, float*, CameraModel<float>);
template __global__ void EveryDetailFunction<double>(const double*, double*, CameraModel<double>);

}  // namespace
