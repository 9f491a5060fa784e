// Marked-pixel compositing (tile_composite.h).
#include "tile_composite.h"

#include <algorithm>
#include <cmath>
#include <vector>

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
  // What the skip test reads of each splat, packed (the loop below tests many splats per
  // pixel and evaluates few of them): the same values, so the same test.
  struct SkipTest {
    float mean_x, mean_y, conic[3], skip_below;
    int k;  // in `list`
  };
  // Blocks of kBlock × kBlock pixels walk only the splats whose box meets the block: the
  // others fail the skip test at each of its pixels, where the reference loop passes them by.
  // Each block holds its splats' tests in list order, contiguous.
  constexpr int kBlock = 4, kBlocks = detail::kTileSize / kBlock;
  thread_local std::vector<SkipTest> near[kBlocks * kBlocks];  // per block of the tile; empty when unmarked
  for (int by = 0; by < kBlocks; ++by) {
    for (int bx = 0; bx < kBlocks; ++bx) {
      std::vector<SkipTest>& list_of_block = near[by * kBlocks + bx];
      list_of_block.clear();
      const PixelBox block{tile.x0 + bx * kBlock, std::min(tile.x0 + (bx + 1) * kBlock, tile.x1),
                           tile.y0 + by * kBlock, std::min(tile.y0 + (by + 1) * kBlock, tile.y1)};
      bool marked = false;
      for (int y = block.y0; y < block.y1 && !marked; ++y) {
        for (int x = block.x0; x < block.x1 && !marked; ++x) {
          marked = mask[(y - tile.y0) * detail::kTileSize + (x - tile.x0)];
        }
      }
      if (!marked) continue;
      for (int k = 0; k < count; ++k) {
        const PixelBox& b = list.reach[k].box;
        if (b.x0 < block.x1 && block.x0 < b.x1 && b.y0 < block.y1 && block.y0 < b.y1) {
          const auto& sp = splats[k];
          list_of_block.push_back(
              {sp.mean2d[0], sp.mean2d[1], {sp.conic[0], sp.conic[1], sp.conic[2]}, list.reach[k].skip_below, k});
        }
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
      for (const SkipTest& test : near[((y - tile.y0) / kBlock) * kBlocks + (x - tile.x0) / kBlock]) {
        const int k = test.k;
        const detail::Vec3<float> conic{{test.conic[0], test.conic[1], test.conic[2]}};
        const float power = detail::GaussianPower(conic, px - test.mean_x, py - test.mean_y);
        if (power < test.skip_below) continue;
        const detail::SplatSample<float> s = detail::EvaluateSplat(splats[k], px, py, ray);
        if (!s.contributes) continue;
        const float next = transmittance * (1.0f - s.alpha);
        if (next < float(detail::kMinTransmittance)) {
          stop = StopKey{list.depths[k], list.indices[k]};
          break;
        }
        const float w = s.alpha * transmittance;
        for (int ch = 0; ch < 3; ++ch) c[ch] += s.color[ch] * w;
        if (weights != nullptr) weights[k] += w;
        transmittance = next;
      }
      const size_t p = size_t(y) * size_t(cam.width) + size_t(x);
      for (int ch = 0; ch < 3; ++ch) color[3 * p + ch] = c[ch] + transmittance * background[ch];
      stops[p] = stop;
    }
  }
}

}  // namespace atex::fit::internal
