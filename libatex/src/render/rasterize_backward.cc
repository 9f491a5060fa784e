// Stage 3 backward: per pixel back to front from the last contributor, with
// T_i recovered by division (conventions §5, composite.h). Gradients are
// accumulated per (tile, Gaussian) pair — each pair belongs to one tile, so to one
// task — and then summed per Gaussian in ascending tile order: the result does not
// depend on the number of threads.
#include <algorithm>

#include "render/parallel.h"
#include "render/render_internal.h"

namespace atex::render_internal {

using detail::Vec3;

namespace {

template <typename T>
void AddSplatGrad(const detail::SplatGrad<T>& a, detail::SplatGrad<T>* sum) {
  for (int k = 0; k < 2; ++k) sum->mean2d[k] += a.mean2d[k];
  for (int k = 0; k < 3; ++k) {
    sum->conic[k] += a.conic[k];
    sum->color[k] += a.color[k];
  }
  sum->opacity += a.opacity;
  sum->frame.axis_u += a.frame.axis_u;
  sum->frame.axis_v += a.frame.axis_v;
  sum->frame.normal += a.frame.normal;
  sum->frame.offset_u += a.frame.offset_u;
  sum->frame.offset_v += a.frame.offset_v;
  sum->frame.offset_n += a.frame.offset_n;
  sum->frame.inv_scale_u += a.frame.inv_scale_u;
  sum->frame.inv_scale_v += a.frame.inv_scale_v;
}

}  // namespace

template <typename T>
Status RasterizeBackward(const detail::CameraModel<T>& cam, const BasicTexturePool<T>* textures,
                         const RenderSettings& settings, const BasicRenderOutput<T>& fwd, const T* grad_color,
                         const T* grad_alpha, RasterGradients<T>* out) {
  const auto& st = fwd.state;
  const int width = cam.width, height = cam.height;
  const size_t n = fwd.radius.size();
  const size_t entries = st.tile_gaussians.size();
  const bool textured = textures != nullptr;

  // Per-entry texel gradient slots: entry e owns texel values [entry_texels[e], entry_texels[e+1]).
  std::vector<uint64_t> entry_texels(textured ? entries + 1 : 1, 0);  // [E+1]
  if (textured) {
    for (size_t e = 0; e < entries; ++e) {
      const size_t i = static_cast<size_t>(st.tile_gaussians[e]);
      entry_texels[e + 1] = entry_texels[e] + uint64_t(textures->heights[i]) * textures->widths[i] * kTexelChannels;
    }
    if (entry_texels[entries] > kMaxEntryTexelValues) {
      return MakeError(StatusCode::kLimitExceeded, "render backward: ", entry_texels[entries],
                       " per-tile texel gradients exceed the limit of ", kMaxEntryTexelValues);
    }
  }
  std::vector<detail::SplatGrad<T>> entry_grads(entries, detail::ZeroSplatGrad<T>());  // [E]
  std::vector<T> entry_texel_grads(entry_texels.back(), T(0));

  const int tiles = cam.tiles_x * cam.tiles_y;
  uint64_t longest = 0;
  for (int t = 0; t < tiles; ++t) longest = std::max(longest, st.tile_ranges[t + 1] - st.tile_ranges[t]);
  std::vector<detail::SplatParams<T>> scratch(size_t(MaxThreads()) * longest);  // [threads][longest]
  std::vector<T> scratch_skip(scratch.size());                                   // [threads][longest] SkipPowerBelow
  const Vec3<T> background{{T(settings.background[0]), T(settings.background[1]), T(settings.background[2])}};

#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 1) if (tiles >= kMinParallelTiles)
#endif
  for (int t = 0; t < tiles; ++t) {
    const uint64_t begin = st.tile_ranges[t], end = st.tile_ranges[t + 1];
    const int count = static_cast<int>(end - begin);
    if (count == 0) continue;
    detail::SplatParams<T>* splats = scratch.data() + size_t(ThreadIndex()) * longest;
    T* skip_below = scratch_skip.data() + size_t(ThreadIndex()) * longest;
    for (int k = 0; k < count; ++k) {
      splats[k] = MakeSplatParams(fwd, textures, st.tile_gaussians[begin + k]);
      skip_below[k] = SkipPowerBelow(splats[k]);
    }
    const int x0 = (t % cam.tiles_x) * detail::kTileSize, y0 = (t / cam.tiles_x) * detail::kTileSize;
    const int x1 = std::min(x0 + detail::kTileSize, width), y1 = std::min(y0 + detail::kTileSize, height);
    for (int y = y0; y < y1; ++y) {
      for (int x = x0; x < x1; ++x) {
        const size_t p = size_t(y) * width + x;
        const int last = st.contributor_end[p];
        if (last == 0) continue;
        const T px = T(x) + T(0.5), py = T(y) + T(0.5);
        const Vec3<T> ray = textured ? detail::PixelRayDirection(cam, px, py) : Vec3<T>{{T(0), T(0), T(1)}};
        const Vec3<T> g_pixel{{grad_color[3 * p], grad_color[3 * p + 1], grad_color[3 * p + 2]}};
        const T g_pixel_alpha = grad_alpha != nullptr ? grad_alpha[p] : T(0);
        const T final_transmittance = st.final_transmittance[p];
        T transmittance = final_transmittance;  // T after the splat being visited
        Vec3<T> back = final_transmittance * background;  // Σ_{j>i} c̃_j w_j + T_final b
        for (int k = last - 1; k >= 0; --k) {
          const auto& sp = splats[k];
          if (detail::GaussianPower(sp.conic, px - sp.mean2d[0], py - sp.mean2d[1]) < skip_below[k]) continue;
          const detail::SplatSample<T> s = detail::EvaluateSplat(sp, px, py, ray);
          if (!s.contributes) continue;
          const T before = transmittance / (T(1) - s.alpha);
          Vec3<T> g_color;
          const T g_alpha = detail::BlendStepVjp(s.alpha, s.color, before, back, final_transmittance, g_pixel,
                                                 g_pixel_alpha, &g_color);
          const uint64_t e = begin + k;
          T* g_texels = textured ? entry_texel_grads.data() + entry_texels[e] : nullptr;
          detail::EvaluateSplatVjp(splats[k], ray, s, g_color, g_alpha, &entry_grads[e], g_texels);
          back += (s.alpha * before) * s.color;
          transmittance = before;
        }
      }
    }
  }

  // Per Gaussian: the pairs in ascending tile order.
  out->splats.assign(n, detail::ZeroSplatGrad<T>());
  out->texels.assign(textured ? textures->texels.size() : 0, T(0));
  const int64_t gaussians = static_cast<int64_t>(n);
#ifdef _OPENMP
#pragma omp parallel for schedule(static) if (gaussians >= kMinParallelGaussians)
#endif
  for (int64_t i = 0; i < gaussians; ++i) {
    detail::SplatGrad<T> sum = detail::ZeroSplatGrad<T>();
    T* g_texels = textured ? out->texels.data() + textures->offsets[i] * kTexelChannels : nullptr;
    for (uint64_t k = st.gaussian_entry_ranges[i]; k < st.gaussian_entry_ranges[i + 1]; ++k) {
      const uint64_t e = st.gaussian_entries[k];
      AddSplatGrad(entry_grads[e], &sum);
      if (textured) {
        const uint64_t values = entry_texels[e + 1] - entry_texels[e];
        for (uint64_t v = 0; v < values; ++v) g_texels[v] += entry_texel_grads[entry_texels[e] + v];
      }
    }
    out->splats[i] = sum;
  }
  return Status::Ok();
}

#define ATEX_INSTANTIATE(T)                                                                                      \
  template Status RasterizeBackward(const detail::CameraModel<T>&, const BasicTexturePool<T>*,                 \
                                    const RenderSettings&, const BasicRenderOutput<T>&, const T*, const T*,    \
                                    RasterGradients<T>*);
ATEX_INSTANTIATE(float)
ATEX_INSTANTIATE(double)
#undef ATEX_INSTANTIATE

}  // namespace atex::render_internal
