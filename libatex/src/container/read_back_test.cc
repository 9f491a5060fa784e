// DecodedAsWritten and EncodedAssetSize against the real thing: the asset a file decodes to,
// bit for bit, and the file's size, for every encoding of every stream.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "atex/container.h"
#include "container/asset_compare.h"
#include "container/attribute_stream.h"
#include "container/read_back.h"
#include "container/synthetic_asset.h"

namespace atex {
namespace {

using container::DecodedAsWritten;
using container::MakeSyntheticAsset;
using container::SyntheticAssetOptions;
using container::SyntheticTextures;

constexpr ScalarEncoding kEncodings[] = {ScalarEncoding::kFloat32, ScalarEncoding::kFloat16, ScalarEncoding::kQuant16,
                                         ScalarEncoding::kQuant8};

Asset Sample(uint64_t seed, size_t n, int degree, SyntheticTextures textures, bool deformation) {
  SyntheticAssetOptions o;
  o.seed = seed;
  o.gaussians = n;
  o.sh_degree = degree;
  o.textures = textures;
  o.deformation = deformation;
  o.stats = true;
  return MakeSyntheticAsset(o);
}

// Case c's encodings: every stream sees every encoding across four consecutive cases.
WriteOptions Mix(int c) {
  WriteOptions w;
  const auto pick = [&](int k) { return kEncodings[(c + k * (c / 4 + 1)) % 4]; };
  w.positions = pick(0);
  w.rotations = pick(1);
  w.log_scales = pick(2);
  w.opacities = pick(3);
  w.sh_dc = pick(4);
  w.sh_rest = pick(5);
  w.texels = pick(6);
  w.deformation_grids = pick(7);
  w.codec = c % 2 == 0 ? Codec::kDeltaShuffleZstd : Codec::kRaw;
  w.write_stats = c % 3 != 0;
  return w;
}

// Bit for bit: the two assets written with every stream f32 and no compression (the file
// holds every float's bits) must be the same bytes; AssetsEqual names a first difference.
void ExpectSameBits(const Asset& expected, const Asset& actual, const std::string& where) {
  EXPECT_TRUE(testing::AssetsEqual(expected, actual)) << where;
  WriteOptions exact;
  exact.codec = Codec::kRaw;
  const auto a = EncodeAsset(expected, exact), b = EncodeAsset(actual, exact);
  ASSERT_TRUE(a.ok() && b.ok()) << where;
  EXPECT_TRUE(*a == *b) << where << ": the same values but not the same bits (a -0 for a +0?)";
}

void ExpectReadBackIsTheDecode(const Asset& asset, const WriteOptions& w, const std::string& where) {
  const auto file = EncodeAsset(asset, w);
  ASSERT_TRUE(file.ok()) << where << file.status().ToString();
  const auto size = EncodedAssetSize(asset, w);
  ASSERT_TRUE(size.ok()) << where;
  EXPECT_EQ(*size, file->size()) << where;
  for (const bool stats : {false, true}) {
    ReadOptions read;
    read.read_stats = stats;
    const auto decoded = DecodeAsset(file->data(), file->size(), read);
    ASSERT_TRUE(decoded.ok()) << where << decoded.status().ToString();
    const auto read_back = DecodedAsWritten(asset, w, stats);
    ASSERT_TRUE(read_back.ok()) << where << read_back.status().ToString();
    ExpectSameBits(*decoded, *read_back, where + (stats ? " with stats" : ""));
  }
}

TEST(ReadBack, EqualsTheDecodeForEveryEncodingOfEveryStream) {
  int c = 0;
  for (const int degree : {0, 1, 3}) {
    for (const auto textures : {SyntheticTextures::kNone, SyntheticTextures::kMixed, SyntheticTextures::kUniform}) {
      const Asset asset = Sample(11 + c, 700, degree, textures, degree != 1);
      for (int k = 0; k < 8; ++k, ++c) {
        ExpectReadBackIsTheDecode(asset, Mix(c), "case " + std::to_string(c));
      }
    }
  }
}

// Large enough for the threaded paths (several row blocks, the level tables), with ties the
// ranges must resolve as one pass in order does: -0 and +0 at the extremes, constant
// components (hi = lo), and a component that spans only two values.
TEST(ReadBack, LargeStreamsWithTiesEqualTheDecode) {
  Asset asset = Sample(5, 40000, 3, SyntheticTextures::kUniform, true);
  Gaussians& g = asset.gaussians;
  std::mt19937 rng(3);
  for (size_t i = 0; i < g.size(); ++i) {
    g.positions[i * 3 + 0] = (rng() % 2) ? 0.0f : -0.0f;  // only zeros of both signs
    g.positions[i * 3 + 1] = 1.5f;                        // constant
    g.opacity_logits[i] = (i % 7 == 0) ? -0.0f : g.opacity_logits[i];
  }
  g.positions[5 * 3 + 2] = -0.0f;
  auto& texels = asset.textures->texels;
  for (size_t i = 0; i < texels.size(); i += 4) texels[i] = (i % 8 == 0) ? 0.25f : -0.25f;  // two values
  for (int k = 0; k < 4; ++k) {
    WriteOptions w;
    w.positions = w.rotations = w.log_scales = w.opacities = w.sh_dc = w.sh_rest = w.texels = w.deformation_grids =
        kEncodings[k];
    ExpectReadBackIsTheDecode(asset, w, "all " + std::to_string(k));
  }
}

// Both refuse `asset` under `w` with the same message (an f16 overflow).
void ExpectTheEncodersOverflowError(const Asset& asset, const WriteOptions& w) {
  const auto encoded = EncodeAsset(asset, w);
  const auto read_back = DecodedAsWritten(asset, w, false);
  ASSERT_FALSE(encoded.ok());
  ASSERT_FALSE(read_back.ok());
  EXPECT_EQ(read_back.status().code(), StatusCode::kOutOfRange);
  EXPECT_EQ(read_back.status().message(), encoded.status().message());
  EXPECT_EQ(EncodedAssetSize(asset, w).status().code(), encoded.status().code());
}

TEST(ReadBack, AFloat16OverflowIsTheEncodersError) {
  Asset asset = Sample(2, 50, 1, SyntheticTextures::kNone, false);
  asset.gaussians.log_scales[7] = 70000.0f;
  WriteOptions w;
  w.log_scales = ScalarEncoding::kFloat16;
  ExpectTheEncodersOverflowError(asset, w);
  // SH is read back in place: the message still names the value, not its overwritten f16.
  Asset sh = Sample(3, 50, 2, SyntheticTextures::kNone, false);
  sh.gaussians.sh[9 * 27 + 5] = -80000.0f;  // Gaussian 9, a rest coefficient
  WriteOptions rest;
  rest.sh_rest = ScalarEncoding::kFloat16;
  ExpectTheEncodersOverflowError(sh, rest);
}

TEST(ReadBack, RefusesWhatEncodeAssetRefuses) {
  Asset asset = Sample(2, 50, 1, SyntheticTextures::kMixed, true);
  asset.gaussians.rotations.pop_back();
  EXPECT_EQ(DecodedAsWritten(asset, {}, false).status().code(), EncodeAsset(asset).status().code());
  EXPECT_EQ(EncodedAssetSize(asset, {}).status().code(), EncodeAsset(asset).status().code());
  const Asset valid = Sample(2, 50, 1, SyntheticTextures::kMixed, true);
  WriteOptions bad;
  bad.zstd_level = 1000;
  EXPECT_EQ(DecodedAsWritten(valid, bad, false).status().code(), StatusCode::kInvalidArgument);
  WriteOptions draco;
  draco.draco_positions = true;
  const StatusCode expected = HaveDracoCodec() ? StatusCode::kUnsupported : StatusCode::kUnsupportedCodec;
  EXPECT_EQ(DecodedAsWritten(valid, draco, false).status().code(), expected);
}

// Through a cache, across assets that change one stream at a time and encodings that change:
// the same bits as the decode, and the unchanged streams come from the cache.
TEST(ReadBack, ACacheGivesTheSameBitsAndHitsUnchangedStreams) {
  container::ReadBackCache cache(2);
  Asset asset = Sample(9, 3000, 3, SyntheticTextures::kMixed, true);
  for (int c = 0; c < 12; ++c) {
    const WriteOptions w = Mix(c % 5);
    if (c % 3 == 1) asset.gaussians.sh[c] += 0.5f;
    if (c % 3 == 2) asset.textures->texels[c] -= 0.25f;
    const auto file = EncodeAsset(asset, w);
    ASSERT_TRUE(file.ok());
    ReadOptions read;
    read.read_stats = false;
    const auto decoded = DecodeAsset(file->data(), file->size(), read);
    const auto cached = DecodedAsWritten(asset, w, false, &cache);
    ASSERT_TRUE(decoded.ok() && cached.ok());
    ExpectSameBits(*decoded, *cached, "case " + std::to_string(c));
    const uint64_t misses = cache.misses();
    const auto again = DecodedAsWritten(asset, w, false, &cache);  // nothing changed: no misses
    ASSERT_TRUE(again.ok());
    ExpectSameBits(*decoded, *again, "again " + std::to_string(c));
    EXPECT_EQ(cache.misses(), misses) << "case " << c;
  }
  EXPECT_GT(cache.hits(), 12u);
}

// StreamRange on several threads finds what one pass in row order finds, bit for bit.
TEST(ReadBack, StreamRangeIsTheFirstExtremeInRowOrder) {
  const uint64_t rows = 300000;
  std::vector<float> values(rows * 2);
  for (uint64_t r = 0; r < rows; ++r) {
    values[r * 2] = (r % 3 == 0) ? -0.0f : 0.0f;  // min and max are zeros of either sign
    values[r * 2 + 1] = static_cast<float>(r % 1000) - 500.0f;
  }
  float lo[2], hi[2];
  container::StreamRange(values.data(), 2, rows, 2, lo, hi);
  EXPECT_TRUE(std::signbit(lo[0]));  // row 0 holds -0: the first minimum and maximum
  EXPECT_TRUE(std::signbit(hi[0]));
  EXPECT_EQ(lo[1], -500.0f);
  EXPECT_EQ(hi[1], 499.0f);
  values[0] = 0.0f;  // row 0 now holds +0
  container::StreamRange(values.data(), 2, rows, 2, lo, hi);
  EXPECT_FALSE(std::signbit(lo[0]));
  EXPECT_FALSE(std::signbit(hi[0]));
}

}  // namespace
}  // namespace atex
