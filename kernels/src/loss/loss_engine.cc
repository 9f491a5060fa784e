// LossEngine: the photometric loss L = (1 - λ)·mean|x − y| + λ·(1 − SSIM(x, y)) and its
// gradient, scheduled as forward (moments, SSIM map, derivative maps, sums) ->
// backward (blurred derivative maps -> gradient) -> a one-thread finalize that adds the
// scaled loss to the caller's device scalar. Nothing synchronises (except Ssim, which
// returns to the host).
#include <cmath>
#include <limits>
#include <vector>

#include "cuda_check.h"
#include "device_buffer.h"
#include "loss/loss_cuda.h"
#include "loss/ssim_kernels.h"

namespace atex::cuda {
namespace {

constexpr double kSsimSigma = 1.5;
constexpr int kMaxSide = 1 << 20;  // grid.y limit (65535 blocks) x 14 rows, and int pixel indices

Status CheckImage(const char* what, const float* a, const float* b, int width, int height) {
  if (a == nullptr || b == nullptr) return MakeError(StatusCode::kInvalidArgument, what, ": null image");
  if (width < 1 || height < 1 || width > kMaxSide || height > kMaxSide / 2) {
    return MakeError(StatusCode::kInvalidArgument, what, ": image size ", width, "x", height, " out of range");
  }
  return Status::Ok();
}

}  // namespace

struct LossEngine::Impl {
  cudaStream_t stream = nullptr;
  loss_detail::GaussianWindow window = loss_detail::MakeGaussianWindow(kSsimSigma);
  DeviceBuffer<float> maps;       // [3][H][W][3]: dS/dmu_x, dS/dE[x^2], dS/dE[xy]
  DeviceBuffer<double> sums;      // [3]: sum(1 - S), sum|x - y|, sum (x - y)^2
  DeviceBuffer<float> scratch;    // [1] loss slot when the caller wants only the SSE
};

LossEngine::LossEngine(cudaStream_t stream) : impl_(std::make_unique<Impl>()) { impl_->stream = stream; }

LossEngine::~LossEngine() = default;

Status LossEngine::Compute(const float* rendered, const float* target, int width, int height, float lambda_dssim,
                           float scale, float* grad, float* loss_device, float* sse_device) {
  ATEX_RETURN_IF_ERROR(CheckImage("LossEngine::Compute", rendered, target, width, height));
  if (!(lambda_dssim >= 0.0f && lambda_dssim <= 1.0f) || !std::isfinite(scale)) {
    return MakeError(StatusCode::kInvalidArgument, "LossEngine::Compute: lambda_dssim ", lambda_dssim, " or scale ",
                     scale, " out of range");
  }
  Impl& im = *impl_;
  const size_t values = static_cast<size_t>(width) * static_cast<size_t>(height) * 3;
  const double count = static_cast<double>(values);
  ATEX_RETURN_IF_ERROR(im.sums.Resize(3));
  ATEX_RETURN_IF_ERROR(im.sums.Zero(im.stream));
  float* dmu = nullptr;
  float* dxx = nullptr;
  float* dxy = nullptr;
  if (grad != nullptr) {
    ATEX_RETURN_IF_ERROR(im.maps.Resize(3 * values));
    dmu = im.maps.data();
    dxx = dmu + values;
    dxy = dxx + values;
  }
  const float c1 = 0.01f * 0.01f;  // (0.01 R)^2, (0.03 R)^2 with data range R = 1
  const float c2 = 0.03f * 0.03f;
  ATEX_RETURN_IF_ERROR(loss_detail::LaunchSsimForward(rendered, target, width, height, c1, c2, im.window, dmu, dxx,
                                                      dxy, im.sums.data(), im.stream));
  if (grad != nullptr) {
    const float l1_coeff = static_cast<float>(scale * (1.0 - lambda_dssim) / count);
    const float ssim_coeff = static_cast<float>(-scale * static_cast<double>(lambda_dssim) / count);
    ATEX_RETURN_IF_ERROR(loss_detail::LaunchSsimBackward(rendered, target, dmu, dxx, dxy, width, height, im.window,
                                                         l1_coeff, ssim_coeff, grad, im.stream));
  }
  if (loss_device != nullptr || sse_device != nullptr) {
    // The finalize kernel always adds to *loss; give it a scratch slot when the caller wants only the SSE.
    float* loss = loss_device;
    if (loss == nullptr) {
      ATEX_RETURN_IF_ERROR(im.scratch.Resize(1));
      loss = im.scratch.data();
    }
    ATEX_RETURN_IF_ERROR(loss_detail::LaunchLossFinalize(im.sums.data(), count, lambda_dssim, scale, loss, sse_device,
                                                         im.stream));
  }
  return Status::Ok();
}

StatusOr<double> LossEngine::Ssim(const float* a, const float* b, int width, int height, float data_range) {
  ATEX_RETURN_IF_ERROR(CheckImage("LossEngine::Ssim", a, b, width, height));
  if (!(data_range > 0.0f) || !std::isfinite(data_range)) {
    return MakeError(StatusCode::kInvalidArgument, "LossEngine::Ssim: data range ", data_range);
  }
  Impl& im = *impl_;
  ATEX_RETURN_IF_ERROR(im.sums.Resize(3));
  ATEX_RETURN_IF_ERROR(im.sums.Zero(im.stream));
  const float c1 = (0.01f * data_range) * (0.01f * data_range);
  const float c2 = (0.03f * data_range) * (0.03f * data_range);
  ATEX_RETURN_IF_ERROR(loss_detail::LaunchSsimForward(a, b, width, height, c1, c2, im.window, nullptr, nullptr,
                                                      nullptr, im.sums.data(), im.stream));
  std::vector<double> sums;
  ATEX_RETURN_IF_ERROR(im.sums.Download(&sums, im.stream));  // synchronises the stream
  const double count = static_cast<double>(width) * static_cast<double>(height) * 3.0;
  return 1.0 - sums[0] / count;
}

}  // namespace atex::cuda
