// .atex encode and decode throughput for 1 M Gaussians with SH degree 3, mixed
// (anisotropic) textures, a D-NeRF-sized deformation field and statistics, per
// codec and per scalar encoding.
//
//   bench_container [--benchmark_filter=...]
//
// Counters: bytes_per_second = in-memory asset bytes (f32 arrays) per second;
// items_per_second = Gaussians per second; file_MB; B_per_G_<component> = file
// bytes per Gaussian of each component (ComponentBytes), B_per_G = all of them.
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <map>
#include <string>

#include "atex/container.h"
#include "bench_models.h"

namespace {

constexpr size_t kGaussians = 1'000'000;

const atex::Asset& BenchAsset() {
  static const atex::Asset asset = SyntheticModel(kGaussians, atex::container::SyntheticTextures::kMixed, 1);
  return asset;
}

// Bytes of the asset's arrays in memory (what a trainer holds).
uint64_t AssetBytes(const atex::Asset& a) {
  const atex::Gaussians& g = a.gaussians;
  uint64_t floats = g.positions.size() + g.rotations.size() + g.log_scales.size() + g.opacity_logits.size() + g.sh.size();
  uint64_t bytes = 0;
  if (a.textures) {
    floats += a.textures->texels.size();
    bytes += a.textures->size() * 4;  // h, w, axes
  }
  if (a.deformation) {
    for (const auto& s : a.deformation->planes) {
      for (const auto& p : s) floats += p.size();
    }
    for (const auto& l : a.deformation->trunk) floats += l.weight.size() + l.bias.size();
    for (const auto& h : a.deformation->heads) {
      for (const auto& l : h) floats += l.weight.size() + l.bias.size();
    }
  }
  if (a.stats) floats += a.stats->size() * 4;
  return bytes + floats * 4;
}

struct Config {
  const char* name;
  atex::WriteOptions options;
};

atex::WriteOptions With(atex::Codec codec, atex::ScalarEncoding all) {
  atex::WriteOptions w;
  w.codec = codec;
  w.positions = w.rotations = w.log_scales = w.opacities = w.sh_dc = w.sh_rest = w.texels = w.deformation_grids = all;
  return w;
}

std::vector<Config> Configs() {
  using atex::Codec;
  using atex::ScalarEncoding;
  std::vector<Config> configs = {
      {"raw/f32", With(Codec::kRaw, ScalarEncoding::kFloat32)},
      {"zstd/f32", With(Codec::kZstd, ScalarEncoding::kFloat32)},
      {"shuffle-zstd/f32", With(Codec::kShuffleZstd, ScalarEncoding::kFloat32)},
      {"shuffle-zstd/f16", With(Codec::kShuffleZstd, ScalarEncoding::kFloat16)},
      {"delta-shuffle-zstd/q16", With(Codec::kDeltaShuffleZstd, ScalarEncoding::kQuant16)},
      {"delta-shuffle-zstd/q8", With(Codec::kDeltaShuffleZstd, ScalarEncoding::kQuant8)},
  };
  // A practical mix: exact positions, half rotations/scales/opacities/DC, 8-bit SH rest
  // and texels, half grids.
  atex::WriteOptions mix = With(Codec::kDeltaShuffleZstd, ScalarEncoding::kFloat16);
  mix.positions = ScalarEncoding::kFloat32;
  mix.sh_rest = ScalarEncoding::kQuant8;
  mix.texels = ScalarEncoding::kQuant8;
  configs.push_back({"delta-shuffle-zstd/mix", mix});
  if (atex::HaveDracoCodec()) {
    atex::WriteOptions draco = With(Codec::kShuffleZstd, ScalarEncoding::kFloat32);
    draco.draco_positions = true;
    draco.draco_position_bits = 16;
    configs.push_back({"draco16+shuffle-zstd/f32", draco});
  }
  return configs;
}

void SetCounters(benchmark::State& state, const std::vector<uint8_t>& file) {
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * kGaussians));
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations() * AssetBytes(BenchAsset())));
  state.counters["file_MB"] = static_cast<double>(file.size()) / 1e6;
  state.counters["B_per_G"] = static_cast<double>(file.size()) / kGaussians;
  auto info = atex::InspectContainer(file.data(), file.size());
  if (!info.ok()) return;
  for (const atex::ComponentSize& c : atex::ComponentBytes(*info)) {
    if (c.component == "header") continue;
    state.counters["B_per_G_" + c.component] = static_cast<double>(c.bytes) / kGaussians;
  }
}

void BM_Encode(benchmark::State& state, atex::WriteOptions options) {
  const atex::Asset& asset = BenchAsset();
  std::vector<uint8_t> file;
  for (auto _ : state) {
    auto bytes = atex::EncodeAsset(asset, options);
    if (!bytes.ok()) {
      state.SkipWithError(bytes.status().ToString().c_str());
      return;
    }
    file = std::move(bytes).value();
    benchmark::DoNotOptimize(file.data());
  }
  SetCounters(state, file);
}

void BM_Decode(benchmark::State& state, atex::WriteOptions options) {
  auto bytes = atex::EncodeAsset(BenchAsset(), options);
  if (!bytes.ok()) {
    state.SkipWithError(bytes.status().ToString().c_str());
    return;
  }
  for (auto _ : state) {
    auto asset = atex::DecodeAsset(bytes->data(), bytes->size());  // every CRC and value checked
    if (!asset.ok()) {
      state.SkipWithError(asset.status().ToString().c_str());
      return;
    }
    benchmark::DoNotOptimize(asset->gaussians.positions.data());
  }
  SetCounters(state, *bytes);
}

// ReadAssetFile of a real file (ATEX_BENCH_READ_FILE, default the bundled lego sample, relative
// to the working directory): the C++ baseline of bench/python_read.py.
void BM_ReadFile(benchmark::State& state, std::string path) {
  for (auto _ : state) {
    auto asset = atex::ReadAssetFile(path);
    if (!asset.ok()) {
      state.SkipWithError(asset.status().ToString().c_str());
      return;
    }
    benchmark::DoNotOptimize(asset->gaussians.positions.data());
  }
}

const bool kRegistered = [] {
  const char* read_file = std::getenv("ATEX_BENCH_READ_FILE");
  benchmark::RegisterBenchmark("ReadFile", BM_ReadFile,
                               std::string(read_file ? read_file : "samples/lego_adaptive_2MiB.atex"))
      ->Unit(benchmark::kMillisecond)
      ->UseRealTime();
  for (const Config& c : Configs()) {
    benchmark::RegisterBenchmark((std::string("Encode/") + c.name).c_str(), BM_Encode, c.options)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
    benchmark::RegisterBenchmark((std::string("Decode/") + c.name).c_str(), BM_Decode, c.options)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
  }
  return true;
}();

}  // namespace

BENCHMARK_MAIN();
