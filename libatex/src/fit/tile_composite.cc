// Marked-pixel compositing (tile_composite.h).
#include "tile_composite.h"

#include <algorithm>
#include <cmath>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "render/render_internal.h"

namespace atex::fit::internal {

namespace {

PixelBox TileBox(const detail::CameraModel<float>& cam, int t) {
  const int x0 = (t % cam.tiles_x) * detail::kTileSize, y0 = (t / cam.tiles_x) * detail::kTileSize;
  return {x0, std::min(x0 + detail::kTileSize, cam.width), y0, std::min(y0 + detail::kTileSize, cam.height)};
}

PixelBox Clip(const PixelBox& a, const PixelBox& b) {
  return {std::max(a.x0, b.x0), std::min(a.x1, b.x1), std::max(a.y0, b.y0), std::min(a.y1, b.y1)};
}

// What the reference loop's skip test reads of four splats (lanes in list order).
struct SkipQuad {
  float mean_x[4], mean_y[4], conic_a[4], conic_b[4], conic_c[4], skip_below[4];
  int k[4];  // the splat's position in the tile's list; -1: padding
};

SkipQuad EmptyQuad() {
  SkipQuad q{};
  for (int l = 0; l < 4; ++l) q.k[l] = -1;
  return q;
}

// Bit l set: lane l passes the skip test at pixel centre (px, py), i.e. !(power <
// skip_below) with power = detail::GaussianPower's −½(A Δx² + C Δy²) − B Δx Δy, computed
// with the same float operations in the same order (no contraction: SSE has no FMA).
unsigned PassingLanes(const SkipQuad& q, float px, float py) {
#if defined(__SSE2__)
  const __m128 dx = _mm_sub_ps(_mm_set1_ps(px), _mm_loadu_ps(q.mean_x));
  const __m128 dy = _mm_sub_ps(_mm_set1_ps(py), _mm_loadu_ps(q.mean_y));
  const __m128 ax = _mm_mul_ps(_mm_mul_ps(_mm_loadu_ps(q.conic_a), dx), dx);
  const __m128 cy = _mm_mul_ps(_mm_mul_ps(_mm_loadu_ps(q.conic_c), dy), dy);
  const __m128 half = _mm_mul_ps(_mm_set1_ps(-0.5f), _mm_add_ps(ax, cy));
  const __m128 power = _mm_sub_ps(half, _mm_mul_ps(_mm_mul_ps(_mm_loadu_ps(q.conic_b), dx), dy));
  unsigned bits = unsigned(_mm_movemask_ps(_mm_cmpnlt_ps(power, _mm_loadu_ps(q.skip_below))));
#else
  unsigned bits = 0;
  for (int l = 0; l < 4; ++l) {
    const detail::Vec3<float> conic{{q.conic_a[l], q.conic_b[l], q.conic_c[l]}};
    bits |= unsigned(!(detail::GaussianPower(conic, px - q.mean_x[l], py - q.mean_y[l]) < q.skip_below[l])) << l;
  }
#endif
  for (int l = 0; l < 4; ++l) bits &= q.k[l] >= 0 ? ~0u : ~(1u << l);
  return bits;
}

}  // namespace

// Outside the ellipse power = skip_below (conic (A, B, C): A dx² + 2B dx dy + C dy² ≤ r with
// r = −2 skip_below, so |dx| ≤ sqrt(r C / det) and |dy| ≤ sqrt(r A / det)) no pixel passes the
// test. The box only saves tests, so it is widened against the float rounding of the test.
SplatReach ReachOf(const detail::CameraModel<float>& cam, const detail::SplatParams<float>& splat) {
  SplatReach reach;
  reach.skip_below = render_internal::SkipPowerBelow(splat);
  const PixelBox image{0, cam.width, 0, cam.height};
  const double a = splat.conic[0], b = splat.conic[1], c = splat.conic[2], det = a * c - b * b;
  const double r = -2.0 * double(reach.skip_below);
  if (r < 0) return reach;  // skip_below > 0: the power (≤ 0 where anything is evaluated) never reaches it
  reach.box = image;
  if (!(det > 0 && a > 0 && c > 0 && std::isfinite(r) && std::isfinite(det))) return reach;
  const double half_x = std::sqrt(r * c / det) * 1.001 + 2.0, half_y = std::sqrt(r * a / det) * 1.001 + 2.0;
  const double mx = splat.mean2d[0], my = splat.mean2d[1];
  if (!std::isfinite(half_x) || !std::isfinite(half_y) || !std::isfinite(mx) || !std::isfinite(my)) return reach;
  const auto clamp = [](double v, int lo, int hi) { return int(std::clamp(v, double(lo), double(hi))); };
  reach.box = {clamp(std::floor(mx - half_x), 0, cam.width), clamp(std::ceil(mx + half_x), 0, cam.width),
               clamp(std::floor(my - half_y), 0, cam.height), clamp(std::ceil(my + half_y), 0, cam.height)};
  return reach;
}

bool MarkPixels(const detail::CameraModel<float>& cam, int t, const detail::SplatParams<float>& splat,
                const SplatReach& reach, float depth, uint32_t index, const StopKey* stops,
                uint8_t mask[kTilePixels]) {
  const PixelBox tile = TileBox(cam, t);
  const PixelBox box = Clip(reach.box, tile);
  bool any = false;
  for (int y = box.y0; y < box.y1; ++y) {
    for (int x = box.x0; x < box.x1; ++x) {
      const float px = float(x) + 0.5f, py = float(y) + 0.5f;
      // The reference loop skips the splat where power < skip_below; elsewhere it may count.
      if (detail::GaussianPower(splat.conic, px - splat.mean2d[0], py - splat.mean2d[1]) < reach.skip_below) continue;
      if (!Before(depth, index, stops[size_t(y) * size_t(cam.width) + size_t(x)])) continue;
      mask[(y - tile.y0) * detail::kTileSize + (x - tile.x0)] = 1;
      any = true;
    }
  }
  return any;
}

void CompositePixels(const detail::CameraModel<float>& cam, int t, const TileList& list,
                     const detail::Vec3<float>& background, const uint8_t mask[kTilePixels], float* color,
                     StopKey* stops, float* weights) {
  const PixelBox tile = TileBox(cam, t);
  const detail::SplatParams<float>* splats = list.splats;
  const int count = list.count;
  const bool textured = count > 0 && splats[0].frame != nullptr;  // all or none of a render's splats are
  // Blocks of kBlock × kBlock pixels walk only the splats whose box meets the block: the
  // others fail the skip test at each of its pixels, where the reference loop passes them by.
  // Each block holds what the skip test reads of its splats, packed four by four in list
  // order (SkipQuad), so that one pixel tests four splats at once, with the reference's
  // float operations in the reference's order on each: the same outcomes.
  constexpr int kBlock = 4, kBlocks = detail::kTileSize / kBlock;
  thread_local std::vector<SkipQuad> near[kBlocks * kBlocks];  // per block of the tile; empty when unmarked
  for (int by = 0; by < kBlocks; ++by) {
    for (int bx = 0; bx < kBlocks; ++bx) {
      std::vector<SkipQuad>& quads = near[by * kBlocks + bx];
      quads.clear();
      const PixelBox block{tile.x0 + bx * kBlock, std::min(tile.x0 + (bx + 1) * kBlock, tile.x1),
                           tile.y0 + by * kBlock, std::min(tile.y0 + (by + 1) * kBlock, tile.y1)};
      bool marked = false;
      for (int y = block.y0; y < block.y1 && !marked; ++y) {
        for (int x = block.x0; x < block.x1 && !marked; ++x) {
          marked = mask[(y - tile.y0) * detail::kTileSize + (x - tile.x0)];
        }
      }
      if (!marked) continue;
      int lane = 4;
      for (int k = 0; k < count; ++k) {
        const PixelBox& b = list.reach[k].box;
        if (!(b.x0 < block.x1 && block.x0 < b.x1 && b.y0 < block.y1 && block.y0 < b.y1)) continue;
        if (lane == 4) quads.push_back(EmptyQuad()), lane = 0;
        const auto& sp = splats[k];
        SkipQuad& q = quads.back();
        q.mean_x[lane] = sp.mean2d[0], q.mean_y[lane] = sp.mean2d[1];
        q.conic_a[lane] = sp.conic[0], q.conic_b[lane] = sp.conic[1], q.conic_c[lane] = sp.conic[2];
        q.skip_below[lane] = list.reach[k].skip_below;
        q.k[lane++] = k;
      }
    }
  }
  // Pixels in row-major order, as the reference (the order the weights are summed in).
  for (int y = tile.y0; y < tile.y1; ++y) {
    for (int x = tile.x0; x < tile.x1; ++x) {
      if (!mask[(y - tile.y0) * detail::kTileSize + (x - tile.x0)]) continue;
      // As render_internal::RasterizeTile, less what only the backward pass reads.
      const float px = float(x) + 0.5f, py = float(y) + 0.5f;
      const detail::Vec3<float> ray =
          textured ? detail::PixelRayDirection(cam, px, py) : detail::Vec3<float>{{0.0f, 0.0f, 1.0f}};
      float transmittance = 1.0f;
      detail::Vec3<float> c{{0.0f, 0.0f, 0.0f}};
      StopKey stop = kNeverStopped;
      bool stopped = false;
      for (const SkipQuad& q : near[((y - tile.y0) / kBlock) * kBlocks + (x - tile.x0) / kBlock]) {
        // Lanes in list order; a padding lane (k < 0) never passes.
        for (unsigned pass = PassingLanes(q, px, py); pass != 0 && !stopped; pass &= pass - 1) {
          const int k = q.k[__builtin_ctz(pass)];
          const detail::SplatSample<float> s = detail::EvaluateSplat(splats[k], px, py, ray);
          if (!s.contributes) continue;
          const float next = transmittance * (1.0f - s.alpha);
          if (next < float(detail::kMinTransmittance)) {
            stop = StopKey{list.depths[k], list.indices[k]};
            stopped = true;
            break;
          }
          const float w = s.alpha * transmittance;
          for (int ch = 0; ch < 3; ++ch) c[ch] += s.color[ch] * w;
          if (weights != nullptr) weights[k] += w;
          transmittance = next;
        }
        if (stopped) break;
      }
      const size_t p = size_t(y) * size_t(cam.width) + size_t(x);
      for (int ch = 0; ch < 3; ++ch) color[3 * p + ch] = c[ch] + transmittance * background[ch];
      stops[p] = stop;
    }
  }
}

}  // namespace atex::fit::internal
