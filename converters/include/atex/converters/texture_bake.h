// Texture baking for players that know nothing of textures (issue 21 item 5).
//
// KHR_gaussian_splatting (and PLY, SPZ, SOG...) carry plain Gaussians only, so a player drops
// each Gaussian's texture plane (docs/conventions.md §5: colour + 0.1·tanh(r), opacity ·
// exp(0.1·tanh(a)), bilinear over a 1x1..4x4 corner-aligned grid spanning ±1 standard deviation
// of the plane's two axes). BakeTextures replaces every textured Gaussian by plain ones whose sum
// approximates its textured footprint:
//   * a 1x1 texture is constant over the plane: it folds exactly into the DC colour and the
//     opacity (one Gaussian, only min(0.99, ·) of the renderer's clamp differs);
//   * a larger texture splits the Gaussian into 2 children along each texture axis whose side is
//     greater than 1 (2 or 4 children), placed in the plane, fitted as texture_bake.cc explains,
//     unless that fit is not clearly better than folding (opaque parents, textures that
//     alternate per texel): then it is folded like a 1x1.
// The result has no texture pool; everything else (rotation, normal-axis scale, higher SH bands,
// time windows) is copied from the parent.
#pragma once

#include <cstddef>

#include "atex/model.h"
#include "atex/status.h"

namespace atex {

struct TextureBakeOptions {
  // Gauss-Newton steps fitting the children's opacities to the textured opacity profile
  // (0: the closed-form moment match only). The colours are then one linear least-squares solve.
  int fit_iterations = 8;
  // Samples per axis of the fit grid over [−3, 3] standard deviations of the plane (>= 5).
  int grid = 25;
};

struct TextureBakeReport {
  size_t input_gaussians = 0;
  size_t output_gaussians = 0;
  size_t folded = 0;       // Gaussians kept as one, their texture folded in (fold_better included)
  size_t split = 0;        // Gaussians replaced by 2 or 4 children
  size_t fold_better = 0;  // textured (> 1x1, not constant) but folded: the children fitted too little better
  // Over the textured Gaussians (> 1x1, not constant), on each one's fit grid: the RMS of the
  // layer error (texture_bake.cc, LayerError: half the opacity error plus the premultiplied
  // colour error, image units) of the baked result, and of the parent without its texture (what
  // a player shows without baking).
  double fit_rms = 0, unbaked_rms = 0;
};

// The baked Gaussians (plain, same SH degree). `textures` must describe `gaussians`
// (ValidateTexturePool). Deterministic: the same input gives the same bytes.
// Errors: kInvalidArgument (pool and Gaussians disagree, bad options), kOutOfRange (a
// non-finite position, scale, logit or texel, naming the element), kLimitExceeded (memory).
StatusOr<Gaussians> BakeTextures(const Gaussians& gaussians, const TexturePool& textures,
                                 const TextureBakeOptions& options = {}, TextureBakeReport* report = nullptr);

}  // namespace atex
