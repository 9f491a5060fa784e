// EncodeAsset -> DecodeAsset over every chunk type, codec and encoding, on
// random content and the edge cases of the issue (0 and 1 Gaussians, uniform 1x1
// and 4x4 textures, mixed anisotropic textures, with and without deformation,
// SH degree 0..3).
#include <gtest/gtest.h>

#include <algorithm>

#include <cmath>
#include <cstring>

#include "atex/container.h"
#include "container/asset_compare.h"
#include "container/half.h"
#include "container/synthetic_asset.h"
#include "core/test_support.h"

namespace atex {
namespace {

using container::MakeSyntheticAsset;
using container::SyntheticAssetOptions;
using container::SyntheticTextures;

Asset RoundTrip(const Asset& asset, const WriteOptions& options, std::vector<uint8_t>* bytes_out = nullptr) {
  auto bytes = EncodeAsset(asset, options);
  EXPECT_TRUE(bytes.ok()) << bytes.status().ToString();
  if (!bytes.ok()) return {};
  auto back = DecodeAsset(bytes->data(), bytes->size());
  EXPECT_TRUE(back.ok()) << back.status().ToString();
  if (bytes_out) *bytes_out = *bytes;
  return back.ok() ? std::move(back).value() : Asset{};
}

constexpr Codec kLosslessCodecs[] = {Codec::kRaw, Codec::kZstd, Codec::kShuffleZstd, Codec::kDeltaShuffleZstd};

TEST(RoundTrip, LosslessForEveryCodecShapeAndDegree) {
  int cases = 0;
  for (size_t n : {0, 1, 2, 300}) {
    for (int degree = 0; degree <= 3; ++degree) {
      for (SyntheticTextures tex : {SyntheticTextures::kNone, SyntheticTextures::kUniform, SyntheticTextures::kMixed}) {
        for (bool deformation : {false, true}) {
          SyntheticAssetOptions o;
          o.seed = 100 + n + degree * 7;
          o.gaussians = n;
          o.sh_degree = degree;
          o.textures = tex;
          o.deformation = deformation;
          o.sh_head = degree > 0 && deformation;
          o.uniform_h = degree % 2 ? 1 : 4;
          o.uniform_w = o.uniform_h;
          const Asset asset = MakeSyntheticAsset(o);
          for (Codec codec : kLosslessCodecs) {
            for (bool fallback : {true, false}) {
              WriteOptions w;
              w.codec = codec;
              w.fallback_to_raw = fallback;
              const Asset back = RoundTrip(asset, w);
              ASSERT_TRUE(testing::AssetsEqual(asset, back))
                  << "n " << n << " degree " << degree << " textures " << int(tex) << " deformation " << deformation
                  << " codec " << CodecName(codec) << " fallback " << fallback;
              ++cases;
            }
          }
        }
      }
    }
  }
  EXPECT_EQ(cases, 4 * 4 * 3 * 2 * 4 * 2);
}

TEST(RoundTrip, AnisotropicTexturesOfEveryShape) {
  // One Gaussian of each of the nine shapes, in an order that makes offsets uneven.
  SyntheticAssetOptions o;
  o.gaussians = 9;
  o.sh_degree = 1;
  o.textures = SyntheticTextures::kMixed;
  Asset asset = MakeSyntheticAsset(o);
  TexturePool& t = *asset.textures;
  const uint8_t sides[] = {1, 2, 4};
  for (int i = 0; i < 9; ++i) {
    t.heights[i] = sides[(i * 4) % 9 / 3];
    t.widths[i] = sides[(i * 4) % 3];
  }
  t.RebuildOffsets();
  t.texels.resize(t.texel_count() * 4);
  for (size_t i = 0; i < t.texels.size(); ++i) t.texels[i] = 0.01f * static_cast<float>(i) - 1.0f;
  ASSERT_TRUE(ValidateAsset(asset).ok());
  const TextureHistogram h = ComputeTextureHistogram(t);
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) EXPECT_EQ(h.counts[a][b], 1u) << a << " " << b;
  }
  EXPECT_EQ(h.texels, 49u);  // (1 + 2 + 4)^2
  for (Codec codec : kLosslessCodecs) {
    WriteOptions w;
    w.codec = codec;
    w.texels = ScalarEncoding::kQuant8;
    const Asset back = RoundTrip(asset, w);
    testing::Tolerances tol;
    tol.texels = 0.5f * (0.01f * 195) / 255.0f + 1e-6f;  // half a step of the per-channel range
    EXPECT_TRUE(testing::AssetsNear(asset, back, tol)) << CodecName(codec);
  }
}

// Largest |value| of an array, for the f16 tolerance.
float MaxAbs(const std::vector<float>& v) {
  float m = 0;
  for (float x : v) m = std::max(m, std::fabs(x));
  return m;
}
float Range(const std::vector<float>& v) {
  if (v.empty()) return 0;
  auto [lo, hi] = std::minmax_element(v.begin(), v.end());
  return *hi - *lo;
}

TEST(RoundTrip, LossyEncodingsStayWithinTheirPrecision) {
  SyntheticAssetOptions o;
  o.gaussians = 500;
  o.sh_degree = 3;
  const Asset asset = MakeSyntheticAsset(o);
  const Gaussians& g = asset.gaussians;
  for (ScalarEncoding e : {ScalarEncoding::kFloat16, ScalarEncoding::kQuant16, ScalarEncoding::kQuant8}) {
    for (Codec codec : {Codec::kRaw, Codec::kShuffleZstd, Codec::kDeltaShuffleZstd}) {
      WriteOptions w;
      w.codec = codec;
      w.positions = w.rotations = w.log_scales = w.opacities = w.sh_dc = w.sh_rest = w.texels = w.deformation_grids = e;
      const Asset back = RoundTrip(asset, w);
      // f16: relative 2^-11; quant: half a step of the whole array's range (a
      // bound on every per-component range).
      auto tol = [&](const std::vector<float>& v) {
        if (e == ScalarEncoding::kFloat16) return MaxAbs(v) * std::ldexp(1.0f, -11) + 1e-7f;
        const float levels = e == ScalarEncoding::kQuant16 ? 65535.0f : 255.0f;
        return Range(v) / levels * 0.5f * 1.0001f + MaxAbs(v) * 1.2e-7f;
      };
      testing::Tolerances t;
      t.positions = tol(g.positions);
      t.rotations = tol(g.rotations);
      t.log_scales = tol(g.log_scales);
      t.opacities = tol(g.opacity_logits);
      t.sh = tol(g.sh);
      t.texels = tol(asset.textures->texels);
      std::vector<float> grids;
      for (const auto& s : asset.deformation->planes) {
        for (const auto& p : s) grids.insert(grids.end(), p.begin(), p.end());
      }
      t.grids = tol(grids);
      EXPECT_TRUE(testing::AssetsNear(asset, back, t)) << ScalarEncodingName(e) << " " << CodecName(codec);
      // The MLP and stats are always f32.
      EXPECT_EQ(back.deformation->trunk[0].weight, asset.deformation->trunk[0].weight);
      EXPECT_EQ(back.stats->importance, asset.stats->importance);
    }
  }
}

TEST(RoundTrip, Float16IsRoundToNearestEven) {
  SyntheticAssetOptions o;
  o.gaussians = 50;
  o.sh_degree = 0;
  const Asset asset = MakeSyntheticAsset(o);
  WriteOptions w;
  w.sh_dc = ScalarEncoding::kFloat16;
  const Asset back = RoundTrip(asset, w);
  for (size_t i = 0; i < asset.gaussians.sh.size(); ++i) {
    bool overflow = false;
    const float expected = container::HalfToFloat(container::FloatToHalf(asset.gaussians.sh[i], &overflow));
    ASSERT_EQ(back.gaussians.sh[i], expected) << i;
  }
}

TEST(RoundTrip, Deterministic) {
  SyntheticAssetOptions o;
  o.gaussians = 400;
  const Asset asset = MakeSyntheticAsset(o);
  for (Codec codec : kLosslessCodecs) {
    WriteOptions w;
    w.codec = codec;
    w.texels = ScalarEncoding::kQuant8;
    auto a = EncodeAsset(asset, w);
    auto b = EncodeAsset(MakeSyntheticAsset(o), w);
    ASSERT_TRUE(a.ok() && b.ok());
    EXPECT_EQ(*a, *b) << CodecName(codec);
    // Re-encoding what was read gives the same bytes.
    auto back = DecodeAsset(a->data(), a->size());
    ASSERT_TRUE(back.ok());
    auto again = EncodeAsset(*back, w);
    ASSERT_TRUE(again.ok());
    EXPECT_EQ(*again, *a) << CodecName(codec);
  }
}

TEST(RoundTrip, DracoPositions) {
  SyntheticAssetOptions o;
  o.gaussians = 2000;
  o.sh_degree = 1;
  const Asset asset = MakeSyntheticAsset(o);
  WriteOptions w;
  w.draco_positions = true;
  w.draco_position_bits = 14;
  if (!HaveDracoCodec()) {
    EXPECT_EQ(EncodeAsset(asset, w).status().code(), StatusCode::kUnsupportedCodec);
    GTEST_SKIP() << "this build has no Draco";
  }
  std::vector<uint8_t> bytes;
  const Asset back = RoundTrip(asset, w, &bytes);
  auto info = InspectContainer(bytes.data(), bytes.size());
  ASSERT_TRUE(info.ok());
  EXPECT_EQ(info->chunks[2].type, "GPOS");
  EXPECT_EQ(info->chunks[2].codec, Codec::kDraco);
  EXPECT_LT(info->chunks[2].stored_size, 2000u * 12 / 2);
  testing::Tolerances t;
  t.positions = Range(asset.gaussians.positions) / float(1 << 14);  // one quantisation step of the cube
  EXPECT_TRUE(testing::AssetsNear(asset, back, t));
  // Order is preserved: the nearest decoded point to each original is itself.
  for (size_t i = 0; i < 2000; i += 97) {
    for (int a = 0; a < 3; ++a)
      ASSERT_NEAR(back.gaussians.positions[i * 3 + a], asset.gaussians.positions[i * 3 + a], t.positions);
  }
  // Deterministic, and valid with 0 and 1 Gaussians (0 falls back to a stream).
  auto again = EncodeAsset(asset, w);
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(*again, bytes);
  for (size_t n : {0, 1}) {
    o.gaussians = n;
    const Asset small = MakeSyntheticAsset(o);
    w.fallback_to_raw = false;
    const Asset small_back = RoundTrip(small, w);
    EXPECT_EQ(small_back.gaussians.size(), n);
  }
}

TEST(RoundTrip, WriteOptionsAreChecked) {
  const Asset asset = MakeSyntheticAsset({});
  WriteOptions w;
  w.zstd_level = 99;
  EXPECT_EQ(EncodeAsset(asset, w).status().code(), StatusCode::kInvalidArgument);
  w = {};
  w.codec = Codec::kDraco;
  EXPECT_EQ(EncodeAsset(asset, w).status().code(), StatusCode::kInvalidArgument);
  w = {};
  w.texels = static_cast<ScalarEncoding>(7);
  EXPECT_EQ(EncodeAsset(asset, w).status().code(), StatusCode::kInvalidArgument);
  if (HaveDracoCodec()) {
    w = {};
    w.draco_positions = true;
    w.draco_position_bits = 31;
    EXPECT_EQ(EncodeAsset(asset, w).status().code(), StatusCode::kInvalidArgument);
  }
}

TEST(RoundTrip, InvalidAssetsAreRefusedBeforeWriting) {
  Asset asset = MakeSyntheticAsset({});
  asset.gaussians.log_scales[10] = std::nanf("");
  auto bytes = EncodeAsset(asset, {});
  ASSERT_FALSE(bytes.ok());
  EXPECT_EQ(bytes.status().code(), StatusCode::kOutOfRange);
  EXPECT_NE(bytes.status().message().find("log_scales element 3"), std::string::npos) << bytes.status().message();
  asset = MakeSyntheticAsset({});
  asset.textures->texels[3] = 1e6f;  // fine as f32, too large for f16
  WriteOptions w;
  w.texels = ScalarEncoding::kFloat16;
  bytes = EncodeAsset(asset, w);
  ASSERT_FALSE(bytes.ok());
  EXPECT_EQ(bytes.status().code(), StatusCode::kOutOfRange);
  EXPECT_NE(bytes.status().message().find("texels row 0 component 3"), std::string::npos) << bytes.status().message();
}

// Time windows (GTWN, format 1.1): exact at every encoding of the other streams, the file says
// 1.1 only when it has them, and they need a deformation field and non-negative widths.
TEST(RoundTrip, TimeWindowsAreExactAndMakeTheFileVersion11) {
  Asset asset = MakeSyntheticAsset({});
  const size_t n = asset.gaussians.size();
  asset.gaussians.time_windows.resize(2 * n);
  for (size_t i = 0; i < n; ++i) {
    asset.gaussians.time_windows[2 * i] = 0.001f * float(i) + 1e-7f;  // f16 would round these
    asset.gaussians.time_windows[2 * i + 1] = i % 3 == 0 ? 0.0f : 57.99f;
  }
  WriteOptions lossy;
  lossy.positions = ScalarEncoding::kFloat16;
  lossy.opacities = ScalarEncoding::kQuant8;
  for (const WriteOptions& w : {WriteOptions{}, lossy}) {
    std::vector<uint8_t> bytes;
    const Asset back = RoundTrip(asset, w, &bytes);
    EXPECT_EQ(back.gaussians.time_windows, asset.gaussians.time_windows);
    auto info = InspectContainer(bytes.data(), bytes.size());
    ASSERT_TRUE(info.ok()) << info.status().ToString();
    EXPECT_EQ(info->version_minor, 1);
  }
  std::vector<uint8_t> plain;
  RoundTrip(MakeSyntheticAsset({}), {}, &plain);
  auto info = InspectContainer(plain.data(), plain.size());
  ASSERT_TRUE(info.ok());
  EXPECT_EQ(info->version_minor, 0);  // no GTWN: a 1.0 file, byte for byte as before

  Asset negative = asset;
  negative.gaussians.time_windows[3] = -1.0f;
  EXPECT_EQ(EncodeAsset(negative, {}).status().code(), StatusCode::kOutOfRange);
  Asset still = asset;
  still.deformation.reset();
  EXPECT_EQ(EncodeAsset(still, {}).status().code(), StatusCode::kInvalidArgument);
  Asset short_windows = asset;
  short_windows.gaussians.time_windows.pop_back();
  EXPECT_FALSE(EncodeAsset(short_windows, {}).ok());
}

TEST(RoundTrip, StatsCanBeLeftOut) {
  const Asset asset = MakeSyntheticAsset({});
  WriteOptions w;
  w.write_stats = false;
  const Asset no_stats = RoundTrip(asset, w);
  EXPECT_FALSE(no_stats.stats.has_value());
  auto bytes = EncodeAsset(asset, {});
  ASSERT_TRUE(bytes.ok());
  ReadOptions r;
  r.read_stats = false;
  auto back = DecodeAsset(bytes->data(), bytes->size(), r);
  ASSERT_TRUE(back.ok());
  EXPECT_FALSE(back->stats.has_value());
}

TEST(RoundTrip, FilesAreWrittenAtomicallyAndReadBack) {
  testing::TempDir dir;
  const Asset asset = MakeSyntheticAsset({});
  const std::string path = (dir / "a.atex").string();
  ASSERT_TRUE(WriteAssetFile(path, asset).ok());
  auto back = ReadAssetFile(path);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_TRUE(testing::AssetsEqual(asset, *back));
  auto missing = ReadAssetFile((dir / "missing.atex").string());
  EXPECT_EQ(missing.status().code(), StatusCode::kNotFound);
}

TEST(RoundTrip, DecodedSizeLimit) {
  const Asset asset = MakeSyntheticAsset({});
  auto bytes = EncodeAsset(asset, {});
  ASSERT_TRUE(bytes.ok());
  ReadOptions r;
  r.max_decoded_bytes = 1000;
  auto back = DecodeAsset(bytes->data(), bytes->size(), r);
  EXPECT_EQ(back.status().code(), StatusCode::kLimitExceeded);
}

// Issue 24: a 7.9 KB file declaring 1.3 GB decoded was read and called valid. Chunks that
// declare more than max_expansion_ratio x the file are refused before anything inflates;
// the default decode limit is never above the machine's RAM.
TEST(RoundTrip, DecompressionBombIsRefusedBeforeInflating) {
  Asset asset = MakeSyntheticAsset({});
  std::fill(asset.gaussians.sh.begin(), asset.gaussians.sh.end(), 0.0f);  // compresses far
  WriteOptions w;
  w.codec = Codec::kZstd;
  auto bytes = EncodeAsset(asset, w);
  ASSERT_TRUE(bytes.ok());
  ReadOptions r;
  EXPECT_TRUE(DecodeAsset(bytes->data(), bytes->size(), r).ok());  // below the 64 MiB floor
  r.expansion_check_floor = 0;
  r.max_expansion_ratio = 1;  // the raw sizes exceed the file's
  auto back = DecodeAsset(bytes->data(), bytes->size(), r);
  EXPECT_EQ(back.status().code(), StatusCode::kLimitExceeded);
  EXPECT_NE(back.status().message().find("times its size"), std::string::npos) << back.status().ToString();
  EXPECT_LE(ReadOptions{}.max_decoded_bytes, std::max<uint64_t>(PhysicalMemoryBytes() / 2, 1))
      << "the default decode limit exceeds half the machine's RAM";
}

}  // namespace
}  // namespace atex
