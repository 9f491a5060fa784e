// Dynamic-region PSNR: quality where the scene moves.
//
// A whole-image PSNR on a multi-view video is dominated by the static background
// (on CMU Panoptic about 80-95 % of a test camera's pixels): a model that drops a
// fast ball or blurs a player loses a fraction of a dB there. The dynamic region of a
// fixed camera is the set of pixels whose ground truth changes over the sequence:
//
//   σ(p) = sqrt( (σ_R(p)² + σ_G(p)² + σ_B(p)²) / 3 ),   dynamic(p) ⇔ σ(p) > τ,
//
// σ_c(p) the population standard deviation over the camera's frames of channel c at
// pixel p (values in [0, 1]). The RMS over channels keeps a colour change of equal
// luminance (a red ball in front of a grey wall) in the region. τ = 0.05 is about 12×
// the median temporal noise of a static Panoptic pixel (JPEG and sensor noise,
// σ ≈ 0.004) and below the σ of a pixel that a high-contrast object (|ΔI| ≈ 0.4)
// covers in 2 of 30 frames (0.4·sqrt(p(1−p)) ≈ 0.10). A brief event in a much longer
// sequence has a smaller σ: lower τ there (`atex eval --dynamic-threshold`).
//
// The region's PSNR of one frame is 10·log10(1 / MSE) with the MSE over the region's
// pixels and all three channels (renders clamped to [0, 1], as every evaluation).
#pragma once

#include <cstdint>
#include <vector>

#include "atex/image.h"
#include "atex/status.h"

namespace atex {

inline constexpr double kDefaultDynamicThreshold = 0.05;

// A per-pixel mask [height][width] of one camera's dynamic region.
struct DynamicRegion {
  int width = 0;
  int height = 0;
  std::vector<uint8_t> mask;  // 1 = dynamic
  size_t count = 0;           // pixels in the region
  double fraction() const { return mask.empty() ? 0.0 : double(count) / double(mask.size()); }
};

// Accumulates the per-pixel temporal mean and variance of one camera's frames
// (Welford's update in double, so 150+ frames lose no precision).
class TemporalVariance {
 public:
  // Adds one frame: [height][width][>= 3 channels]; the first fixes the shape.
  // kInvalidArgument for another shape or fewer than 3 channels.
  Status Add(const Image& frame);
  int frames() const { return frames_; }
  // The region of pixels with σ > threshold (threshold >= 0, finite). With fewer than
  // two frames nothing can change: kInvalidArgument.
  StatusOr<DynamicRegion> Region(double threshold) const;

 private:
  int width_ = 0, height_ = 0, frames_ = 0;
  std::vector<double> mean_;  // [H][W][3]
  std::vector<double> m2_;    // [H][W][3] sum of squared deviations
};

// PSNR (dB, data range 1) of `rendered` against `target` over the region's pixels.
// Both images have the region's width and height and >= 3 channels (the first three
// are compared); rendered values are clamped to [0, 1]. +infinity when they agree
// exactly there; kInvalidArgument for an empty region.
StatusOr<double> RegionPsnr(const Image& rendered, const Image& target, const DynamicRegion& region);

}  // namespace atex
