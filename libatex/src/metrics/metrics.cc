// PSNR, SSIM, DSSIM on Image values (double precision throughout).
#include <cmath>
#include <limits>

#include "atex/metrics.h"
#include "metrics/ssim_core.h"

namespace atex {
namespace {

Status CheckPair(const Image& a, const Image& b) {
  if (a.width != b.width || a.height != b.height || a.channels != b.channels) {
    return MakeError(StatusCode::kInvalidArgument, "image sizes differ: ", a.width, "x", a.height, "x", a.channels,
                     " vs ", b.width, "x", b.height, "x", b.channels);
  }
  if (a.width <= 0 || a.height <= 0 || a.channels <= 0) {
    return MakeError(StatusCode::kInvalidArgument, "empty image (", a.width, "x", a.height, "x", a.channels, ")");
  }
  const size_t n = size_t(a.width) * a.height * a.channels;
  if (a.pixels.size() != n || b.pixels.size() != n) {
    return MakeError(StatusCode::kInvalidArgument, "image pixel arrays hold ", a.pixels.size(), " and ",
                     b.pixels.size(), " values, expected ", n);
  }
  for (size_t i = 0; i < n; ++i) {
    if (!std::isfinite(a.pixels[i]) || !std::isfinite(b.pixels[i])) {
      return MakeError(StatusCode::kOutOfRange, "non-finite pixel value at element ", i);
    }
  }
  return Status::Ok();
}

// The constants and window of SSIM with `options` (C1 = (0.01 R)², C2 = (0.03 R)²).
metrics_detail::SsimParams ParamsOf(const SsimOptions& options) {
  metrics_detail::SsimParams params;
  params.c1 = (0.01 * options.data_range) * (0.01 * options.data_range);
  params.c2 = (0.03 * options.data_range) * (0.03 * options.data_range);
  params.window = options.window;
  params.sigma = options.sigma;
  params.valid = options.padding == SsimPadding::kValid;
  return params;
}

std::vector<double> ToDouble(const Image& image) {
  return std::vector<double>(image.pixels.begin(), image.pixels.end());
}

}  // namespace

StatusOr<double> Psnr(const Image& a, const Image& b, double data_range) {
  ATEX_RETURN_IF_ERROR(CheckPair(a, b));
  if (!(data_range > 0)) return MakeError(StatusCode::kInvalidArgument, "PSNR data range ", data_range);
  double sum = 0;
  for (size_t i = 0; i < a.pixels.size(); ++i) {
    const double d = double(a.pixels[i]) - double(b.pixels[i]);
    sum += d * d;
  }
  const double mse = sum / double(a.pixels.size());
  if (mse == 0) return std::numeric_limits<double>::infinity();
  return 10.0 * std::log10(data_range * data_range / mse);
}

StatusOr<double> Ssim(const Image& a, const Image& b, const SsimOptions& options) {
  ATEX_RETURN_IF_ERROR(CheckPair(a, b));
  if (options.window < 1 || options.window % 2 == 0 || !(options.sigma > 0) || !(options.data_range > 0)) {
    return MakeError(StatusCode::kInvalidArgument, "SSIM options: window ", options.window, " (odd, >= 1), sigma ",
                     options.sigma, ", data range ", options.data_range);
  }
  const metrics_detail::SsimParams params = ParamsOf(options);
  if (params.valid && (a.width < options.window || a.height < options.window)) {
    return MakeError(StatusCode::kInvalidArgument, "SSIM with valid padding needs images of at least ",
                     options.window, "x", options.window, ", got ", a.width, "x", a.height);
  }
  const std::vector<double> x = ToDouble(a), y = ToDouble(b);
  return metrics_detail::SsimMeanAndGrad<double>(x.data(), y.data(), a.width, a.height, a.channels, params, 0.0,
                                                 nullptr);
}

StatusOr<double> Dssim(const Image& a, const Image& b, double data_range) {
  SsimOptions options;
  options.data_range = data_range;
  ATEX_ASSIGN_OR_RETURN(const double ssim, Ssim(a, b, options));
  return (1.0 - ssim) / 2.0;
}

StatusOr<ImageMetrics> CompareImages(const Image& rendered, const Image& target) {
  ATEX_RETURN_IF_ERROR(CheckPair(rendered, target));
  ImageMetrics m;
  double abs_sum = 0, sq_sum = 0;
  for (size_t i = 0; i < rendered.pixels.size(); ++i) {
    const double d = double(rendered.pixels[i]) - double(target.pixels[i]);
    abs_sum += std::abs(d);
    sq_sum += d * d;
  }
  m.l1 = abs_sum / double(rendered.pixels.size());
  m.mse = sq_sum / double(rendered.pixels.size());
  m.psnr = m.mse == 0 ? std::numeric_limits<double>::infinity() : -10.0 * std::log10(m.mse);
  // SSIM at the default options (data range 1) and DSSIM at data range 2 share their filtered
  // maps: one pass over the images, the values Ssim and Dssim give.
  SsimOptions range2;
  range2.data_range = 2.0;
  const std::vector<double> x = ToDouble(rendered), y = ToDouble(target);
  std::vector<double> ssims;
  metrics_detail::SsimMeans(x.data(), y.data(), rendered.width, rendered.height, rendered.channels,
                            {ParamsOf(SsimOptions{}), ParamsOf(range2)}, &ssims);
  m.ssim = ssims[0];
  m.dssim1 = (1.0 - m.ssim) / 2.0;
  m.dssim2 = (1.0 - ssims[1]) / 2.0;
  return m;
}

}  // namespace atex
