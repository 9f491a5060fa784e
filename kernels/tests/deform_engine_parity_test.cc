// The deformation engine's contract beyond parity with the CPU: cuBLAS handle settings and
// TF32, the HexPlane regulariser against the CPU, exact transfers, the parameter layout, and
// refusals before any device work.
#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "deform_test_util.h"

namespace atex::cuda {
namespace {

using namespace deform_testing;  // NOLINT: the helpers of these tests

// handle allows TF32, and honour set_allow_tf32 (looser tolerance: TF32 has a 10-bit mantissa).
TEST(DeformEngineTest, RestoresHandleSettingsAndHonoursTf32) {
  ATEX_REQUIRE_CUDA_DEVICE();
  const DeformationConfig config =
      BaseConfig(8, {12, 10, 14, 9}, {1, 2}, 32, 1, {true, true, true, false, false}, 0);
  const DeformationField field = RandomField(config, 42);
  const Gaussians all = RandomGaussians(config, 1500, 0, 0.1, 43);
  const Gaussians canonical = Subset(all, SafeGaussians(field, all, 0.25f));
  const size_t n = canonical.size();
  Gaussians cpu_deformed;
  ATEX_ASSERT_OK(DeformForward(field, canonical, 0.25, &cpu_deformed, nullptr));

  GpuContext gpu;
  ASSERT_TRUE(gpu.ok());
  cudaStream_t other_stream = nullptr;
  ATEX_ASSERT_CUDA(cudaStreamCreate(&other_stream));
  ASSERT_EQ(cublasSetStream(gpu.cublas(), other_stream), CUBLAS_STATUS_SUCCESS);
  ASSERT_EQ(cublasSetMathMode(gpu.cublas(), CUBLAS_TF32_TENSOR_OP_MATH), CUBLAS_STATUS_SUCCESS);

  DeviceField device_field;
  ATEX_ASSERT_OK(device_field.Upload(field, gpu.stream()));
  DeviceGaussians d_canonical, d_deformed;
  ATEX_ASSERT_OK(d_canonical.Upload(canonical));
  DeformEngine engine(gpu.cublas(), gpu.stream());
  for (int run = 0; run < 4; ++run) {
    const bool tf32 = run % 2 == 1, fuse = run < 2;
    engine.set_allow_tf32(tf32);
    engine.set_fuse_bias_relu(fuse);
    ATEX_ASSERT_OK(d_deformed.Poison(canonical));
    ATEX_ASSERT_OK(engine.Forward(device_field.layout, device_field.grid.data(), device_field.mlp.data(),
                                  static_cast<int>(n), 1, 0.25f, d_canonical.tensors(), d_deformed.tensors()));
    ATEX_ASSERT_CUDA(cudaStreamSynchronize(gpu.stream()));
    const Gaussians gpu_deformed = d_deformed.Download(0);
    const double error = RelativeError(gpu_deformed.positions, cpu_deformed.positions);
    std::printf("[deform parity] forward positions with %s GEMMs (%d hidden layers fused, %d not) on a TF32-enabled "
                "handle: relative error %.3g\n",
                tf32 ? "TF32" : "FP32", engine.last_forward_fused_layers(), engine.last_forward_unfused_layers(),
                error);
    EXPECT_EQ(FirstNonFinite(gpu_deformed.positions), -1);
    EXPECT_LE(error, tf32 ? 2e-2 : kForwardTolerance);
    // Training and rendering run TF32 with the fused epilogue: it must actually be taken on
    // the GPUs we build for, or the measured speed is not the code's.
    if (tf32 && fuse) {
      EXPECT_EQ(engine.last_forward_unfused_layers(), 0);
    }
    if (!fuse) {
      EXPECT_EQ(engine.last_forward_fused_layers(), 0);
    }
    cudaStream_t stream_after = nullptr;
    cublasMath_t math_after = CUBLAS_DEFAULT_MATH;
    ASSERT_EQ(cublasGetStream(gpu.cublas(), &stream_after), CUBLAS_STATUS_SUCCESS);
    ASSERT_EQ(cublasGetMathMode(gpu.cublas(), &math_after), CUBLAS_STATUS_SUCCESS);
    EXPECT_EQ(stream_after, other_stream);
    EXPECT_EQ(math_after, CUBLAS_TF32_TENSOR_OP_MATH);
  }
  cublasSetStream(gpu.cublas(), nullptr);
  cudaStreamDestroy(other_stream);
}

// ---- regulariser ----------------------------------------------------------------------

void CheckRegularizer(const DeformationConfig& config, const char* name) {
  const DeformationField field = RandomField(config, 77, 0.2, 1.8);
  const DeformationField base = RandomFieldLike(field, 0.001, 78);
  RegularizerWeights weights;
  weights.plane_tv = 0.3f;
  weights.time_smoothness = 0.7f;
  weights.time_l1 = 0.2f;
  DeformationField cpu_grad = base;
  const float cpu_value = DeformRegularizer(field, weights, &cpu_grad);
  ASSERT_TRUE(std::isfinite(cpu_value));

  GpuContext gpu;
  ASSERT_TRUE(gpu.ok());
  DeviceField d_field, d_grad;
  ATEX_ASSERT_OK(d_field.Upload(field, gpu.stream()));
  ATEX_ASSERT_OK(d_grad.Upload(base, gpu.stream()));
  DeviceBuffer<float> loss;
  ATEX_ASSERT_OK(ToDevice(std::vector<float>{0.25f}, &loss));  // the engine ADDS to it
  DeformEngine engine(gpu.cublas(), gpu.stream());
  ATEX_ASSERT_OK(engine.Regularizer(d_field.layout, d_field.grid.data(), weights.plane_tv, weights.time_smoothness,
                                    weights.time_l1, d_grad.grid.data(), loss.data()));
  ATEX_ASSERT_CUDA(cudaStreamSynchronize(gpu.stream()));
  const double gpu_value = static_cast<double>(ToHost(loss)[0]) - 0.25;
  const double value_error = std::abs(gpu_value - cpu_value) / std::abs(static_cast<double>(cpu_value));
  const StatusOr<DeformationField> gpu_grad = d_grad.Download(gpu.stream());
  ATEX_ASSERT_OK(gpu_grad.status());
  const double grad_error = RelativeError(FlattenPlanes(*gpu_grad), FlattenPlanes(cpu_grad), FlattenPlanes(base));
  std::printf("[deform parity] regulariser %s: value %.9g (cpu %.9g) relative error %.3g, gradient %.3g\n", name,
              gpu_value, static_cast<double>(cpu_value), value_error, grad_error);
  EXPECT_LE(value_error, 1e-5);
  EXPECT_LE(grad_error, 1e-5);
  EXPECT_EQ(FirstNonFinite(FlattenPlanes(*gpu_grad)), -1);
  // The MLP part of the gradient buffer is not touched.
  EXPECT_EQ(FlattenMlp(*gpu_grad), FlattenMlp(base));

  // Value only (no gradient buffer) gives the same value.
  ATEX_ASSERT_OK(ToDevice(std::vector<float>{0.0f}, &loss));
  ATEX_ASSERT_OK(engine.Regularizer(d_field.layout, d_field.grid.data(), weights.plane_tv, weights.time_smoothness,
                                    weights.time_l1, nullptr, loss.data()));
  ATEX_ASSERT_CUDA(cudaStreamSynchronize(gpu.stream()));
  EXPECT_NEAR(ToHost(loss)[0], gpu_value, 1e-6 * std::abs(gpu_value));
}

TEST(DeformRegularizerParityTest, MatchesCpu) {
  ATEX_REQUIRE_CUDA_DEVICE();
  CheckRegularizer(BaseConfig(8, {12, 10, 14, 9}, {1, 2}, 16, 1, {true, true, true, false, false}, 0), "two scales");
}

TEST(DeformRegularizerParityTest, PlanesWithFewerThanThreeRowsSkipSmoothness) {
  ATEX_REQUIRE_CUDA_DEVICE();
  // y resolution 2 (xy plane has 2 rows) and time resolution 2 (every time plane has 2 rows).
  CheckRegularizer(BaseConfig(5, {6, 2, 5, 2}, {1, 3}, 16, 1, {true, false, false, false, false}, 0), "short planes");
}

// ---- transfers and layout ---------------------------------------------------------------

TEST(DeformTransferTest, UploadDownloadRoundTripIsExact) {
  ATEX_REQUIRE_CUDA_DEVICE();
  DeformationConfig config =
      BaseConfig(5, {7, 6, 9, 4}, {1, 2, 3}, 24, 2, {true, false, true, true, true}, 2);
  std::swap(config.aabb_lo, config.aabb_hi);
  const DeformationField field = RandomField(config, 99);
  GpuContext gpu;
  ASSERT_TRUE(gpu.ok());
  DeviceField d_field;
  ATEX_ASSERT_OK(d_field.Upload(field, gpu.stream()));
  const StatusOr<DeformationField> back = d_field.Download(gpu.stream());
  ATEX_ASSERT_OK(back.status());
  ASSERT_EQ(back->planes.size(), field.planes.size());
  for (size_t s = 0; s < field.planes.size(); ++s) {
    for (int p = 0; p < kNumHexPlanes; ++p) EXPECT_EQ(back->planes[s][p], field.planes[s][p]) << s << "," << p;
  }
  ASSERT_EQ(back->trunk.size(), field.trunk.size());
  for (size_t l = 0; l < field.trunk.size(); ++l) {
    EXPECT_EQ(back->trunk[l].weight, field.trunk[l].weight);
    EXPECT_EQ(back->trunk[l].bias, field.trunk[l].bias);
    EXPECT_EQ(back->trunk[l].in, field.trunk[l].in);
    EXPECT_EQ(back->trunk[l].out, field.trunk[l].out);
  }
  for (int h = 0; h < kNumDeformHeads; ++h) {
    for (int j = 0; j < 2; ++j) {
      EXPECT_EQ(back->heads[h][j].weight, field.heads[h][j].weight) << h;
      EXPECT_EQ(back->heads[h][j].bias, field.heads[h][j].bias) << h;
      EXPECT_EQ(back->heads[h][j].in, field.heads[h][j].in) << h;
      EXPECT_EQ(back->heads[h][j].out, field.heads[h][j].out) << h;
    }
  }
  EXPECT_EQ(back->config.aabb_lo, field.config.aabb_lo);
  EXPECT_EQ(back->config.aabb_hi, field.config.aabb_hi);
  EXPECT_EQ(back->config.grid.multires, field.config.grid.multires);
  EXPECT_EQ(back->config.heads, field.config.heads);
  EXPECT_EQ(back->config.sh_coeffs, field.config.sh_coeffs);
  EXPECT_TRUE(CheckDeformationField(*back).ok());

  // The device grid is channel-last: value (c, b, a) of plane (s, p) sits at ((b * res_a) + a) * C + c.
  const std::vector<float> grid = ToHost(d_field.grid);
  const int s = 1, p = 4;  // yt plane of the second scale
  const int res_a = config.grid.resolution(s, kHexPlaneAxes[p][0]);
  const int res_b = config.grid.resolution(s, kHexPlaneAxes[p][1]);
  const int c = 3, b = 2, a = 5;
  ASSERT_LT(a, res_a);
  ASSERT_LT(b, res_b);
  EXPECT_EQ(grid[d_field.layout.plane_offset[s * 6 + p] + (static_cast<size_t>(b) * res_a + a) * 5 + c],
            field.planes[s][p][(static_cast<size_t>(c) * res_b + b) * res_a + a]);
}

// These run without a device: the checks happen before anything touches the GPU.
TEST(DeformLayoutTest, SizesMatchTheFieldsParameterCount) {
  DeformationConfig config = BaseConfig(7, {5, 6, 7, 8}, {1, 2, 4}, 20, 3, {true, false, true, false, true}, 3);
  const DeformationField field = RandomField(config, 5);
  const DeformLayout layout = DeformLayout::Make(config);
  EXPECT_EQ(layout.grid_size + layout.mlp_size, ParameterCount(field));
  EXPECT_EQ(layout.grid_size, FlattenPlanes(field).size());
  EXPECT_EQ(layout.mlp_size, FlattenMlp(field).size());
  // Layers are packed back to back in the documented order.
  EXPECT_EQ(layout.trunk[0].weight, 0u);
  EXPECT_EQ(layout.trunk[0].bias, static_cast<size_t>(config.grid.feature_dim() * 20));
  EXPECT_EQ(layout.head_hidden[kHeadPosition].weight, layout.trunk[2].bias + 20);
  EXPECT_EQ(layout.head_output[kHeadPosition].weight, layout.head_hidden[kHeadPosition].bias + 20);
  EXPECT_EQ(layout.head_hidden[kHeadRotation].weight, layout.head_output[kHeadPosition].bias + 3);
  EXPECT_EQ(layout.head_hidden[kHeadScale].in, 0);  // disabled
  EXPECT_EQ(layout.head_output[kHeadSH].out, 48);
  EXPECT_EQ(layout.mlp_size, layout.head_output[kHeadSH].bias + 48);
  EXPECT_EQ(layout.plane_offset.size(), 18u);
  EXPECT_EQ(layout.plane_offset[1], static_cast<size_t>(7 * 6 * 5));  // after the xy plane [C][y][x]
}

TEST(DeformEngineValidationTest, RejectsBadCallsBeforeTouchingTheDevice) {
  DeformationConfig config = BaseConfig(4, {5, 5, 5, 5}, {1}, 8, 1, {true, true, true, false, true}, 1);
  const DeformLayout layout = DeformLayout::Make(config);
  // A fake, never dereferenced, non-null pointer: validation must fail before any access.
  float* fake = reinterpret_cast<float*>(uintptr_t{256});
  GaussianTensors tensors{fake, fake, fake, fake, fake};
  DeformEngine engine(nullptr, nullptr);
  // SH head configured for K = 4, Gaussians with K = 1.
  EXPECT_EQ(engine.Forward(layout, fake, fake, 10, 1, 0.5f, tensors, {}).code(), StatusCode::kInvalidArgument);
  // Backward with no Forward before it.
  EXPECT_EQ(engine.Backward(layout, fake, fake, 10, 4, 0.5f, tensors, tensors, fake, fake, {}).code(),
            StatusCode::kInvalidArgument);
  // Deformed aliasing canonical.
  EXPECT_EQ(engine.Forward(layout, fake, fake, 10, 4, 0.5f, tensors, tensors).code(), StatusCode::kInvalidArgument);
  // A layout edited after Make.
  DeformLayout edited = layout;
  edited.mlp_size += 1;
  EXPECT_EQ(engine.Forward(edited, fake, fake, 10, 4, 0.5f, tensors, {}).code(), StatusCode::kInvalidArgument);
  // More scales than any valid config has.
  DeformationConfig many = config;
  many.grid.multires.assign(17, 1);
  EXPECT_EQ(engine.Forward(DeformLayout::Make(many), fake, fake, 10, 4, 0.5f, tensors, {}).code(),
            StatusCode::kInvalidArgument);
  // Non-finite time.
  EXPECT_EQ(engine.Forward(layout, fake, fake, 10, 4, std::nanf(""), tensors, {}).code(),
            StatusCode::kInvalidArgument);
  // Upload of a field whose plane has the wrong size.
  DeformationField field = RandomField(config, 3);
  field.planes[0][2].pop_back();
  EXPECT_EQ(UploadDeformation(field, layout, fake, fake, nullptr).code(), StatusCode::kInvalidArgument);
  // Download into nothing.
  EXPECT_EQ(DownloadDeformation(fake, fake, layout, nullptr, nullptr).code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace atex::cuda
