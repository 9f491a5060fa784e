// Stage 3: front-to-back compositing per pixel, one 16×16 tile per task
// (conventions §5).
#include <algorithm>

#include "render/parallel.h"
#include "render/render_internal.h"

namespace atex::render_internal {

using detail::Vec3;

template <typename T>
void RasterizeTile(const detail::CameraModel<T>& cam, const BasicTexturePool<T>* textures, const Vec3<T>& background,
                   int t, detail::SplatParams<T>* splats, T* skip_below, T* weights, BasicRenderOutput<T>* out) {
  auto& st = out->state;
  const int width = cam.width, height = cam.height;
  const uint64_t begin = st.tile_ranges[t], end = st.tile_ranges[t + 1];
  const int count = static_cast<int>(end - begin);
  const bool textured = textures != nullptr;
  for (int k = 0; k < count; ++k) {
    splats[k] = MakeSplatParams(*out, textures, st.tile_gaussians[begin + k]);
    skip_below[k] = SkipPowerBelow(splats[k]);
  }
  const int x0 = (t % cam.tiles_x) * detail::kTileSize, y0 = (t / cam.tiles_x) * detail::kTileSize;
  const int x1 = std::min(x0 + detail::kTileSize, width), y1 = std::min(y0 + detail::kTileSize, height);
  for (int y = y0; y < y1; ++y) {
    for (int x = x0; x < x1; ++x) {
      const T px = T(x) + T(0.5), py = T(y) + T(0.5);
      const Vec3<T> ray = textured ? detail::PixelRayDirection(cam, px, py) : Vec3<T>{{T(0), T(0), T(1)}};
      T transmittance = T(1);
      Vec3<T> color{{T(0), T(0), T(0)}};
      int last = 0;
      for (int k = 0; k < count; ++k) {
        const auto& sp = splats[k];
        if (detail::GaussianPower(sp.conic, px - sp.mean2d[0], py - sp.mean2d[1]) < skip_below[k]) continue;
        const detail::SplatSample<T> s = detail::EvaluateSplat(sp, px, py, ray);
        if (!s.contributes) continue;
        const T next = transmittance * (T(1) - s.alpha);
        if (next < T(detail::kMinTransmittance)) break;
        const T w = s.alpha * transmittance;
        for (int ch = 0; ch < 3; ++ch) color[ch] += s.color[ch] * w;
        if (weights != nullptr) weights[k] += w;
        transmittance = next;
        last = k + 1;
      }
      const size_t p = size_t(y) * width + x;
      for (int ch = 0; ch < 3; ++ch) out->color[3 * p + ch] = color[ch] + transmittance * background[ch];
      out->alpha[p] = T(1) - transmittance;
      st.final_transmittance[p] = transmittance;
      st.contributor_end[p] = last;
    }
  }
}

template <typename T>
void RasterizeForward(const detail::CameraModel<T>& cam, const BasicTexturePool<T>* textures,
                      const RenderSettings& settings, BasicRenderOutput<T>* out) {
  auto& st = out->state;
  const int width = cam.width, height = cam.height;
  const size_t pixels = size_t(width) * size_t(height);
  const size_t n = out->radius.size();
  out->color.assign(pixels * 3, T(0));
  out->alpha.assign(pixels, T(0));
  st.final_transmittance.assign(pixels, T(1));
  st.contributor_end.assign(pixels, 0);
  std::vector<T> entry_weight(st.tile_gaussians.size(), T(0));  // [E] Σ_pixels w of each (tile, Gaussian) pair

  const int tiles = cam.tiles_x * cam.tiles_y;
  const uint64_t longest = LongestTile(*out);
  // Per-thread copy of the current tile's splats (gsplat's shared-memory batch).
  std::vector<detail::SplatParams<T>> scratch(size_t(MaxThreads()) * longest);  // [threads][longest]
  std::vector<T> scratch_skip(scratch.size());                                   // [threads][longest] SkipPowerBelow
  const Vec3<T> background{{T(settings.background[0]), T(settings.background[1]), T(settings.background[2])}};

#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 1) if (tiles >= kMinParallelTiles)
#endif
  for (int t = 0; t < tiles; ++t) {
    RasterizeTile(cam, textures, background, t, scratch.data() + size_t(ThreadIndex()) * longest,
                  scratch_skip.data() + size_t(ThreadIndex()) * longest, entry_weight.data() + st.tile_ranges[t], out);
  }

  // Importance: the pairs' sums in ascending tile order (same result for any thread count).
  out->importance.assign(n, T(0));
  const int64_t gaussians = static_cast<int64_t>(n);
#ifdef _OPENMP
#pragma omp parallel for schedule(static) if (gaussians >= kMinParallelGaussians)
#endif
  for (int64_t i = 0; i < gaussians; ++i) {
    T sum = T(0);
    for (uint64_t k = st.gaussian_entry_ranges[i]; k < st.gaussian_entry_ranges[i + 1]; ++k) {
      sum += entry_weight[st.gaussian_entries[k]];
    }
    out->importance[i] = sum;
  }
}

template void RasterizeForward(const detail::CameraModel<float>&, const BasicTexturePool<float>*,
                               const RenderSettings&, BasicRenderOutput<float>*);
template void RasterizeForward(const detail::CameraModel<double>&, const BasicTexturePool<double>*,
                               const RenderSettings&, BasicRenderOutput<double>*);
template void RasterizeTile(const detail::CameraModel<float>&, const BasicTexturePool<float>*, const Vec3<float>&, int,
                            detail::SplatParams<float>*, float*, float*, BasicRenderOutput<float>*);

}  // namespace atex::render_internal
