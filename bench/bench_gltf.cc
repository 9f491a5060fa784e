// glTF / splaTV export and import speed and output sizes on a synthetic asset shaped
// like a trained D-NeRF scene: N Gaussians with SH degree 3, adaptive textures (sides
// 1, 2 or 4) and the D-NeRF deformation config of 4DGaussians (C = 32, resolution
// 64^3 x 25, multires [1, 2], MLP width 64, position/scale/rotation heads).
// Counters: bytes of the output and bytes per Gaussian.
//   build/bench/bench_gltf --benchmark_counters_tabular=true
#include <benchmark/benchmark.h>

#include <random>

#include "atex/container.h"
#include "atex/converters/gltf.h"
#include "atex/converters/splatv.h"
#include "atex/deform.h"

namespace {

atex::Asset MakeScene(size_t n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
  atex::Asset asset;
  atex::Gaussians& g = asset.gaussians;
  g.sh_degree = 3;
  g.Resize(n);
  for (auto& v : g.positions) v = 1.3f * unit(rng);
  for (auto& v : g.rotations) v = unit(rng);
  for (auto& v : g.log_scales) v = -4.5f + 0.7f * unit(rng);
  for (auto& v : g.opacity_logits) v = 2.0f * unit(rng);
  for (size_t i = 0; i < g.sh.size(); ++i) g.sh[i] = (i % 48 < 3 ? 1.0f : 0.1f) * unit(rng);
  atex::TexturePool t;
  const uint8_t sides[3] = {1, 2, 4};
  for (size_t i = 0; i < n; ++i) {
    const uint32_t r = uint32_t(rng());
    t.heights.push_back(sides[(r % 10 < 7) ? 0 : 1 + r % 2]);  // mostly 1x1, as adaptive textures end up
    t.widths.push_back(sides[((r >> 8) % 10 < 7) ? 0 : 1 + (r >> 8) % 2]);
    t.axis_u.push_back(0);
    t.axis_v.push_back(1);
  }
  t.RebuildOffsets();
  t.texels.resize(t.texel_count() * 4);
  for (auto& v : t.texels) v = 0.5f * unit(rng);
  asset.textures = std::move(t);
  asset.metadata.texture_mode = "adaptive";
  atex::DeformationConfig c;  // DeformationConfig's defaults are the D-NeRF configuration
  c.sh_coeffs = g.sh_coeffs();
  c.aabb_lo = {-1.3f, -1.3f, -1.3f};
  c.aabb_hi = {1.3f, 1.3f, 1.3f};
  auto field = atex::InitDeformationField(c, seed);
  if (field.ok()) {
    // Native initialisation has constant time planes and 0.01-scaled last layers (no motion):
    // vary the time planes and amplify the heads so that the scene moves like a trained one.
    for (auto& planes : field->planes) {
      for (int p = 0; p < atex::kNumHexPlanes; ++p) {
        const bool time_plane = p == 2 || p == 4 || p == 5;  // xt, yt, zt
        for (auto& v : planes[size_t(p)]) v = 1.0f + (time_plane ? 0.5f : 0.2f) * unit(rng);
      }
    }
    for (auto& head : field->heads) {
      for (auto& v : head[1].weight) v *= 30.0f;
    }
    asset.deformation = std::move(field).value();
  }
  asset.metadata.axes = "opencv";
  return asset;
}

const atex::Asset& Scene() {
  static const atex::Asset scene = MakeScene(100000, 7);
  return scene;
}

void SetCounters(benchmark::State& state, size_t bytes, size_t gaussians) {
  state.counters["bytes"] = double(bytes);
  state.counters["B/gaussian"] = double(bytes) / double(gaussians);
  state.counters["gaussians/s"] = benchmark::Counter(double(gaussians), benchmark::Counter::kIsIterationInvariantRate);
}

atex::GltfExportOptions Flavour(int which) {
  atex::GltfExportOptions o;
  if (which >= 1) o.meshopt = true;                                // exact floats, int16 rotations
  if (which == 2) o.meshopt_float_bits = 14, o.raw_parameters = false;  // lossy
  return o;
}
const char* kFlavourNames[] = {"plain", "meshopt_exact", "meshopt_14bit"};

void BM_GlbEncode(benchmark::State& state) {
  const atex::Asset& scene = Scene();
  const atex::GltfExportOptions options = Flavour(int(state.range(0)));
  size_t bytes = 0;
  for (auto _ : state) {
    auto glb = atex::EncodeGlb(scene, options);
    if (!glb.ok()) state.SkipWithError(glb.status().ToString().c_str());
    bytes = glb->size();
    benchmark::DoNotOptimize(glb->data());
  }
  state.SetLabel(kFlavourNames[state.range(0)]);
  SetCounters(state, bytes, scene.gaussians.size());
}
BENCHMARK(BM_GlbEncode)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);

void BM_GlbDecode(benchmark::State& state) {
  const atex::Asset& scene = Scene();
  auto glb = atex::EncodeGlb(scene, Flavour(int(state.range(0))));
  if (!glb.ok()) {
    state.SkipWithError(glb.status().ToString().c_str());
    return;
  }
  for (auto _ : state) {
    auto asset = atex::DecodeGltf(glb->data(), glb->size());
    if (!asset.ok()) state.SkipWithError(asset.status().ToString().c_str());
    benchmark::DoNotOptimize(asset->gaussians.positions.data());
  }
  state.SetLabel(kFlavourNames[state.range(0)]);
  SetCounters(state, glb->size(), scene.gaussians.size());
}
BENCHMARK(BM_GlbDecode)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);

void BM_AtexEncode(benchmark::State& state) {  // the native container, for the size comparison
  const atex::Asset& scene = Scene();
  size_t bytes = 0;
  for (auto _ : state) {
    auto bytes_or = atex::EncodeAsset(scene);
    if (!bytes_or.ok()) state.SkipWithError(bytes_or.status().ToString().c_str());
    bytes = bytes_or->size();
  }
  SetCounters(state, bytes, scene.gaussians.size());
}
BENCHMARK(BM_AtexEncode)->Unit(benchmark::kMillisecond);

// splaTV: samples x 3 deformation passes dominate; 16 samples on the full scene.
void BM_SplatvEncode(benchmark::State& state) {
  const atex::Asset& scene = Scene();
  atex::SplatvOptions options;
  options.samples = int(state.range(0));
  options.psnr_times = 3;  // + 9 reference renders (default camera, 1280x720)
  size_t bytes = 0;
  for (auto _ : state) {
    auto result = atex::EncodeSplatv(scene, options);
    if (!result.ok()) state.SkipWithError(result.status().ToString().c_str());
    bytes = result->bytes.size();
    state.counters["pos_rms_rel"] = result->report.position_rms_relative;
    state.counters["rot_rms_deg"] = result->report.rotation_rms_deg;
    state.counters["opa_rms"] = result->report.opacity_rms;
    state.counters["motion_rel"] = result->report.motion_rms_relative;
    state.counters["psnr_full"] = result->report.psnr_full_db;
    state.counters["psnr_motion"] = result->report.psnr_motion_db;
  }
  SetCounters(state, bytes, scene.gaussians.size());
}
BENCHMARK(BM_SplatvEncode)->Arg(16)->Iterations(1)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
