// Stage 1 (per-Gaussian projection, SH colour, texture frame), stage 2 (tile
// lists in (depth, index) order) and the backward of stage 1.
#include <algorithm>
#include <numeric>

#include "atex/detail/quaternion.h"
#include "atex/detail/sh.h"
#include "atex/detail/texture.h"
#include "render/parallel.h"
#include "render/render_internal.h"

namespace atex::render_internal {

using detail::Mat3;
using detail::Vec2;
using detail::Vec3;
using detail::Vec4;

template <typename T>
Status BuildRenderState(const detail::CameraModel<T>& cam, const BasicGaussians<T>& g,
                        const BasicTexturePool<T>* textures, int sh_degree, BasicRenderOutput<T>* out) {
  const size_t n = g.size();
  const size_t coeffs = static_cast<size_t>(g.sh_coeffs());
  auto& st = out->state;
  out->width = cam.width;
  out->height = cam.height;
  st.tiles_x = cam.tiles_x;
  st.tiles_y = cam.tiles_y;
  st.sh_degree = sh_degree;
  st.textured = textures != nullptr;
  out->radius.assign(n, 0);
  out->mean2d.assign(n * 2, T(0));
  out->depth.assign(n, T(0));
  st.conic.assign(n * 3, T(0));
  st.opacity.assign(n, T(0));
  st.color.assign(n * 3, T(0));
  st.frames.assign(textures != nullptr ? n : 0, detail::ZeroTextureFrame<T>());
  std::vector<detail::TileRect> rects(n, detail::TileRect{0, 0, 0, 0});  // [N]
  const T max_texture_factor = textures != nullptr ? T(detail::kTextureAlphaFactorBound) : T(1);

  const int64_t count = static_cast<int64_t>(n);
#ifdef _OPENMP
#pragma omp parallel for schedule(static) if (count >= kMinParallelGaussians)
#endif
  for (int64_t ii = 0; ii < count; ++ii) {
    const size_t i = static_cast<size_t>(ii);
    const Vec3<T> mean = Load3(g.positions, i);
    const Vec3<T> log_scale = Load3(g.log_scales, i);
    const Mat3<T> rotation = detail::QuaternionToRotation(Load4(g.rotations, i));
    const detail::ProjectedGaussian<T> p = detail::ProjectGaussian(cam, mean, rotation, log_scale);
    out->depth[i] = p.depth;
    out->mean2d[2 * i] = p.mean2d[0];
    out->mean2d[2 * i + 1] = p.mean2d[1];
    st.opacity[i] = detail::Sigmoid(g.opacity_logits[i]);
    if (!p.visible) continue;
    out->radius[i] = p.radius;
    rects[i] = detail::ContributionTileRect(p.rect, p.mean2d, p.cov2d, st.opacity[i] * max_texture_factor,
                                            cam.tiles_x, cam.tiles_y);
    for (int k = 0; k < 3; ++k) st.conic[3 * i + k] = p.conic[k];
    bool clamped[3];
    const Vec3<T> color = detail::ShColor(sh_degree, &g.sh[i * coeffs * 3], mean - cam.center, clamped);
    for (int k = 0; k < 3; ++k) st.color[3 * i + k] = color[k];
    if (textures != nullptr) {
      st.frames[i] = detail::MakeTextureFrame(rotation, mean, log_scale, cam.center, textures->axis_u[i],
                                              textures->axis_v[i]);
    }
  }

  // ---- tile lists ----
  std::vector<int32_t> order;  // visible Gaussians in (depth, index) order
  uint64_t entries = 0;
  st.gaussian_entry_ranges.assign(n + 1, 0);
  for (size_t i = 0; i < n; ++i) {
    const auto& r = rects[i];
    const uint64_t area = out->radius[i] > 0 ? uint64_t(r.x1 - r.x0) * uint64_t(r.y1 - r.y0) : 0;
    if (area > 0) order.push_back(static_cast<int32_t>(i));
    entries += area;
    st.gaussian_entry_ranges[i + 1] = entries;
  }
  if (entries > kMaxTileEntries) {
    return MakeError(StatusCode::kLimitExceeded, "render: ", entries, " (tile, Gaussian) pairs exceed the limit of ",
                     kMaxTileEntries, " of the reference rasteriser");
  }
  std::sort(order.begin(), order.end(), [&](int32_t a, int32_t b) {
    const T da = out->depth[a], db = out->depth[b];
    return da < db || (da == db && a < b);
  });
  const size_t tiles = size_t(cam.tiles_x) * size_t(cam.tiles_y);
  st.tile_ranges.assign(tiles + 1, 0);
  for (int32_t i : order) {
    const auto& r = rects[i];
    for (int ty = r.y0; ty < r.y1; ++ty)
      for (int tx = r.x0; tx < r.x1; ++tx) ++st.tile_ranges[size_t(ty) * cam.tiles_x + tx + 1];
  }
  std::partial_sum(st.tile_ranges.begin(), st.tile_ranges.end(), st.tile_ranges.begin());
  std::vector<uint64_t> cursor(st.tile_ranges.begin(), st.tile_ranges.end() - 1);  // [tiles]
  st.tile_gaussians.assign(entries, 0);
  st.gaussian_entries.assign(entries, 0);
  for (int32_t i : order) {
    const auto& r = rects[i];
    uint64_t k = st.gaussian_entry_ranges[i];
    for (int ty = r.y0; ty < r.y1; ++ty) {
      for (int tx = r.x0; tx < r.x1; ++tx) {
        const uint64_t e = cursor[size_t(ty) * cam.tiles_x + tx]++;
        st.tile_gaussians[e] = i;
        st.gaussian_entries[k++] = e;
      }
    }
  }
  return Status::Ok();
}

template <typename T>
void ProjectionBackward(const detail::CameraModel<T>& cam, const BasicGaussians<T>& g,
                        const BasicTexturePool<T>* textures, const BasicRenderOutput<T>& forward,
                        const RasterGradients<T>& raster, BasicRenderGradients<T>* out) {
  const size_t n = g.size();
  const size_t coeffs = static_cast<size_t>(g.sh_coeffs());
  const int sh_degree = forward.state.sh_degree;
  const int64_t count = static_cast<int64_t>(n);
#ifdef _OPENMP
#pragma omp parallel for schedule(static) if (count >= kMinParallelGaussians)
#endif
  for (int64_t ii = 0; ii < count; ++ii) {
    const size_t i = static_cast<size_t>(ii);
    const detail::SplatGrad<T>& sg = raster.splats[i];
    out->mean2d[2 * i] = sg.mean2d[0];
    out->mean2d[2 * i + 1] = sg.mean2d[1];
    if (forward.radius[i] <= 0) continue;
    const Vec3<T> mean = Load3(g.positions, i);
    const Vec3<T> log_scale = Load3(g.log_scales, i);
    const Vec4<T> q = Load4(g.rotations, i);
    const Mat3<T> rotation = detail::QuaternionToRotation(q);
    Vec3<T> g_mean{{T(0), T(0), T(0)}};
    Vec3<T> g_log_scale{{T(0), T(0), T(0)}};
    Mat3<T> g_rotation = detail::ZeroMat3<T>();
    detail::ProjectGaussianVjp(cam, mean, rotation, log_scale, sg.mean2d, sg.conic, &g_mean, &g_rotation,
                               &g_log_scale);
    const T* sh = &g.sh[i * coeffs * 3];
    const Vec3<T> dir = mean - cam.center;
    bool clamped[3];
    detail::ShColor(sh_degree, sh, dir, clamped);
    g_mean += detail::ShColorVjp(sh_degree, sh, dir, clamped, sg.color, &out->gaussians.sh[i * coeffs * 3]);
    const T alpha = forward.state.opacity[i];
    out->gaussians.opacity_logits[i] = sg.opacity * alpha * (T(1) - alpha);
    if (textures != nullptr) {
      detail::MakeTextureFrameVjp(rotation, mean, log_scale, cam.center, textures->axis_u[i], textures->axis_v[i],
                                  sg.frame, &g_rotation, &g_mean, &g_log_scale);
    }
    const Vec4<T> g_q = detail::QuaternionToRotationVjp(q, g_rotation);
    for (int k = 0; k < 3; ++k) {
      out->gaussians.positions[3 * i + k] = g_mean[k];
      out->gaussians.log_scales[3 * i + k] = g_log_scale[k];
    }
    for (int k = 0; k < 4; ++k) out->gaussians.rotations[4 * i + k] = g_q[k];
  }
}

#define ATEX_INSTANTIATE(T)                                                                                     \
  template Status BuildRenderState(const detail::CameraModel<T>&, const BasicGaussians<T>&,                   \
                                   const BasicTexturePool<T>*, int, BasicRenderOutput<T>*);                     \
  template void ProjectionBackward(const detail::CameraModel<T>&, const BasicGaussians<T>&,                   \
                                   const BasicTexturePool<T>*, const BasicRenderOutput<T>&,                     \
                                   const RasterGradients<T>&, BasicRenderGradients<T>*);
ATEX_INSTANTIATE(float)
ATEX_INSTANTIATE(double)
#undef ATEX_INSTANTIATE

}  // namespace atex::render_internal
