// GPU timings of the deformation network and the photometric loss (kernels/src/deform,
// kernels/src/loss). Built by kernels/tests/tests.cmake (it needs atex_cuda), not by the
// bench/ glob, which takes only bench_*.cc.
//
//   build/bench/bench_cuda_deform --benchmark_counters_tabular=true
//
// Times are CUDA-event times of one call (UseManualTime), after warm-up; inputs are random
// (never zeros). Configs: N3DV (C=16, res [64,64,64,150], multires [1,2], W=128, all five
// heads, SH degree 3) and D-NeRF (C=32, res [64,64,64,25], multires [1,2], W=64, heads
// x, s, r, SH degree 0), as REFERENCE.md §8 measured the PyTorch stack.
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <random>
#include <vector>

#include <benchmark/benchmark.h>
#include <cublas_v2.h>
#include <cuda_runtime.h>

#include "bench_configs.h"
#include "atex/deform.h"
#include "atex/model.h"
#include "deform/deform_cuda.h"
#include "device_buffer.h"
#include "loss/loss_cuda.h"

namespace {

using atex::cuda::DeviceBuffer;

bool HaveDevice() {
  int count = 0;
  return cudaGetDeviceCount(&count) == cudaSuccess && count > 0;
}

std::vector<float> Uniform(size_t n, float lo, float hi, std::mt19937& rng) {
  std::uniform_real_distribution<float> u(lo, hi);
  std::vector<float> v(n);
  for (float& x : v) x = u(rng);
  return v;
}

// Everything one deformation benchmark needs on the device.
struct DeformBench {
  cudaStream_t stream = nullptr;
  cublasHandle_t cublas = nullptr;
  atex::cuda::DeformLayout layout;
  DeviceBuffer<float> grid, mlp, grad_grid, grad_mlp;
  DeviceBuffer<float> canonical[5], deformed[5], grad_deformed[5], grad_canonical[5];
  std::unique_ptr<atex::cuda::DeformEngine> engine;
  int n = 0, sh_coeffs = 1;

  static atex::cuda::GaussianTensors Tensors(DeviceBuffer<float>* t) {
    return {t[0].data(), t[1].data(), t[2].data(), t[3].data(), t[4].data()};
  }

  bool Init(const atex::DeformationConfig& config, int count) {
    n = count;
    sh_coeffs = config.sh_coeffs;
    if (cudaStreamCreate(&stream) != cudaSuccess || cublasCreate(&cublas) != CUBLAS_STATUS_SUCCESS) return false;
    auto field = atex::InitDeformationField(config, 7);
    if (!field.ok()) return false;
    layout = atex::cuda::DeformLayout::Make(config);
    if (!grid.Resize(layout.grid_size).ok() || !mlp.Resize(layout.mlp_size).ok() ||
        !grad_grid.Resize(layout.grid_size).ok() || !grad_mlp.Resize(layout.mlp_size).ok()) {
      return false;
    }
    if (!atex::cuda::UploadDeformation(*field, layout, grid.data(), mlp.data(), stream).ok()) return false;
    std::mt19937 rng(11);
    const size_t widths[5] = {3, 3, 4, 1, static_cast<size_t>(3 * sh_coeffs)};
    for (int t = 0; t < 5; ++t) {
      const size_t size = static_cast<size_t>(n) * widths[t];
      if (!canonical[t].Upload(Uniform(size, -0.9f, 0.9f, rng)).ok() || !deformed[t].Resize(size).ok() ||
          !grad_deformed[t].Upload(Uniform(size, -1e-3f, 1e-3f, rng)).ok() ||
          !grad_canonical[t].Upload(std::vector<float>(size, 0.0f)).ok()) {
        return false;
      }
    }
    if (!grad_grid.Zero().ok() || !grad_mlp.Zero().ok()) return false;
    cudaDeviceSynchronize();
    engine = std::make_unique<atex::cuda::DeformEngine>(cublas, stream);
    return true;
  }
  ~DeformBench() {
    engine.reset();
    if (cublas) cublasDestroy(cublas);
    if (stream) cudaStreamDestroy(stream);
  }
  atex::Status Forward() {
    return engine->Forward(layout, grid.data(), mlp.data(), n, sh_coeffs, 0.37f, Tensors(canonical),
                           Tensors(deformed));
  }
  atex::Status Backward() {
    return engine->Backward(layout, grid.data(), mlp.data(), n, sh_coeffs, 0.37f, Tensors(canonical),
                            Tensors(grad_deformed), grad_grid.data(), grad_mlp.data(), Tensors(grad_canonical));
  }
};

// Times `body` with CUDA events on `stream`, one manual-time iteration per benchmark iteration.
template <typename Body>
void TimeLoop(benchmark::State& state, cudaStream_t stream, Body&& body) {
  for (int i = 0; i < 3; ++i) {  // warm-up: module load, cuBLAS heuristics, workspace growth
    if (!body().ok()) {
      state.SkipWithError("call failed");
      return;
    }
  }
  cudaEvent_t start, stop;
  cudaEventCreate(&start);
  cudaEventCreate(&stop);
  for (auto _ : state) {
    cudaEventRecord(start, stream);
    const atex::Status status = body();
    cudaEventRecord(stop, stream);
    cudaEventSynchronize(stop);
    if (!status.ok()) {
      state.SkipWithError(status.ToString().c_str());
      break;
    }
    float ms = 0;
    cudaEventElapsedTime(&ms, start, stop);
    state.SetIterationTime(ms / 1e3);
  }
  cudaEventDestroy(start);
  cudaEventDestroy(stop);
}

// range(0): 0 = N3DV, 1 = D-NeRF; range(1): Gaussians; range(2): 1 = allow TF32; range(3): 1 = with backward.
void BM_Deform(benchmark::State& state) {
  if (!HaveDevice()) {
    state.SkipWithError("no CUDA device");
    return;
  }
  DeformBench bench;
  if (!bench.Init(DatasetDeformation(state.range(0) == 0 ? "n3dv" : "dnerf"), static_cast<int>(state.range(1)))) {
    state.SkipWithError("setup failed");
    return;
  }
  bench.engine->set_allow_tf32(state.range(2) != 0);
  const bool backward = state.range(3) != 0;
  TimeLoop(state, bench.stream, [&] {
    atex::Status status = bench.Forward();
    if (!status.ok() || !backward) return status;
    return bench.Backward();
  });
  state.counters["workspace_MiB"] = static_cast<double>(bench.engine->workspace_bytes()) / (1 << 20);
}
BENCHMARK(BM_Deform)
    ->ArgNames({"n3dv0_dnerf1", "n", "tf32", "bwd"})
    ->Args({0, 100000, 0, 0})
    ->Args({0, 100000, 0, 1})
    ->Args({0, 300000, 0, 0})
    ->Args({0, 300000, 0, 1})
    ->Args({0, 300000, 1, 1})
    ->Args({1, 100000, 0, 0})
    ->Args({1, 100000, 0, 1})
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

void BM_Regularizer(benchmark::State& state) {
  if (!HaveDevice()) {
    state.SkipWithError("no CUDA device");
    return;
  }
  DeformBench bench;
  if (!bench.Init(DatasetDeformation("n3dv"), 1)) {
    state.SkipWithError("setup failed");
    return;
  }
  DeviceBuffer<float> loss;
  if (!loss.Upload(std::vector<float>{0.0f}).ok()) return;
  TimeLoop(state, bench.stream, [&] {
    return bench.engine->Regularizer(bench.layout, bench.grid.data(), 2e-4f, 1e-3f, 1e-4f, bench.grad_grid.data(),
                                     loss.data());
  });
}
BENCHMARK(BM_Regularizer)->UseManualTime()->Unit(benchmark::kMicrosecond);

// range(0) x range(1) image; loss + gradient.
void BM_Loss(benchmark::State& state) {
  if (!HaveDevice()) {
    state.SkipWithError("no CUDA device");
    return;
  }
  const int width = static_cast<int>(state.range(0)), height = static_cast<int>(state.range(1));
  const size_t n = static_cast<size_t>(width) * height * 3;
  cudaStream_t stream = nullptr;
  cudaStreamCreate(&stream);
  {
    std::mt19937 rng(3);
    DeviceBuffer<float> rendered, target, grad, scalars;
    if (!rendered.Upload(Uniform(n, 0.0f, 1.0f, rng)).ok() || !target.Upload(Uniform(n, 0.0f, 1.0f, rng)).ok() ||
        !grad.Resize(n).ok() || !scalars.Upload(std::vector<float>{0.0f, 0.0f}).ok()) {
      state.SkipWithError("setup failed");
    } else {
      cudaDeviceSynchronize();
      atex::cuda::LossEngine engine(stream);
      TimeLoop(state, stream, [&] {
        return engine.Compute(rendered.data(), target.data(), width, height, 0.2f, 1.0f, grad.data(),
                              scalars.data(), scalars.data() + 1);
      });
    }
  }
  cudaStreamDestroy(stream);
}
BENCHMARK(BM_Loss)->Args({640, 360})->Args({1352, 1014})->UseManualTime()->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
