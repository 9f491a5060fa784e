// Data and metrics: the training loss with its gradient, SSIM, image decoding,
// nearest-neighbour scales, and (with the real data) Panoptic initialisation.
//   build/bench/bench_data [--benchmark_filter=...]
// The Panoptic benchmark reads $ATEX_DATA_DIR (default ../shared/data) and is
// skipped when the data is absent.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <random>

#include "atex/dataset.h"
#include "atex/image.h"
#include "atex/init.h"
#include "atex/metrics.h"

namespace {

// A smooth image with some texture (compresses like a photograph, not like noise).
atex::Image TestImage(int width, int height, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> noise(-0.05f, 0.05f);
  atex::Image image(width, height, 3);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      for (int c = 0; c < 3; ++c) {
        const float v = 0.5f + 0.3f * std::sin(0.02f * x + 0.03f * y + c) + noise(rng);
        image.at(x, y, c) = std::min(1.0f, std::max(0.0f, v));
      }
    }
  }
  return image;
}

void BM_PhotometricLossWithGradient(benchmark::State& state) {
  const int width = static_cast<int>(state.range(0)), height = static_cast<int>(state.range(1));
  const atex::Image target = TestImage(width, height, 1);
  const atex::Image rendered = TestImage(width, height, 2);
  std::vector<float> grad(rendered.pixels.size());
  for (auto _ : state) {
    float loss = atex::PhotometricLoss<float>(rendered.pixels.data(), target.pixels.data(), width, height, 0.2,
                                              grad.data());
    benchmark::DoNotOptimize(loss);
    benchmark::ClobberMemory();
  }
  state.counters["Mpixel/s"] =
      benchmark::Counter(double(width) * height * state.iterations() / 1e6, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_PhotometricLossWithGradient)->Args({640, 360})->Args({1352, 1014})->Unit(benchmark::kMillisecond);

void BM_SsimDouble(benchmark::State& state) {
  const atex::Image a = TestImage(640, 360, 1), b = TestImage(640, 360, 2);
  for (auto _ : state) benchmark::DoNotOptimize(*atex::Ssim(a, b));
}
BENCHMARK(BM_SsimDouble)->Unit(benchmark::kMillisecond);

void BM_DecodeImage(benchmark::State& state) {
  const auto format = static_cast<atex::ImageFormat>(state.range(0));
  const auto bytes = atex::EncodeImage(TestImage(640, 360, 3), format);
  if (!bytes.ok()) {
    state.SkipWithError(bytes.status().ToString().c_str());
    return;
  }
  for (auto _ : state) {
    auto image = atex::DecodeImage(bytes->data(), bytes->size(), "bench");
    benchmark::DoNotOptimize(image);
  }
  state.SetLabel(state.range(0) == 0 ? "png 640x360" : state.range(0) == 1 ? "jpeg 640x360" : "exr 640x360");
}
BENCHMARK(BM_DecodeImage)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);

void BM_NearestNeighborLogScales(benchmark::State& state) {
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<float> points(state.range(0) * 3);
  for (float& v : points) v = u(rng);
  for (auto _ : state) benchmark::DoNotOptimize(atex::NearestNeighborLogScales(points, 3));
  state.counters["points/s"] = benchmark::Counter(double(state.range(0)) * state.iterations(), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_NearestNeighborLogScales)->Arg(100000)->Unit(benchmark::kMillisecond);

void BM_InitPanopticHullAndVolume(benchmark::State& state) {
  const char* env = std::getenv("ATEX_DATA_DIR");
  const std::filesystem::path root = std::filesystem::path(env ? env : "../shared/data") / "panoptic_basketball";
  if (!std::filesystem::exists(root / "train_meta.json")) {
    state.SkipWithError("Panoptic data not found (set ATEX_DATA_DIR)");
    return;
  }
  atex::DatasetOptions options;
  options.max_timesteps = 1;
  auto dataset = atex::OpenDataset(root.string(), options);
  if (!dataset.ok()) {
    state.SkipWithError(dataset.status().ToString().c_str());
    return;
  }
  size_t points = 0;
  for (auto _ : state) {
    auto g = atex::InitializeGaussians(**dataset);  // defaults: 60k hull + 30k volume points, 128^3 grid
    points = g.ok() ? g->size() : 0;
    benchmark::DoNotOptimize(points);
  }
  state.counters["gaussians"] = double(points);
}
BENCHMARK(BM_InitPanopticHullAndVolume)->Unit(benchmark::kMillisecond)->Iterations(3);

}  // namespace

BENCHMARK_MAIN();
