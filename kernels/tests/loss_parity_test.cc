// Parity of the CUDA photometric loss (LossEngine) with the CPU reference
// (atex::PhotometricLoss, atex::Ssim) on random images of odd sizes. The reference runs
// in double precision, so the measured error is the GPU's own.
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "atex/image.h"
#include "atex/metrics.h"
#include "gpu_test_support.h"
#include "loss/loss_cuda.h"

namespace atex::cuda {
namespace {

using ::atex::cuda::testing::FirstNonFinite;
using ::atex::cuda::testing::PoisonedDevice;
using ::atex::cuda::testing::RelativeError;
using ::atex::cuda::testing::ToDevice;
using ::atex::cuda::testing::ToHost;

constexpr double kLossTolerance = 1e-5;
constexpr double kGradientTolerance = 1e-4;
constexpr double kSsimTolerance = 1e-5;  // absolute: SSIM lies in [-1, 1] and may be near 0

enum class Pair { kIndependent, kClose };

// Target U(0, 1); rendered either independent U(0, 1) or target + N(0, 0.05) (high SSIM,
// where 1 - SSIM is small). About 5% of the rendered values equal the target exactly
// (the L1 gradient is 0 there).
void MakeImages(int width, int height, Pair pair, uint64_t seed, std::vector<float>* rendered,
                std::vector<float>* target) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  std::normal_distribution<float> noise(0.0f, 0.05f);
  const size_t n = static_cast<size_t>(width) * height * 3;
  rendered->resize(n);
  target->resize(n);
  for (size_t i = 0; i < n; ++i) {
    (*target)[i] = unit(rng);
    (*rendered)[i] = pair == Pair::kIndependent ? unit(rng) : (*target)[i] + noise(rng);
    if (unit(rng) < 0.05f) (*rendered)[i] = (*target)[i];
  }
}

struct Case {
  int width, height;
  Pair pair;
  float lambda;
};

std::string CaseName(const ::testing::TestParamInfo<Case>& info) {
  const Case& c = info.param;
  return std::to_string(c.width) + "x" + std::to_string(c.height) +
         (c.pair == Pair::kIndependent ? "_independent" : "_close") + "_lambda" +
         std::to_string(static_cast<int>(std::lround(c.lambda * 100)));
}

class LossParityTest : public ::testing::TestWithParam<Case> {};

TEST_P(LossParityTest, LossAndGradientMatchCpu) {
  ATEX_REQUIRE_CUDA_DEVICE();
  const Case& c = GetParam();
  std::vector<float> rendered, target;
  MakeImages(c.width, c.height, c.pair, 17 + c.width * 1000 + c.height, &rendered, &target);
  const size_t n = rendered.size();

  // Reference in double.
  const std::vector<double> rendered64(rendered.begin(), rendered.end());
  std::vector<double> cpu_grad(n);
  const double cpu_loss =
      PhotometricLoss<double>(rendered64.data(), target.data(), c.width, c.height, c.lambda, cpu_grad.data());
  double sse = 0;
  for (size_t i = 0; i < n; ++i) sse += (double(rendered[i]) - target[i]) * (double(rendered[i]) - target[i]);

  cudaStream_t stream = nullptr;
  ATEX_ASSERT_CUDA(cudaStreamCreate(&stream));
  {
    DeviceBuffer<float> d_rendered, d_target, d_grad, d_scalars;
    ATEX_ASSERT_OK(ToDevice(rendered, &d_rendered));
    ATEX_ASSERT_OK(ToDevice(target, &d_target));
    ATEX_ASSERT_OK(PoisonedDevice(n, &d_grad));
    ATEX_ASSERT_OK(ToDevice(std::vector<float>{0.5f, 0.125f}, &d_scalars));  // loss, sse: the engine ADDS
    const float scale = 0.75f;
    LossEngine engine(stream);
    ATEX_ASSERT_OK(engine.Compute(d_rendered.data(), d_target.data(), c.width, c.height, c.lambda, scale,
                                  d_grad.data(), d_scalars.data(), d_scalars.data() + 1));
    ATEX_ASSERT_CUDA(cudaStreamSynchronize(stream));
    const std::vector<float> scalars = ToHost(d_scalars);
    std::vector<float> grad = ToHost(d_grad);
    ASSERT_EQ(FirstNonFinite(grad), -1) << "gradient element not written (or not finite)";
    for (float& g : grad) g /= scale;
    const double gpu_loss = (double(scalars[0]) - 0.5) / scale;
    const double loss_error = std::abs(gpu_loss - cpu_loss) / std::abs(cpu_loss);
    const double grad_error = RelativeError(grad, cpu_grad);
    const double sse_error = std::abs((double(scalars[1]) - 0.125) - sse) / sse;
    std::printf("[loss parity] %dx%d %s lambda %.2f: loss %.9g (cpu %.9g) relative error %.3g, gradient %.3g, "
                "sse %.3g\n",
                c.width, c.height, c.pair == Pair::kIndependent ? "independent" : "close", c.lambda, gpu_loss,
                cpu_loss, loss_error, grad_error, sse_error);
    EXPECT_LE(loss_error, kLossTolerance);
    EXPECT_LE(grad_error, kGradientTolerance);
    EXPECT_LE(sse_error, 1e-5);
    // Where rendered == target the L1 term gives no gradient: with lambda = 0 the gradient is exactly 0 there.
    if (c.lambda == 0.0f) {
      for (size_t i = 0; i < n; ++i) {
        if (rendered[i] == target[i]) {
          ASSERT_EQ(grad[i], 0.0f) << i;
        }
      }
    }

    // Loss only (no gradient): the same value.
    ATEX_ASSERT_OK(ToDevice(std::vector<float>{0.0f, 0.0f}, &d_scalars));
    ATEX_ASSERT_OK(engine.Compute(d_rendered.data(), d_target.data(), c.width, c.height, c.lambda, 1.0f, nullptr,
                                  d_scalars.data(), nullptr));
    ATEX_ASSERT_CUDA(cudaStreamSynchronize(stream));
    EXPECT_LE(std::abs(ToHost(d_scalars)[0] - cpu_loss) / std::abs(cpu_loss), kLossTolerance);
  }
  cudaStreamDestroy(stream);
}

INSTANTIATE_TEST_SUITE_P(Images, LossParityTest,
                         ::testing::Values(Case{37, 23, Pair::kIndependent, 0.2f}, Case{37, 23, Pair::kClose, 0.2f},
                                           Case{37, 23, Pair::kIndependent, 0.0f}, Case{37, 23, Pair::kClose, 1.0f},
                                           Case{100, 100, Pair::kIndependent, 0.2f},
                                           Case{100, 100, Pair::kClose, 0.2f}, Case{640, 360, Pair::kClose, 0.2f},
                                           Case{640, 360, Pair::kIndependent, 0.2f}, Case{1, 1, Pair::kClose, 0.2f},
                                           Case{7, 300, Pair::kClose, 0.2f}),
                         CaseName);

TEST(SsimParityTest, MatchesCpuSsim) {
  ATEX_REQUIRE_CUDA_DEVICE();
  cudaStream_t stream = nullptr;
  ATEX_ASSERT_CUDA(cudaStreamCreate(&stream));
  {
    LossEngine engine(stream);
    const int sizes[][2] = {{37, 23}, {100, 100}, {640, 360}};
    for (const auto& size : sizes) {
      for (Pair pair : {Pair::kIndependent, Pair::kClose}) {
        std::vector<float> a, b;
        MakeImages(size[0], size[1], pair, 99 + size[0], &a, &b);
        Image image_a(size[0], size[1], 3), image_b(size[0], size[1], 3);
        image_a.pixels = a;
        image_b.pixels = b;
        DeviceBuffer<float> d_a, d_b;
        ATEX_ASSERT_OK(ToDevice(a, &d_a));
        ATEX_ASSERT_OK(ToDevice(b, &d_b));
        for (double range : {1.0, 2.0}) {
          SsimOptions options;
          options.data_range = range;
          const StatusOr<double> cpu = Ssim(image_a, image_b, options);
          ATEX_ASSERT_OK(cpu.status());
          const StatusOr<double> gpu =
              engine.Ssim(d_a.data(), d_b.data(), size[0], size[1], static_cast<float>(range));
          ATEX_ASSERT_OK(gpu.status());
          std::printf("[loss parity] SSIM %dx%d %s R=%.0f: gpu %.9f cpu %.9f difference %.3g\n", size[0], size[1],
                      pair == Pair::kIndependent ? "independent" : "close", range, *gpu, *cpu,
                      std::abs(*gpu - *cpu));
          EXPECT_LE(std::abs(*gpu - *cpu), kSsimTolerance);
        }
      }
    }
    // Identical images: exactly 1 up to rounding.
    std::vector<float> a, b;
    MakeImages(64, 48, Pair::kIndependent, 5, &a, &b);
    DeviceBuffer<float> d_a;
    ATEX_ASSERT_OK(ToDevice(a, &d_a));
    const StatusOr<double> same = engine.Ssim(d_a.data(), d_a.data(), 64, 48, 1.0f);
    ATEX_ASSERT_OK(same.status());
    EXPECT_NEAR(*same, 1.0, 1e-6);
  }
  cudaStreamDestroy(stream);
}

// Without a device: argument checks happen before anything touches the GPU.
TEST(LossEngineValidationTest, RejectsBadArguments) {
  LossEngine engine(nullptr);
  float* fake = reinterpret_cast<float*>(uintptr_t{256});
  EXPECT_EQ(engine.Compute(nullptr, fake, 4, 4, 0.2f, 1.0f, fake, fake, nullptr).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(engine.Compute(fake, fake, 0, 4, 0.2f, 1.0f, fake, fake, nullptr).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(engine.Compute(fake, fake, 4, 4, 1.5f, 1.0f, fake, fake, nullptr).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(engine.Compute(fake, fake, 4, 4, 0.2f, std::nanf(""), fake, fake, nullptr).code(),
            StatusCode::kInvalidArgument);
  EXPECT_EQ(engine.Ssim(fake, fake, 4, -1, 1.0f).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(engine.Ssim(fake, fake, 4, 4, 0.0f).status().code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace atex::cuda
