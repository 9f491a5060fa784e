// CPU reference deformation field (libatex/src/deform): forward, and forward +
// backward (field and canonical gradients), for 100k Gaussians with the two
// published 4DGaussians configs:
//   D-NeRF: C = 32, res [64, 64, 64, 25], multires [1, 2], W = 64, heads x, s, r
//   N3DV:   C = 16, res [64, 64, 64, 150], multires [1, 2], W = 128, all five heads, SH degree 3
//
//   build/bench/bench_deform --benchmark_counters_tabular=true
//
// Wall-clock times (UseRealTime: the work is spread over OpenMP threads).
#include <benchmark/benchmark.h>

#include <random>

#include "bench_configs.h"
#include "atex/deform.h"

namespace {

constexpr size_t kGaussians = 100000;

struct Scene {
  atex::DeformationField field;
  atex::Gaussians canonical;
  atex::Gaussians grad_deformed;
};

Scene MakeScene(const atex::DeformationConfig& config, int sh_degree) {
  Scene scene;
  scene.field = *atex::InitDeformationField(config, 7);
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  // Non-trivial planes and heads (the init leaves the heads near zero).
  for (auto& scale : scene.field.planes)
    for (auto& plane : scale)
      for (float& v : plane) v += 0.1f * u(rng);
  for (auto& head : scene.field.heads)
    for (auto& layer : head)
      for (float& v : layer.weight) v += 0.05f * u(rng);
  for (atex::Gaussians* g : {&scene.canonical, &scene.grad_deformed}) {
    g->sh_degree = sh_degree;
    g->Resize(kGaussians);
    for (auto* v : {&g->positions, &g->rotations, &g->log_scales, &g->opacity_logits, &g->sh})
      for (float& x : *v) x = u(rng);
  }
  return scene;
}

void Report(benchmark::State& state, const Scene& scene) {
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()) * static_cast<int64_t>(kGaussians));
  state.counters["params"] = static_cast<double>(atex::ParameterCount(scene.field));
}

void Forward(benchmark::State& state, const Scene& scene) {
  atex::Gaussians deformed;
  for (auto _ : state) {
    if (!atex::DeformForward(scene.field, scene.canonical, 0.4, &deformed, nullptr).ok()) {
      state.SkipWithError("DeformForward failed");
      break;
    }
    benchmark::DoNotOptimize(deformed.positions.data());
  }
  Report(state, scene);
}

void ForwardBackward(benchmark::State& state, const Scene& scene) {
  atex::Gaussians deformed, grad_canonical;
  atex::DeformCache cache;
  atex::DeformationField grad_field = atex::ZerosLike(scene.field);
  for (auto _ : state) {
    grad_canonical = atex::Gaussians();
    if (!atex::DeformForward(scene.field, scene.canonical, 0.4, &deformed, &cache).ok() ||
        !atex::DeformBackward(scene.field, scene.canonical, 0.4, cache, scene.grad_deformed, &grad_field,
                              &grad_canonical)
             .ok()) {
      state.SkipWithError("deformation failed");
      break;
    }
    benchmark::DoNotOptimize(grad_field.planes[0][0].data());
  }
  Report(state, scene);
  state.counters["cache_MiB"] = static_cast<double>(cache.bytes()) / (1 << 20);
}

const Scene& Dnerf() {
  static const Scene scene = MakeScene(DatasetDeformation("dnerf"), 0);
  return scene;
}
const Scene& N3dv() {
  static const Scene scene = MakeScene(DatasetDeformation("n3dv"), 3);
  return scene;
}

void BM_DeformForward_Dnerf(benchmark::State& state) { Forward(state, Dnerf()); }
void BM_DeformForwardBackward_Dnerf(benchmark::State& state) { ForwardBackward(state, Dnerf()); }
void BM_DeformForward_N3dv(benchmark::State& state) { Forward(state, N3dv()); }
void BM_DeformForwardBackward_N3dv(benchmark::State& state) { ForwardBackward(state, N3dv()); }

BENCHMARK(BM_DeformForward_Dnerf)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_DeformForwardBackward_Dnerf)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_DeformForward_N3dv)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_DeformForwardBackward_N3dv)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
