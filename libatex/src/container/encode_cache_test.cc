// EncodeCache and DecodeCache: cached encodes are byte-identical to uncached ones, cached
// decodes equal uncached ones, and hits happen only for unchanged content.
#include <gtest/gtest.h>

#include "atex/container.h"
#include "container/synthetic_asset.h"

namespace atex {
namespace {

using container::MakeSyntheticAsset;
using container::SyntheticAssetOptions;
using container::SyntheticTextures;

Asset Sample(uint64_t seed, size_t n, int degree, SyntheticTextures textures) {
  SyntheticAssetOptions o;
  o.seed = seed;
  o.gaussians = n;
  o.sh_degree = degree;
  o.textures = textures;
  o.deformation = true;
  o.stats = true;
  return MakeSyntheticAsset(o);
}

constexpr ScalarEncoding kEncodings[] = {ScalarEncoding::kFloat32, ScalarEncoding::kFloat16, ScalarEncoding::kQuant16,
                                         ScalarEncoding::kQuant8};

// A deterministic mix of encodings for case `c`.
WriteOptions Mix(int c) {
  WriteOptions w;
  const auto pick = [&](int k) { return kEncodings[(c / (k + 1) + k) % 4]; };
  w.positions = pick(0);
  w.rotations = pick(1);
  w.log_scales = pick(2);
  w.opacities = pick(3);
  w.sh_dc = pick(4);
  w.sh_rest = pick(5);
  w.texels = pick(6);
  w.deformation_grids = pick(7);
  w.codec = c % 3 == 0 ? Codec::kDeltaShuffleZstd : c % 3 == 1 ? Codec::kShuffleZstd : Codec::kRaw;
  w.write_stats = c % 2 == 0;
  return w;
}

TEST(EncodeCache, CachedBytesEqualUncachedAcrossChangingAssets) {
  EncodeCache cache(2);
  Asset asset = Sample(3, 500, 3, SyntheticTextures::kMixed);
  int cases_with_hits = 0;
  for (int c = 0; c < 24; ++c) {
    const WriteOptions w = Mix(c % 6);
    if (c % 4 == 3) asset.gaussians.positions[c] += 0.25f;  // one stream changes, the rest may hit
    const auto plain = EncodeAsset(asset, w);
    const uint64_t hits_before = cache.hits();
    const auto cached = EncodeAsset(asset, w, &cache);
    ASSERT_TRUE(plain.ok() && cached.ok()) << plain.status().ToString() << cached.status().ToString();
    ASSERT_EQ(*plain, *cached) << "case " << c;
    // The same encode again: every chunk is a hit.
    const uint64_t misses_before = cache.misses();
    const auto again = EncodeAsset(asset, w, &cache);
    ASSERT_TRUE(again.ok());
    ASSERT_EQ(*plain, *again);
    EXPECT_EQ(cache.misses(), misses_before) << "case " << c;
    cases_with_hits += cache.hits() > hits_before ? 1 : 0;
  }
  EXPECT_GT(cases_with_hits, 0);
}

TEST(EncodeCache, ChangedContentIsAMissNotAStaleHit) {
  EncodeCache cache;
  Asset asset = Sample(5, 200, 1, SyntheticTextures::kUniform);
  const WriteOptions w = Mix(0);
  ASSERT_TRUE(EncodeAsset(asset, w, &cache).ok());
  const uint64_t misses = cache.misses();
  asset.textures->texels.back() += 1e-3f;  // the last byte of one chunk's content
  const auto cached = EncodeAsset(asset, w, &cache);
  const auto plain = EncodeAsset(asset, w);
  ASSERT_TRUE(cached.ok() && plain.ok());
  EXPECT_EQ(*cached, *plain);
  EXPECT_EQ(cache.misses(), misses + 1);  // TEXL only
  // A different zstd level or codec is a different chunk too.
  WriteOptions w9 = w;
  w9.zstd_level = 9;
  const auto level9 = EncodeAsset(asset, w9, &cache);
  const auto plain9 = EncodeAsset(asset, w9);
  ASSERT_TRUE(level9.ok() && plain9.ok());
  EXPECT_EQ(*level9, *plain9);
  WriteOptions raw = w;
  raw.codec = Codec::kRaw;
  const auto cached_raw = EncodeAsset(asset, raw, &cache);
  const auto plain_raw = EncodeAsset(asset, raw);
  ASSERT_TRUE(cached_raw.ok() && plain_raw.ok());
  EXPECT_EQ(*cached_raw, *plain_raw);
}

// The streams keyed without being built (SH split into DC and rest, the flattened grids):
// a change to one value of each is a miss of the chunks made from it, and the bytes stay
// those of an uncached encode.
TEST(EncodeCache, StreamsBuiltOnAMissAreKeyedByWhatTheyAreMadeOf) {
  EncodeCache cache;
  Asset asset = Sample(8, 300, 2, SyntheticTextures::kMixed);
  const WriteOptions w = Mix(3);
  ASSERT_TRUE(EncodeAsset(asset, w, &cache).ok());
  const auto changed_once = [&](int expected_misses) {
    const uint64_t misses = cache.misses();
    const auto cached = EncodeAsset(asset, w, &cache);
    const auto plain = EncodeAsset(asset, w);
    ASSERT_TRUE(cached.ok() && plain.ok());
    EXPECT_EQ(*cached, *plain);
    EXPECT_EQ(cache.misses(), misses + expected_misses);
  };
  asset.gaussians.sh[5] += 0.125f;  // an SH rest coefficient: GSH0 and GSHR are keyed by the whole array
  changed_once(2);
  asset.gaussians.sh[0] += 0.125f;  // a DC coefficient
  changed_once(2);
  ASSERT_TRUE(asset.deformation.has_value());
  asset.deformation->planes.back().back().back() += 0.25f;  // the last value of the last grid
  changed_once(1);
  changed_once(0);  // nothing changed: every chunk a hit
}

// Every value of two decoded assets, compared exactly (bit patterns: -0 and NaN-free inputs).
void ExpectSameValues(const Asset& a, const Asset& b, int c) {
  EXPECT_EQ(a.gaussians.positions, b.gaussians.positions) << c;
  EXPECT_EQ(a.gaussians.rotations, b.gaussians.rotations) << c;
  EXPECT_EQ(a.gaussians.log_scales, b.gaussians.log_scales) << c;
  EXPECT_EQ(a.gaussians.opacity_logits, b.gaussians.opacity_logits) << c;
  EXPECT_EQ(a.gaussians.sh, b.gaussians.sh) << c;
  ASSERT_EQ(a.textures.has_value(), b.textures.has_value()) << c;
  if (a.textures) {
    EXPECT_EQ(a.textures->texels, b.textures->texels) << c;
  }
  ASSERT_EQ(a.deformation.has_value(), b.deformation.has_value()) << c;
  if (a.deformation) {
    EXPECT_EQ(a.deformation->planes, b.deformation->planes) << c;
    EXPECT_EQ(EncodeAsset(a).value(), EncodeAsset(b).value()) << c;  // the MLP and the rest
  }
  ASSERT_EQ(a.stats.has_value(), b.stats.has_value()) << c;
  if (a.stats) {
    EXPECT_EQ(a.stats->importance, b.stats->importance) << c;
  }
}

TEST(DecodeCache, CachedDecodesEqualUncachedAcrossChangingFiles) {
  DecodeCache cache(2);
  Asset asset = Sample(3, 500, 3, SyntheticTextures::kMixed);
  int cases_with_hits = 0;
  for (int c = 0; c < 24; ++c) {
    const WriteOptions w = Mix(c % 6);
    if (c % 4 == 3) asset.gaussians.positions[c] += 0.25f;  // one stream changes, the rest may hit
    const auto bytes = EncodeAsset(asset, w);
    ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
    const auto plain = DecodeAsset(bytes->data(), bytes->size());
    const uint64_t hits_before = cache.hits();
    const auto cached = DecodeAsset(bytes->data(), bytes->size(), {}, &cache);
    ASSERT_TRUE(plain.ok() && cached.ok()) << plain.status().ToString() << cached.status().ToString();
    ExpectSameValues(*plain, *cached, c);
    // The same file again: every stream is a hit.
    const uint64_t misses_before = cache.misses();
    const auto again = DecodeAsset(bytes->data(), bytes->size(), {}, &cache);
    ASSERT_TRUE(again.ok());
    ExpectSameValues(*plain, *again, c);
    EXPECT_EQ(cache.misses(), misses_before) << "case " << c;
    cases_with_hits += cache.hits() > hits_before ? 1 : 0;
  }
  EXPECT_GT(cases_with_hits, 0);
}

TEST(DecodeCache, AChangedChunkIsDecodedAndACorruptOneStillRefused) {
  DecodeCache cache;
  Asset asset = Sample(5, 200, 1, SyntheticTextures::kUniform);
  WriteOptions w = Mix(0);
  w.texels = ScalarEncoding::kQuant8;
  const auto first = EncodeAsset(asset, w);
  ASSERT_TRUE(first.ok());
  ASSERT_TRUE(DecodeAsset(first->data(), first->size(), {}, &cache).ok());
  const uint64_t misses = cache.misses();
  asset.textures->texels.back() += 0.5f;  // one texel: TEXL's stored bytes change
  const auto second = EncodeAsset(asset, w);
  ASSERT_TRUE(second.ok());
  const auto cached = DecodeAsset(second->data(), second->size(), {}, &cache);
  const auto plain = DecodeAsset(second->data(), second->size());
  ASSERT_TRUE(cached.ok() && plain.ok());
  ExpectSameValues(*plain, *cached, 0);
  EXPECT_EQ(cache.misses(), misses + 1);  // TEXL only
  // A file whose cached chunk is damaged after its header: the CRC check still refuses it.
  std::vector<uint8_t> damaged = *second;
  damaged[damaged.size() / 2] ^= 0x40;
  const auto refused = DecodeAsset(damaged.data(), damaged.size(), {}, &cache);
  EXPECT_FALSE(refused.ok());
}

}  // namespace
}  // namespace atex
