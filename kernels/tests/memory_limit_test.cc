// Issue 24: out of GPU memory is a limit (kLimitExceeded, as on the CPU), never an
// internal error, and the message says how much was asked and how much is free; so is a
// view with more (tile, Gaussian) pairs than the tile lists can index. The
// device stays usable afterwards (the error is not left pending for later checks).
#include <cmath>

#include <gtest/gtest.h>

#include "atex/cuda/cuda_backend.h"
#include "atex/train/backend.h"
#include "cuda_check.h"
#include "device_buffer.h"
#include "gpu_test_support.h"
#include "render/render_cuda.h"

namespace atex::cuda {
namespace {

TEST(DeviceMemory, AnAllocationBeyondTheCardIsALimitNamingBothSizes) {
  ATEX_REQUIRE_CUDA_DEVICE();
  size_t free_bytes = 0, total_bytes = 0;
  ASSERT_EQ(cudaMemGetInfo(&free_bytes, &total_bytes), cudaSuccess);
  DeviceBuffer<float> huge;
  const Status s = huge.Resize(2 * (total_bytes / sizeof(float)));  // twice the card
  EXPECT_EQ(s.code(), StatusCode::kLimitExceeded) << s.ToString();
  EXPECT_NE(s.message().find("MiB asked"), std::string::npos) << s.ToString();
  EXPECT_NE(s.message().find("GiB free of"), std::string::npos) << s.ToString();
  EXPECT_EQ(cudaGetLastError(), cudaSuccess);  // cleared: the next launch check is clean
  DeviceBuffer<float> small;
  EXPECT_TRUE(small.Resize(1024).ok());
  // Beyond the address space: refused before cudaMalloc.
  EXPECT_EQ(huge.Resize(SIZE_MAX / 2).code(), StatusCode::kLimitExceeded);
}

// Gaussians at 2 m in front of the camera, `sigma` metres across, opaque, grey.
train::ModelState OpaqueWall(size_t n, float sigma) {
  train::ModelState state;
  Gaussians& g = state.gaussians;
  g.sh_degree = 0;
  for (size_t i = 0; i < n; ++i) {
    const float x = static_cast<float>(i % 1000) * 1e-3f - 0.5f, y = static_cast<float>(i / 1000 % 1000) * 1e-3f - 0.5f;
    g.positions.insert(g.positions.end(), {x, y, 2.0f});
    g.rotations.insert(g.rotations.end(), {1, 0, 0, 0});
    g.log_scales.insert(g.log_scales.end(), 3, std::log(sigma));
    g.opacity_logits.push_back(5.0f);
    g.sh.insert(g.sh.end(), 3, 0.0f);  // DC 0: colour 0.5
  }
  return state;
}

TEST(DeviceMemory, AViewWithMoreTilePairsThanTheListsHoldIsALimitNotAWrappedCount) {
  // The stress case of gpu_memory_stress.sh (8 M screen-sized Gaussians): its 43 billion
  // (tile, Gaussian) pairs wrapped the 32-bit count, and the sort failed with "invalid
  // device ordinal" (E18). 600,000 Gaussians of 5 m at 2 m cover all 4,096 tiles of a
  // 1024x1024 view: 2.46 billion pairs, past kMaxTileEntries.
  ATEX_REQUIRE_CUDA_DEVICE();
  auto backend = MakeCudaBackend();
  ASSERT_TRUE(backend.ok()) << backend.status().ToString();
  const size_t n = 600'000;
  ASSERT_GT(n * 4096, kMaxTileEntries);
  ASSERT_TRUE((*backend)->Load(OpaqueWall(n, 5.0f)).ok());
  Camera camera;
  camera.width = camera.height = 1024;
  camera.fx = camera.fy = 1000;
  camera.cx = camera.cy = 512;
  train::RenderRequest request;
  request.active_sh_degree = 0;
  request.apply_deformation = false;
  request.use_textures = false;
  auto image = (*backend)->Render(camera, request);
  ASSERT_FALSE(image.ok());
  EXPECT_EQ(image.status().code(), StatusCode::kLimitExceeded) << image.status().ToString();
  EXPECT_NE(image.status().message().find("(tile, Gaussian) pairs, more than the renderer's limit"),
            std::string::npos)
      << image.status().ToString();
  EXPECT_NE(image.status().message().find("GiB free of"), std::string::npos) << image.status().ToString();
  // The same model in a view within the limit renders (64 tiles: 38.4 million pairs).
  camera.width = camera.height = 128;
  camera.fx = camera.fy = 125;
  camera.cx = camera.cy = 64;
  auto small = (*backend)->Render(camera, request);
  ASSERT_TRUE(small.ok()) << small.status().ToString();
  EXPECT_NEAR(small->pixels[0], 0.5f, 0.05f);
}

TEST(DeviceMemory, CudaStatusMapsAllocationFailuresToTheLimitCode) {
  // No device needed: the mapping of the error values.
  const Status oom = CudaStatus(cudaErrorMemoryAllocation, "cudaMalloc", __FILE__, __LINE__);
  EXPECT_EQ(oom.code(), StatusCode::kLimitExceeded) << oom.ToString();
  EXPECT_NE(oom.message().find("out of GPU memory"), std::string::npos);
  EXPECT_EQ(CublasStatus(CUBLAS_STATUS_ALLOC_FAILED, "cublasCreate", __FILE__, __LINE__).code(),
            StatusCode::kLimitExceeded);
  EXPECT_EQ(CudaStatus(cudaErrorInvalidValue, "x", __FILE__, __LINE__).code(), StatusCode::kInternal);
}

}  // namespace
}  // namespace atex::cuda
