// Where `atex fit` spends its time on a large textured model: one evaluation of a
// candidate move is apply (the lever), encode (exact bytes), decode (exact stored
// values), then load and render the probes. This times every part but the render
// (the CUDA backend's, measured on the device) on a synthetic model the size of
// Panoptic basketball's uniform 4x4 stage-2 model (360k Gaussians, SH degree 3,
// 16 texels each, a realistic deformation field, f32 streams as training writes).
//
//   bench_fit [--benchmark_filter=...]
//   bench_fit --write-model PATH   (writes the synthetic model, to time `atex fit` on it)
#include <benchmark/benchmark.h>

#include <cstdio>
#include <numeric>
#include <string>

#include "atex/container.h"
#include "atex/fit.h"
#include "atex/train/trainer.h"
#include "bench_models.h"
#include "fit/texture_shrink.h"

namespace {

constexpr size_t kGaussians = 360'000;

const atex::Asset& UniformModel() {
  static const atex::Asset asset = SyntheticModel(kGaussians, atex::container::SyntheticTextures::kUniform, 7);
  return asset;
}

const std::vector<uint8_t>& UniformFile() {
  static const std::vector<uint8_t> bytes = *atex::EncodeAsset(UniformModel());
  return bytes;
}

void BM_FitEncode(benchmark::State& state) {
  for (auto _ : state) {
    auto bytes = atex::EncodeAsset(UniformModel());
    benchmark::DoNotOptimize(bytes);
    state.counters["file_MB"] = static_cast<double>(bytes->size()) / 1e6;
  }
}

void BM_FitDecode(benchmark::State& state) {
  atex::ReadOptions read;
  read.read_stats = false;
  for (auto _ : state) {
    auto asset = atex::DecodeAsset(UniformFile().data(), UniformFile().size(), read);
    benchmark::DoNotOptimize(asset);
  }
}

// The same for the decode: the candidate's other streams come from the decode cache (filled
// by the state's own decode).
void BM_FitDecodeCachedOneStreamChanged(benchmark::State& state) {
  atex::ReadOptions read;
  read.read_stats = false;
  read.verify_checksums = false;  // as the fitter's measurements decode
  std::vector<uint8_t> files[2];
  for (int k = 0; k < 2; ++k) {
    atex::WriteOptions w;
    w.rotations = k == 0 ? atex::ScalarEncoding::kQuant16 : atex::ScalarEncoding::kFloat16;
    files[k] = *atex::EncodeAsset(UniformModel(), w);
  }
  atex::DecodeCache cache(3);
  (void)atex::DecodeAsset(files[0].data(), files[0].size(), read, &cache);
  int k = 1;
  for (auto _ : state) {
    auto asset = atex::DecodeAsset(files[k].data(), files[k].size(), read, &cache);
    benchmark::DoNotOptimize(asset);
    k = 1 - k;
  }
}

// What the fitter pays per candidate that changes one stream's encoding: the other
// chunks come from the cache (filled by the state's own encode).
void BM_FitEncodeCachedOneStreamChanged(benchmark::State& state) {
  atex::EncodeCache cache(3);
  (void)atex::EncodeAsset(UniformModel(), {}, &cache);
  bool flip = false;
  for (auto _ : state) {
    atex::WriteOptions w;
    w.rotations = flip ? atex::ScalarEncoding::kQuant16 : atex::ScalarEncoding::kFloat16;
    flip = !flip;
    auto bytes = atex::EncodeAsset(UniformModel(), w, &cache);
    benchmark::DoNotOptimize(bytes);
  }
}

// One texture move of the plan, `count` texture axes halved, timed on a fresh copy of the
// model each iteration; `memo` as the plan passes it (null: none).
void TimeShrinkTextures(benchmark::State& state, uint64_t count, atex::fit::TextureShrinkMemo* memo) {
  atex::fit::Move move;
  move.lever = atex::fit::Lever::kTextures;
  move.count = count;
  std::vector<uint32_t> kept(kGaussians);
  std::iota(kept.begin(), kept.end(), 0u);
  atex::WriteOptions write;
  for (auto _ : state) {
    state.PauseTiming();
    atex::Asset asset = UniformModel();
    state.ResumeTiming();
    auto s = atex::fit::ApplyMove(move, {}, &asset, &write, &kept, 4, memo);
    benchmark::DoNotOptimize(s);
  }
}

void BM_FitShrinkTextures(benchmark::State& state) {
  // About 10 % of the growable textures lose an axis, every residual computed.
  TimeShrinkTextures(state, kGaussians / 10, nullptr);
}

void BM_FitShrinkTexturesSeenBefore(benchmark::State& state) {
  // The move as the plan makes it: the memo already holds the residuals of the state's
  // textures (an earlier candidate of the same state computed them), not of those it shrinks.
  atex::fit::TextureShrinkMemo memo;
  {
    atex::fit::Move one;
    one.lever = atex::fit::Lever::kTextures;
    one.count = 1;  // the residuals of every texture as it is, not of the shrunk ones
    std::vector<uint32_t> kept(kGaussians);
    std::iota(kept.begin(), kept.end(), 0u);
    atex::WriteOptions write;
    atex::Asset warm = UniformModel();
    (void)atex::fit::ApplyMove(one, {}, &warm, &write, &kept, 4, &memo);
  }
  TimeShrinkTextures(state, kGaussians / 10, &memo);
}

void BM_FitPrune(benchmark::State& state) {
  const std::vector<uint32_t> order = atex::fit::ImportanceOrder(UniformModel(), 6666);
  for (auto _ : state) {
    state.PauseTiming();
    atex::Asset asset = UniformModel();
    std::vector<uint32_t> kept(kGaussians);
    std::iota(kept.begin(), kept.end(), 0u);
    state.ResumeTiming();
    atex::fit::Move move;
    move.lever = atex::fit::Lever::kPrune;
    move.count = kGaussians / 10;
    atex::WriteOptions write;
    auto s = atex::fit::ApplyMove(move, order, &asset, &write, &kept);
    benchmark::DoNotOptimize(s);
  }
}

// What one count-search trial of the refill encodes: every chunk of a pruned asset (a prune
// changes every per-Gaussian stream), with the quantised encodings a Panoptic plan reaches.
void BM_FitEncodePrunedQuantised(benchmark::State& state) {
  const std::vector<uint32_t> order = atex::fit::ImportanceOrder(UniformModel(), 6666);
  atex::Asset asset = UniformModel();
  std::vector<uint32_t> kept(kGaussians);
  std::iota(kept.begin(), kept.end(), 0u);
  atex::fit::Move move;
  move.lever = atex::fit::Lever::kPrune;
  move.count = kGaussians / 10;
  atex::WriteOptions write;
  write.write_stats = false;
  write.rotations = write.log_scales = write.opacities = write.sh_dc = atex::ScalarEncoding::kQuant16;
  write.sh_rest = write.texels = atex::ScalarEncoding::kQuant8;
  if (!atex::fit::ApplyMove(move, order, &asset, &write, &kept).ok()) {
    state.SkipWithError("prune failed");
    return;
  }
  for (auto _ : state) {
    auto bytes = atex::EncodeAsset(asset, write);
    benchmark::DoNotOptimize(bytes);
    state.counters["file_MB"] = static_cast<double>(bytes->size()) / 1e6;
  }
}

void BM_FitStateFromAsset(benchmark::State& state) {
  for (auto _ : state) {
    auto s = atex::train::StateFromAsset(UniformModel());
    benchmark::DoNotOptimize(s);
  }
}

// ApplyPlan when the move that crosses the budget is indivisible and lands far below it:
// RefillSlack then undoes divisible moves (here texture and prune moves, latest first),
// bisecting each one's count against the budget. The plan: texels f16, five texture
// moves, one prune move, then sh_rest q8; the budget leaves the last move 60 % of its
// saving as slack, more than the prune and last texture moves can take back.
void BM_FitApplyPlanRefill(benchmark::State& state) {
  const atex::Asset& asset = UniformModel();
  atex::fit::Plan plan;
  plan.prune_order = atex::fit::ImportanceOrder(asset, 6666);
  auto add = [&](atex::fit::Lever lever, uint64_t count, atex::fit::Stream stream, atex::ScalarEncoding e) {
    atex::fit::Move m;
    m.lever = lever;
    m.count = count;
    m.stream = stream;
    m.encoding = e;
    plan.moves.push_back(m);
  };
  using atex::fit::Lever;
  using atex::fit::Stream;
  add(Lever::kEncoding, 0, Stream::kTexels, atex::ScalarEncoding::kFloat16);
  for (int i = 0; i < 5; ++i) add(Lever::kTextures, kGaussians / 10, Stream::kPositions, {});
  add(Lever::kPrune, kGaussians / 20, Stream::kPositions, {});
  add(Lever::kEncoding, 0, Stream::kShRest, atex::ScalarEncoding::kQuant8);
  // Record each move's size as BuildPlan would.
  atex::Asset a = asset;
  atex::WriteOptions write;
  std::vector<uint32_t> kept(kGaussians);
  std::iota(kept.begin(), kept.end(), 0u);
  for (atex::fit::Move& m : plan.moves) {
    if (!atex::fit::ApplyMove(m, plan.prune_order, &a, &write, &kept).ok()) state.SkipWithError("ApplyMove");
    m.bytes_after = atex::EncodeAsset(a, write)->size();
  }
  const uint64_t before_last = plan.moves[plan.moves.size() - 2].bytes_after, last = plan.moves.back().bytes_after;
  const uint64_t budget = last + (before_last - last) * 6 / 10;
  for (auto _ : state) {
    auto fitted = atex::fit::ApplyPlan(asset, plan, {}, budget);
    if (!fitted.ok()) state.SkipWithError(fitted.status().ToString().c_str());
    state.counters["slack_bytes"] = fitted.ok() ? static_cast<double>(budget - fitted->bytes.size()) : -1;
    state.counters["moves_kept"] = fitted.ok() ? static_cast<double>(fitted->moves.size()) : -1;
  }
}

// The render-only state the fitter loads for each measurement on a GPU (no moments: the
// backend zeroes them on the device).
void BM_FitRenderStateFromAsset(benchmark::State& state) {
  for (auto _ : state) {
    auto s = atex::train::RenderStateFromAsset(UniformModel());
    benchmark::DoNotOptimize(s);
  }
}

BENCHMARK(BM_FitApplyPlanRefill)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(1);
BENCHMARK(BM_FitEncode)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_FitDecode)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_FitEncodeCachedOneStreamChanged)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_FitDecodeCachedOneStreamChanged)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_FitShrinkTextures)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_FitShrinkTexturesSeenBefore)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_FitPrune)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_FitEncodePrunedQuantised)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_FitStateFromAsset)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_FitRenderStateFromAsset)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

int main(int argc, char** argv) {
  if (argc == 3 && std::string(argv[1]) == "--write-model") {
    const atex::Status written = atex::WriteAssetFile(argv[2], UniformModel(), {});
    if (!written.ok()) {
      std::fprintf(stderr, "%s\n", written.ToString().c_str());
      return 1;
    }
    return 0;
  }
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
