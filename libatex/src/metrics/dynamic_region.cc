#include "atex/dynamic_region.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace atex {

Status TemporalVariance::Add(const Image& frame) {
  if (frame.channels < 3) {
    return MakeError(StatusCode::kInvalidArgument, "dynamic region: frame has ", frame.channels,
                     " channels, needs at least 3");
  }
  if (frames_ == 0) {
    width_ = frame.width;
    height_ = frame.height;
    mean_.assign(size_t(width_) * height_ * 3, 0.0);
    m2_.assign(mean_.size(), 0.0);
  } else if (frame.width != width_ || frame.height != height_) {
    return MakeError(StatusCode::kInvalidArgument, "dynamic region: frame ", frames_, " is ", frame.width, "x",
                     frame.height, ", the camera's first frame is ", width_, "x", height_);
  }
  ++frames_;
  const size_t pixels = size_t(width_) * height_;
  const double inv_n = 1.0 / frames_;
  for (size_t p = 0; p < pixels; ++p) {
    for (int c = 0; c < 3; ++c) {
      const double x = frame.pixels[p * frame.channels + c];
      double& mean = mean_[p * 3 + c];
      const double delta = x - mean;
      mean += delta * inv_n;
      m2_[p * 3 + c] += delta * (x - mean);
    }
  }
  return Status::Ok();
}

StatusOr<DynamicRegion> TemporalVariance::Region(double threshold) const {
  if (!std::isfinite(threshold) || threshold < 0) {
    return MakeError(StatusCode::kInvalidArgument, "dynamic region: threshold ", threshold,
                     " must be finite and >= 0");
  }
  if (frames_ < 2) {
    return MakeError(StatusCode::kInvalidArgument, "dynamic region: needs at least two frames of one camera, has ",
                     frames_);
  }
  DynamicRegion region;
  region.width = width_;
  region.height = height_;
  region.mask.assign(size_t(width_) * height_, 0);
  // σ² (RMS over channels) = (m2_R + m2_G + m2_B) / (3 n).
  const double limit = threshold * threshold * 3.0 * frames_;
  for (size_t p = 0; p < region.mask.size(); ++p) {
    const double m2 = m2_[p * 3] + m2_[p * 3 + 1] + m2_[p * 3 + 2];
    if (m2 > limit) {
      region.mask[p] = 1;
      ++region.count;
    }
  }
  return region;
}

StatusOr<double> RegionPsnr(const Image& rendered, const Image& target, const DynamicRegion& region) {
  for (const Image* image : {&rendered, &target}) {
    if (image->width != region.width || image->height != region.height || image->channels < 3) {
      return MakeError(StatusCode::kInvalidArgument, "region PSNR: image ", image->width, "x", image->height, "x",
                       image->channels, " does not match the region's ", region.width, "x", region.height, "x3");
    }
  }
  if (region.count == 0) return MakeError(StatusCode::kInvalidArgument, "region PSNR: the region is empty");
  double sum = 0;
  for (size_t p = 0; p < region.mask.size(); ++p) {
    if (!region.mask[p]) continue;
    for (int c = 0; c < 3; ++c) {
      const double a = std::clamp(rendered.pixels[p * rendered.channels + c], 0.0f, 1.0f);
      const double d = a - target.pixels[p * target.channels + c];
      sum += d * d;
    }
  }
  const double mse = sum / (3.0 * region.count);
  if (mse == 0) return std::numeric_limits<double>::infinity();
  return 10.0 * std::log10(1.0 / mse);
}

}  // namespace atex
