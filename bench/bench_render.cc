// CPU reference rasteriser: forward and forward+backward time per frame.
//
//   bench_render [--benchmark_filter=...]
//
// Scenes follow REFERENCE.md §8: random Gaussians in the camera frustum,
// z ∈ [2, 6], log-scale ≈ ln 0.015 ± 0.4, SH degree 3 (all active), one view with a
// 65° horizontal field of view. Arguments: Gaussians, width, height, textures
// (0 = none, 1 = uniform 4×4, 2 = adaptive: sides drawn from {1, 2, 4} per axis),
// all texels random. Counters: visible = Gaussians with positive radius,
// pairs = (tile, Gaussian) entries.
#include <benchmark/benchmark.h>

#include <cmath>
#include <map>
#include <random>
#include <tuple>

#include "atex/render.h"

namespace {

struct BenchScene {
  atex::Camera camera;
  atex::Gaussians gaussians;
  atex::TexturePool textures;
  bool textured = false;
};

BenchScene MakeScene(int count, int width, int height, int texture_kind) {
  BenchScene s;
  std::mt19937 rng(1234);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  std::normal_distribution<float> normal(0.0f, 1.0f);
  auto& cam = s.camera;
  cam.width = width;
  cam.height = height;
  cam.fx = cam.fy = 0.5 * width / std::tan(0.5 * 65.0 * M_PI / 180.0);
  cam.cx = 0.5 * width;
  cam.cy = 0.5 * height;
  auto& g = s.gaussians;
  g.sh_degree = 3;
  g.Resize(count);
  const float half_x = 0.5f * width / float(cam.fx), half_y = 0.5f * height / float(cam.fy);
  for (int i = 0; i < count; ++i) {
    const float z = 2.0f + 4.0f * unit(rng);
    g.positions[3 * i] = (2 * unit(rng) - 1) * half_x * z;
    g.positions[3 * i + 1] = (2 * unit(rng) - 1) * half_y * z;
    g.positions[3 * i + 2] = z;
    for (int k = 0; k < 3; ++k) g.log_scales[3 * i + k] = std::log(0.015f) + 0.4f * normal(rng);
    for (int k = 0; k < 4; ++k) g.rotations[4 * i + k] = normal(rng);
    g.opacity_logits[i] = 4 * unit(rng) - 2;
    for (int k = 0; k < 16 * 3; ++k) g.sh[size_t(i) * 48 + k] = (k < 3 ? 1.0f : 0.2f) * normal(rng);
  }
  if (texture_kind != 0) {
    s.textured = true;
    auto pool = atex::AttachTextures(g, texture_kind == 1 ? atex::TextureMode::kUniform : atex::TextureMode::kAdaptive);
    s.textures = std::move(*pool);
    if (texture_kind == 2) {
      const uint8_t sides[3] = {1, 2, 4};
      for (int i = 0; i < count; ++i) {
        s.textures.heights[i] = sides[rng() % 3];
        s.textures.widths[i] = sides[rng() % 3];
      }
      s.textures.RebuildOffsets();
      s.textures.texels.resize(s.textures.texel_count() * 4);
    }
    for (float& t : s.textures.texels) t = normal(rng);
  }
  return s;
}

const BenchScene& Scene(int count, int width, int height, int texture_kind) {
  static std::map<std::tuple<int, int, int, int>, BenchScene> cache;
  const auto key = std::make_tuple(count, width, height, texture_kind);
  auto it = cache.find(key);
  if (it == cache.end()) it = cache.emplace(key, MakeScene(count, width, height, texture_kind)).first;
  return it->second;
}

void SetCounters(benchmark::State& state, const atex::RenderOutput& out) {
  int visible = 0;
  for (int32_t r : out.radius) visible += r > 0;
  state.counters["visible"] = visible;
  state.counters["pairs"] = double(out.state.tile_gaussians.size());
}

void BM_RenderForward(benchmark::State& state) {
  const auto& s = Scene(int(state.range(0)), int(state.range(1)), int(state.range(2)), int(state.range(3)));
  const atex::TexturePool* tex = s.textured ? &s.textures : nullptr;
  atex::RenderSettings settings;
  atex::RenderOutput last;
  for (auto _ : state) {
    auto out = atex::RenderForward(s.camera, s.gaussians, tex, settings);
    if (!out.ok()) {
      state.SkipWithError(out.status().ToString().c_str());
      return;
    }
    last = std::move(*out);
    benchmark::DoNotOptimize(last.color.data());
  }
  SetCounters(state, last);
}

void BM_RenderForwardBackward(benchmark::State& state) {
  const auto& s = Scene(int(state.range(0)), int(state.range(1)), int(state.range(2)), int(state.range(3)));
  const atex::TexturePool* tex = s.textured ? &s.textures : nullptr;
  atex::RenderSettings settings;
  std::vector<float> grad(size_t(s.camera.width) * s.camera.height * 3, 1e-3f);
  atex::RenderOutput last;
  atex::RenderGradients grads;
  for (auto _ : state) {
    auto out = atex::RenderForward(s.camera, s.gaussians, tex, settings);
    if (!out.ok()) {
      state.SkipWithError(out.status().ToString().c_str());
      return;
    }
    const atex::Status st = atex::RenderBackward(s.camera, s.gaussians, tex, settings, *out, grad.data(), nullptr, &grads);
    if (!st.ok()) {
      state.SkipWithError(st.ToString().c_str());
      return;
    }
    last = std::move(*out);
    benchmark::DoNotOptimize(grads.gaussians.positions.data());
  }
  SetCounters(state, last);
}

void Arguments(benchmark::internal::Benchmark* b) {
  b->ArgNames({"gaussians", "width", "height", "textures"});
  for (int textures : {0, 1, 2}) {
    b->Args({10'000, 100, 100, textures});
    b->Args({100'000, 640, 360, textures});
  }
  b->Unit(benchmark::kMillisecond)->UseRealTime();
}

BENCHMARK(BM_RenderForward)->Apply(Arguments);
BENCHMARK(BM_RenderForwardBackward)->Apply(Arguments);

}  // namespace

BENCHMARK_MAIN();
