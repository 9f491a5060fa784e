// Test helpers of the render module: random small scenes, a naive reference
// renderer (every pixel against every Gaussian, no tile lists), and the discrete
// "signature" of a render — every branch the rasteriser took — that tells a
// finite-difference check whether a perturbation crossed a non-smooth point.
#pragma once

#include <cstdint>
#include <random>
#include <vector>

#include "atex/camera.h"
#include "atex/model.h"
#include "atex/render.h"

namespace atex::render_testing {

enum class TextureKind { kNone, kUniform, kAdaptiveMixed };

struct SceneOptions {
  int count = 16;                // Gaussians inside the view frustum
  int sh_degree = 3;
  TextureKind textures = TextureKind::kNone;
  bool opaque = false;           // opacities up to ~0.998 (reaches the 0.99 clamp and the T < 1e-4 stop)
  bool extras = true;            // + 2 large Gaussians beyond the Jacobian clamp, 1 behind the camera
  double texel_range = 1.5;      // texels uniform in [-range, range]
};

// A pinhole camera with a random rigid pose (looking roughly along +z of the world).
Camera RandomCamera(int width, int height, std::mt19937& rng);

template <typename T>
BasicGaussians<T> RandomGaussians(const Camera& camera, const SceneOptions& options, std::mt19937& rng);

// Textures for `g`: uniform 4x4, or adaptive sizes cycling through 1x1, 1x4, 4x1, 2x4,
// 4x2, 1x2, 2x1, 2x2, 4x4 and axes cycling through all six (p, q) pairs; random texels.
template <typename T>
BasicTexturePool<T> RandomTextures(const BasicGaussians<T>& g, TextureKind kind, double texel_range,
                                   std::mt19937& rng);

// Every discrete decision of a render: radii, tile lists (which include the depth
// order), contributor counts, per-Gaussian Jacobian and SH clamps, and per (pixel,
// splat) until the pixel stops: skipped or not, alpha clamp, u/v clamps, bilinear
// cells, plane-denominator substitution. Equal signatures ⇒ the rendered function
// is smooth between the two inputs.
template <typename T>
std::vector<int64_t> RenderSignature(const Camera& camera, const BasicGaussians<T>& g,
                                     const BasicTexturePool<T>* textures, const RenderSettings& settings,
                                     const BasicRenderOutput<T>& forward);
// Only the per-pixel part (for perturbations of the rasteriser's inputs).
template <typename T>
std::vector<int64_t> PixelSignature(const Camera& camera, const BasicTexturePool<T>* textures,
                                    const BasicRenderOutput<T>& forward);

// Naive reference: for each pixel, all visible Gaussians whose tile rectangle
// contains the pixel's tile, sorted by (depth, index), composited with
// detail::EvaluateSplat. Colour [H][W][3] and alpha [H][W].
template <typename T>
void NaiveRender(const Camera& camera, const BasicGaussians<T>& g, const BasicTexturePool<T>* textures,
                 const RenderSettings& settings, std::vector<T>* color, std::vector<T>* alpha);

}  // namespace atex::render_testing
