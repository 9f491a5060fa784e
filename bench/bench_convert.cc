// Size and speed of the splat file formats on real data, and the image cost of
// their lossy steps.
//
//   bench_convert [--benchmark_filter=...]      (data: $ATEX_DATA_DIR, else ../shared/data)
//
// Data sets:
//   biker   playcanvas_biker_v4.spz: 152,746 real trained Gaussians (SH degree 0),
//           decoded by our SPZ reader (so already on SPZ's grids).
//   garden  gsplat test_garden.npz: 138,766 real COLMAP points with colours; the
//           rest is synthetic: isotropic scales from the 3 nearest neighbours (as
//           3DGS initialises), identity rotations, opacity 0.5, SH degree 0.
//
// Times are process CPU time (all threads: SPZ v4 codes its streams in parallel),
// and items_per_second is computed from it, so figures stay comparable on a busy machine.
// BM_Format/<format>/<data>: whole-splat encode or decode. Counters: B_per_splat
//   (file bytes per Gaussian), items_per_second (Gaussians per second).
// BM_Positions/<codec>/<data>: the position stream alone (the other attributes are
//   constant so they cost next to nothing): bits_per_pos and decode speed.
// BM_QualityCost/<variant>: garden rendered from its 3 real cameras (648x420) by
//   the reference rasteriser, original vs. after the lossy round trip: psnr_min,
//   psnr_mean in dB, ref_mean = mean pixel value of the reference renders (one
//   iteration; the time is the renders').
#include <benchmark/benchmark.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <string>
#include <unordered_map>

#include "atex/camera.h"
#include "atex/container.h"
#include "atex/converters/drc.h"
#include "atex/converters/ply.h"
#include "atex/converters/spz.h"
#include "atex/metrics.h"
#include "atex/npy.h"
#include "atex/render.h"

namespace {

namespace fs = std::filesystem;
constexpr float kShC0 = 0.28209479177387814f;

fs::path DataDir() {
  if (const char* env = std::getenv("ATEX_DATA_DIR"); env != nullptr && *env != '\0') return env;
  // bench/bench_convert.cc -> <checkout>/../shared/data
  return fs::path(__FILE__).parent_path().parent_path().parent_path() / "shared" / "data";
}

struct Dataset {
  std::string error;  // non-empty: not available
  atex::Gaussians g;
  std::vector<atex::Camera> cameras;
};

// 3DGS's initial scale: sqrt of the mean squared distance to the 3 nearest
// neighbours, found on a uniform hash grid.
std::vector<float> NeighbourScales(const std::vector<float>& positions) {
  const size_t n = positions.size() / 3;
  float lo[3], hi[3];
  for (int k = 0; k < 3; ++k) lo[k] = hi[k] = positions[k];
  for (size_t i = 0; i < positions.size(); ++i) {
    lo[i % 3] = std::min(lo[i % 3], positions[i]);
    hi[i % 3] = std::max(hi[i % 3], positions[i]);
  }
  const double volume = std::max(1e-12, double(hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]));
  const double cell = std::cbrt(volume / std::max<size_t>(n, 1) * 4.0);
  auto key = [&](int64_t x, int64_t y, int64_t z) { return (x * 73856093) ^ (y * 19349663) ^ (z * 83492791); };
  auto coord = [&](float v, int k) { return static_cast<int64_t>(std::floor((v - lo[k]) / cell)); };
  std::unordered_multimap<int64_t, uint32_t> grid;
  grid.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    grid.emplace(key(coord(positions[i * 3], 0), coord(positions[i * 3 + 1], 1), coord(positions[i * 3 + 2], 2)),
                 static_cast<uint32_t>(i));
  }
  std::vector<float> scales(n);
  for (size_t i = 0; i < n; ++i) {
    const float* p = &positions[i * 3];
    std::array<double, 3> best{1e30, 1e30, 1e30};
    const int64_t cx = coord(p[0], 0), cy = coord(p[1], 1), cz = coord(p[2], 2);
    for (int r = 1; r <= 3 && best[2] >= 1e30; ++r) {
      best = {1e30, 1e30, 1e30};
      for (int64_t dx = -r; dx <= r; ++dx) {
        for (int64_t dy = -r; dy <= r; ++dy) {
          for (int64_t dz = -r; dz <= r; ++dz) {
            auto [b, e] = grid.equal_range(key(cx + dx, cy + dy, cz + dz));
            for (auto it = b; it != e; ++it) {
              if (it->second == i) continue;
              const float* q = &positions[size_t{it->second} * 3];
              const double d = double(p[0] - q[0]) * (p[0] - q[0]) + double(p[1] - q[1]) * (p[1] - q[1]) +
                               double(p[2] - q[2]) * (p[2] - q[2]);
              if (d < best[2]) {
                best[2] = d;
                std::sort(best.begin(), best.end());
              }
            }
          }
        }
      }
    }
    const double mean = best[2] < 1e30 ? (best[0] + best[1] + best[2]) / 3 : cell * cell;
    scales[i] = static_cast<float>(std::sqrt(std::max(mean, 1e-14)));
  }
  return scales;
}

const Dataset& Biker() {
  static const Dataset data = [] {
    Dataset d;
    auto g = atex::ReadSpzGaussians((DataDir() / "splats" / "playcanvas_biker_v4.spz").string());
    if (!g.ok()) {
      d.error = g.status().ToString();
    } else {
      d.g = std::move(g).value();
    }
    return d;
  }();
  return data;
}

const Dataset& Garden() {
  static const Dataset data = [] {
    Dataset d;
    auto npz = atex::ReadNpzFile((DataDir() / "gsplat_test_garden" / "test_garden.npz").string());
    if (!npz.ok()) {
      d.error = npz.status().ToString();
      return d;
    }
    auto& arrays = *npz;
    const std::vector<float> means = arrays["means3d"].ToFloat();    // [N][3]
    const std::vector<double> colors = arrays["colors"].ToDouble();  // [N][3] 0..255
    const size_t n = means.size() / 3;
    atex::Gaussians& g = d.g;
    g.sh_degree = 0;
    g.Resize(n);
    g.positions = means;
    const std::vector<float> scales = NeighbourScales(means);
    for (size_t i = 0; i < n; ++i) {
      for (int k = 0; k < 3; ++k) {
        g.log_scales[i * 3 + k] = std::log(scales[i]);
        g.sh[i * 3 + k] = static_cast<float>((colors[i * 3 + k] / 255.0 - 0.5) / kShC0);
      }
      g.rotations[i * 4] = 1.0f;
      g.opacity_logits[i] = 0.0f;
    }
    const std::vector<double> viewmats = arrays["viewmats"].ToDouble();  // [C][4][4] world-to-camera
    const std::vector<double> ks = arrays["Ks"].ToDouble();              // [C][3][3]
    const int width = static_cast<int>(*arrays["width"].Scalar("width"));
    const int height = static_cast<int>(*arrays["height"].Scalar("height"));
    for (size_t c = 0; c < viewmats.size() / 16; ++c) {
      atex::Camera cam;
      cam.width = width;
      cam.height = height;
      cam.fx = ks[c * 9 + 0];
      cam.fy = ks[c * 9 + 4];
      cam.cx = ks[c * 9 + 2];
      cam.cy = ks[c * 9 + 5];
      for (int k = 0; k < 16; ++k) cam.world_to_camera[k] = viewmats[c * 16 + k];
      cam.name = "garden camera " + std::to_string(c);
      d.cameras.push_back(cam);
    }
    return d;
  }();
  return data;
}

const Dataset& ByName(const std::string& name) { return name == "biker" ? Biker() : Garden(); }

// The same Gaussians with every attribute but the positions constant.
atex::Gaussians PositionsOnly(const atex::Gaussians& g) {
  atex::Gaussians p;
  p.sh_degree = 0;
  p.Resize(g.size());
  p.positions = g.positions;
  for (size_t i = 0; i < g.size(); ++i) p.rotations[i * 4] = 1.0f;
  return p;
}

atex::Asset AssetOf(const atex::Gaussians& g) {
  atex::Asset a;
  a.gaussians = g;
  return a;
}

atex::WriteOptions AtexOptions(atex::Codec codec, atex::ScalarEncoding encoding, bool draco_positions = false) {
  atex::WriteOptions w;
  w.codec = codec;
  w.positions = w.rotations = w.log_scales = w.opacities = w.sh_dc = w.sh_rest = encoding;
  w.draco_positions = draco_positions;
  w.draco_position_bits = 16;
  return w;
}

// A whole-splat format: encoder and decoder (decode returns the Gaussians).
struct Format {
  std::function<atex::StatusOr<std::vector<uint8_t>>(const atex::Gaussians&)> encode;
  std::function<atex::StatusOr<atex::Gaussians>(const std::vector<uint8_t>&)> decode;
};

std::map<std::string, Format> Formats() {
  using atex::Codec;
  using atex::ScalarEncoding;
  std::map<std::string, Format> f;
  f["ply"] = {[](const atex::Gaussians& g) { return atex::EncodePlyGaussians(g); },
              [](const std::vector<uint8_t>& b) { return atex::ReadPlyGaussiansFromMemory(b.data(), b.size()); }};
  for (int version : {3, 4}) {
    f["spz_v" + std::to_string(version)] = {
        [version](const atex::Gaussians& g) {
          atex::SpzWriteOptions o;
          o.version = version;
          return atex::EncodeSpz(g, o);
        },
        [](const std::vector<uint8_t>& b) { return atex::DecodeSpz(b.data(), b.size()); }};
  }
  auto atex_format = [](atex::WriteOptions w) {
    return Format{[w](const atex::Gaussians& g) { return atex::EncodeAsset(AssetOf(g), w); },
                  [](const std::vector<uint8_t>& b) -> atex::StatusOr<atex::Gaussians> {
                    auto a = atex::DecodeAsset(b.data(), b.size());
                    if (!a.ok()) return a.status();
                    return std::move(a->gaussians);
                  }};
  };
  f["atex_shuffle-zstd_f32"] = atex_format(AtexOptions(Codec::kShuffleZstd, ScalarEncoding::kFloat32));
  f["atex_shuffle-zstd_f16"] = atex_format(AtexOptions(Codec::kShuffleZstd, ScalarEncoding::kFloat16));
  f["atex_delta-shuffle-zstd_q16"] = atex_format(AtexOptions(Codec::kDeltaShuffleZstd, ScalarEncoding::kQuant16));
  f["atex_delta-shuffle-zstd_q8"] = atex_format(AtexOptions(Codec::kDeltaShuffleZstd, ScalarEncoding::kQuant8));
  if (atex::HaveDracoCodec()) {
    f["atex_q16_draco16"] = atex_format(AtexOptions(Codec::kDeltaShuffleZstd, ScalarEncoding::kQuant16, true));
  }
  return f;
}

const Format& FormatByName(const std::string& name) {
  static const std::map<std::string, Format> formats = Formats();
  return formats.at(name);
}

void BM_FormatEncode(benchmark::State& state, std::string format, std::string data) {
  const Dataset& d = ByName(data);
  if (!d.error.empty()) return state.SkipWithError(d.error.c_str());
  const Format& f = FormatByName(format);
  size_t bytes = 0;
  for (auto _ : state) {
    auto out = f.encode(d.g);
    if (!out.ok()) return state.SkipWithError(out.status().ToString().c_str());
    bytes = out->size();
    benchmark::DoNotOptimize(out->data());
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * d.g.size()));
  state.counters["B_per_splat"] = double(bytes) / d.g.size();
}

void BM_FormatDecode(benchmark::State& state, std::string format, std::string data) {
  const Dataset& d = ByName(data);
  if (!d.error.empty()) return state.SkipWithError(d.error.c_str());
  const Format& f = FormatByName(format);
  auto bytes = f.encode(d.g);
  if (!bytes.ok()) return state.SkipWithError(bytes.status().ToString().c_str());
  for (auto _ : state) {
    auto g = f.decode(*bytes);
    if (!g.ok()) return state.SkipWithError(g.status().ToString().c_str());
    benchmark::DoNotOptimize(g->positions.data());
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * d.g.size()));
  state.counters["B_per_splat"] = double(bytes->size()) / d.g.size();
}

// Position codecs: bytes of the position stream and a decode function.
struct PositionCodec {
  std::function<atex::StatusOr<std::vector<uint8_t>>(const atex::Gaussians&)> encode;
  std::function<atex::Status(const std::vector<uint8_t>&)> decode;
  std::function<uint64_t(const std::vector<uint8_t>&)> position_bytes;
};

uint64_t AtexPositionBytes(const std::vector<uint8_t>& file) {
  auto info = atex::InspectContainer(file.data(), file.size());
  if (!info.ok()) return 0;
  for (const auto& c : atex::ComponentBytes(*info)) {
    if (c.component == "positions") return c.bytes;
  }
  return 0;
}

PositionCodec ByPositionCodec(const std::string& name) {
  using atex::Codec;
  using atex::ScalarEncoding;
  auto atex_codec = [](atex::WriteOptions w) {
    return PositionCodec{[w](const atex::Gaussians& g) { return atex::EncodeAsset(AssetOf(PositionsOnly(g)), w); },
                         [](const std::vector<uint8_t>& b) { return atex::DecodeAsset(b.data(), b.size()).status(); },
                         AtexPositionBytes};
  };
  if (name == "atex_f32") return atex_codec(AtexOptions(Codec::kShuffleZstd, ScalarEncoding::kFloat32));
  if (name == "atex_f16") return atex_codec(AtexOptions(Codec::kShuffleZstd, ScalarEncoding::kFloat16));
  if (name == "atex_q16") return atex_codec(AtexOptions(Codec::kDeltaShuffleZstd, ScalarEncoding::kQuant16));
  if (name == "atex_q8") return atex_codec(AtexOptions(Codec::kDeltaShuffleZstd, ScalarEncoding::kQuant8));
  if (name == "atex_draco16") return atex_codec(AtexOptions(Codec::kDeltaShuffleZstd, ScalarEncoding::kQuant16, true));
  if (name == "spz_v4") {
    return PositionCodec{[](const atex::Gaussians& g) { return atex::EncodeSpz(PositionsOnly(g)); },
                         [](const std::vector<uint8_t>& b) { return atex::DecodeSpz(b.data(), b.size()).status(); },
                         [](const std::vector<uint8_t>& b) -> uint64_t {
                           uint64_t first = 0;  // TOC entry 0 (positions): compressed size, u64 LE at byte 32
                           for (int k = 7; k >= 0; --k) first = (first << 8) | b[32 + k];
                           return first;
                         }};
  }
  // drc<bits>
  const int bits = std::atoi(name.c_str() + 3);
  return PositionCodec{[bits](const atex::Gaussians& g) {
                         atex::DracoExportOptions o;
                         o.position_bits = bits;
                         return atex::EncodeDracoPointCloud(g, o);
                       },
                       [](const std::vector<uint8_t>& b) {
                         return atex::DecodeDracoPointCloud(b.data(), b.size()).status();
                       },
                       [](const std::vector<uint8_t>& b) -> uint64_t { return b.size(); }};
}

void BM_Positions(benchmark::State& state, std::string codec_name, std::string data) {
  const Dataset& d = ByName(data);
  if (!d.error.empty()) return state.SkipWithError(d.error.c_str());
  if (codec_name.find("draco") != std::string::npos && !atex::HaveDracoCodec()) {
    return state.SkipWithError("no Draco codec in this build");
  }
  const PositionCodec codec = ByPositionCodec(codec_name);
  auto bytes = codec.encode(d.g);
  if (!bytes.ok()) return state.SkipWithError(bytes.status().ToString().c_str());
  for (auto _ : state) {
    auto s = codec.decode(*bytes);
    if (!s.ok()) return state.SkipWithError(s.ToString().c_str());
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * d.g.size()));
  state.counters["bits_per_pos"] = 8.0 * double(codec.position_bytes(*bytes)) / d.g.size();
  state.counters["file_B_per_splat"] = double(bytes->size()) / d.g.size();
}

// Renders of garden from its cameras.
std::vector<atex::Image> Render(const atex::Gaussians& g, const std::vector<atex::Camera>& cameras) {
  std::vector<atex::Image> images;
  for (const auto& cam : cameras) {
    auto out = atex::RenderForward(cam, g, nullptr, atex::RenderSettings{});
    images.push_back(out.ok() ? atex::RenderedImage(*out) : atex::Image());
  }
  return images;
}

// The Gaussians after a lossy round trip (order preserved).
atex::StatusOr<atex::Gaussians> LossyRoundTrip(const std::string& variant, const atex::Gaussians& g) {
  if (variant == "spz_v4") {
    auto b = atex::EncodeSpz(g);
    if (!b.ok()) return b.status();
    return atex::DecodeSpz(b->data(), b->size());
  }
  if (variant.rfind("drc", 0) == 0) {  // positions through Draco, sequential (keeps the order)
    atex::DracoExportOptions o;
    o.position_bits = std::atoi(variant.c_str() + 3);
    o.kd_tree = false;
    auto b = atex::EncodeDracoPointCloud(g, o);
    if (!b.ok()) return b.status();
    auto pc = atex::DecodeDracoPointCloud(b->data(), b->size());
    if (!pc.ok()) return pc.status();
    atex::Gaussians out = g;
    out.positions = pc->positions;
    return out;
  }
  using atex::Codec;
  using atex::ScalarEncoding;
  atex::WriteOptions w = variant == "atex_f16"   ? AtexOptions(Codec::kShuffleZstd, ScalarEncoding::kFloat16)
                         : variant == "atex_q16" ? AtexOptions(Codec::kDeltaShuffleZstd, ScalarEncoding::kQuant16)
                         : variant == "atex_q8"  ? AtexOptions(Codec::kDeltaShuffleZstd, ScalarEncoding::kQuant8)
                                                 : AtexOptions(Codec::kDeltaShuffleZstd, ScalarEncoding::kQuant16, true);
  auto b = atex::EncodeAsset(AssetOf(g), w);
  if (!b.ok()) return b.status();
  auto a = atex::DecodeAsset(b->data(), b->size());
  if (!a.ok()) return a.status();
  return std::move(a->gaussians);
}

void BM_QualityCost(benchmark::State& state, std::string variant) {
  const Dataset& d = Garden();
  if (!d.error.empty()) return state.SkipWithError(d.error.c_str());
  if (variant.find("draco") != std::string::npos && !atex::HaveDracoCodec()) {
    return state.SkipWithError("no Draco codec in this build");
  }
  static const std::vector<atex::Image> reference = Render(d.g, d.cameras);
  double psnr_min = std::numeric_limits<double>::infinity(), psnr_sum = 0;
  for (auto _ : state) {
    auto lossy = LossyRoundTrip(variant, d.g);
    if (!lossy.ok()) return state.SkipWithError(lossy.status().ToString().c_str());
    const auto images = Render(*lossy, d.cameras);
    psnr_sum = 0;
    for (size_t c = 0; c < images.size(); ++c) {
      auto psnr = atex::Psnr(reference[c], images[c]);
      if (!psnr.ok()) return state.SkipWithError(psnr.status().ToString().c_str());
      psnr_min = std::min(psnr_min, *psnr);
      psnr_sum += *psnr;
    }
  }
  // Sanity: the reference renders are not empty (PSNR against a black image means nothing).
  double mean = 0, count = 0;
  for (const auto& image : reference) {
    for (float v : image.pixels) mean += v;
    count += static_cast<double>(image.pixels.size());
  }
  state.counters["ref_mean"] = count > 0 ? mean / count : 0.0;
  state.counters["psnr_min"] = psnr_min;
  state.counters["psnr_mean"] = psnr_sum / std::max<size_t>(d.cameras.size(), 1);
}

const char* kData[] = {"biker", "garden"};

int RegisterAll() {
  for (const char* data : kData) {
    for (const char* format : {"ply", "spz_v3", "spz_v4", "atex_shuffle-zstd_f32", "atex_shuffle-zstd_f16",
                               "atex_delta-shuffle-zstd_q16", "atex_delta-shuffle-zstd_q8", "atex_q16_draco16"}) {
      if (std::string(format) == "atex_q16_draco16" && !atex::HaveDracoCodec()) continue;
      benchmark::RegisterBenchmark((std::string("BM_FormatEncode/") + format + "/" + data).c_str(), BM_FormatEncode,
                                   format, data)
          ->MeasureProcessCPUTime()
          ->Unit(benchmark::kMillisecond);
      benchmark::RegisterBenchmark((std::string("BM_FormatDecode/") + format + "/" + data).c_str(), BM_FormatDecode,
                                   format, data)
          ->MeasureProcessCPUTime()
          ->Unit(benchmark::kMillisecond);
    }
    for (const char* codec : {"atex_f32", "atex_f16", "atex_q16", "atex_q8", "atex_draco16", "spz_v4", "drc11",
                              "drc16"}) {
      benchmark::RegisterBenchmark((std::string("BM_Positions/") + codec + "/" + data).c_str(), BM_Positions, codec,
                                   data)
          ->MeasureProcessCPUTime()
          ->Unit(benchmark::kMillisecond);
    }
  }
  for (const char* variant : {"spz_v4", "atex_f16", "atex_q16", "atex_q8", "atex_draco16", "drc16", "drc11"}) {
    benchmark::RegisterBenchmark((std::string("BM_QualityCost/") + variant).c_str(), BM_QualityCost, variant)
        ->Iterations(1)
        ->Unit(benchmark::kSecond);
  }
  return 0;
}

const int kRegistered = RegisterAll();

}  // namespace

BENCHMARK_MAIN();
