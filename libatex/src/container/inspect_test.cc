#include <gtest/gtest.h>

#include "atex/container.h"
#include "container/synthetic_asset.h"

namespace atex {
namespace {

TEST(Inspect, ChunkTableAndExactSizeAccounting) {
  container::SyntheticAssetOptions o;
  o.gaussians = 777;
  o.sh_degree = 3;
  const Asset asset = container::MakeSyntheticAsset(o);
  for (Codec codec : {Codec::kRaw, Codec::kShuffleZstd}) {
    WriteOptions w;
    w.codec = codec;
    auto bytes = EncodeAsset(asset, w);
    ASSERT_TRUE(bytes.ok());
    auto info = InspectContainer(bytes->data(), bytes->size());
    ASSERT_TRUE(info.ok()) << info.status().ToString();
    EXPECT_EQ(info->file_size, bytes->size());
    const std::vector<std::string> expected = {"META", "GHDR", "GPOS", "GROT", "GSCL", "GOPA", "GSH0",
                                               "GSHR", "TLAY", "TEXL", "DCFG", "DGRD", "DMLP", "GSTA"};
    ASSERT_EQ(info->chunks.size(), expected.size());
    for (size_t i = 0; i < expected.size(); ++i) {
      EXPECT_EQ(info->chunks[i].type, expected[i]);
      EXPECT_TRUE(info->chunks[i].known);
      EXPECT_EQ(info->chunks[i].critical(), expected[i] != "GSTA");
      EXPECT_EQ(info->chunks[i].offset % 8, 0u);
    }
    // Raw sizes from the spec: GPOS = 16 + 777 * 3 * 4; GSHR = 16 + 777 * 45 * 4; TLAY = 777.
    EXPECT_EQ(info->chunks[2].raw_size, 16u + 777u * 12u);
    EXPECT_EQ(info->chunks[7].raw_size, 16u + 777u * 45u * 4u);
    EXPECT_EQ(info->chunks[8].raw_size, 777u);
    EXPECT_EQ(info->chunks[9].raw_size, 16u + asset.textures->texel_count() * 16u);
    uint64_t total = 0;
    for (const ComponentSize& c : ComponentBytes(*info)) total += c.bytes;
    EXPECT_EQ(total, bytes->size());
    const auto groups = ComponentBytes(*info);
    EXPECT_EQ(groups.front().component, "header");
    EXPECT_EQ(groups.front().bytes, 32u);
    // The positions group is exactly GPOS's TOC entry plus its padded bytes.
    for (const ComponentSize& c : groups) {
      if (c.component == "positions") {
        EXPECT_EQ(c.bytes, 48u + ((info->chunks[2].stored_size + 7) / 8) * 8);
      }
    }
  }
}

TEST(Inspect, RefusesDamagedHeaders) {
  auto bytes = EncodeAsset(container::MakeSyntheticAsset({}), {});
  ASSERT_TRUE(bytes.ok());
  (*bytes)[40] ^= 1;  // inside the TOC
  EXPECT_EQ(InspectContainer(bytes->data(), bytes->size()).status().code(), StatusCode::kChecksumMismatch);
  EXPECT_EQ(InspectContainer(bytes->data(), 31).status().code(), StatusCode::kTruncated);
}

// DecodeMetadata reads META alone: the metadata DecodeAsset gives, also when another chunk's
// bytes are damaged; a damaged META, TOC or a truncated file is still refused.
TEST(Inspect, MetadataAloneSkipsTheOtherChunks) {
  container::SyntheticAssetOptions o;
  o.gaussians = 300;
  Asset asset = container::MakeSyntheticAsset(o);
  asset.metadata.background = {0.25f, 0.5f, 1.0f};
  asset.metadata.texture_mode = "adaptive";
  auto bytes = EncodeAsset(asset, {});
  ASSERT_TRUE(bytes.ok());
  auto whole = DecodeAsset(bytes->data(), bytes->size());
  ASSERT_TRUE(whole.ok()) << whole.status().ToString();
  auto meta = DecodeMetadata(bytes->data(), bytes->size());
  ASSERT_TRUE(meta.ok()) << meta.status().ToString();
  EXPECT_EQ(meta->background, whole->metadata.background);
  EXPECT_EQ(meta->texture_mode, "adaptive");
  EXPECT_EQ(meta->bounds_min, whole->metadata.bounds_min);
  EXPECT_EQ(meta->bounds_max, whole->metadata.bounds_max);
  EXPECT_EQ(meta->extra, whole->metadata.extra);

  auto info = InspectContainer(bytes->data(), bytes->size());
  ASSERT_TRUE(info.ok());
  const auto chunk = [&](const std::string& type) {
    for (const ChunkInfo& c : info->chunks)
      if (c.type == type) return c;
    ADD_FAILURE() << type << " missing";
    return ChunkInfo{};
  };
  std::vector<uint8_t> damaged = *bytes;
  damaged[chunk("GPOS").offset + 3] ^= 0x40;  // a stream's stored bytes
  EXPECT_EQ(DecodeAsset(damaged.data(), damaged.size()).status().code(), StatusCode::kChecksumMismatch);
  auto still = DecodeMetadata(damaged.data(), damaged.size());
  ASSERT_TRUE(still.ok()) << still.status().ToString();
  EXPECT_EQ(still->background, asset.metadata.background);

  damaged = *bytes;
  damaged[chunk("META").offset + 1] ^= 0x40;
  const Status bad_meta = DecodeMetadata(damaged.data(), damaged.size()).status();
  EXPECT_EQ(bad_meta.code(), StatusCode::kChecksumMismatch);
  EXPECT_NE(bad_meta.message().find("META"), std::string::npos) << bad_meta.ToString();
  EXPECT_EQ(DecodeMetadata(bytes->data(), 31).status().code(), StatusCode::kTruncated);
  EXPECT_EQ(DecodeMetadata(nullptr, 10).status().code(), StatusCode::kInvalidArgument);
}

TEST(Inspect, Names) {
  EXPECT_EQ(CodecName(Codec::kDeltaShuffleZstd), "delta-shuffle-zstd");
  EXPECT_EQ(CodecName(static_cast<Codec>(9)), "codec-9");
  EXPECT_EQ(ScalarEncodingName(ScalarEncoding::kQuant16), "q16");
}

TEST(Inspect, TextureHistogram) {
  TexturePool t;
  t.heights = {1, 1, 4, 2, 4};
  t.widths = {1, 1, 4, 4, 1};
  t.axis_u = {0, 0, 0, 0, 0};
  t.axis_v = {1, 1, 1, 1, 1};
  t.RebuildOffsets();
  const TextureHistogram h = ComputeTextureHistogram(t);
  EXPECT_EQ(h.counts[0][0], 2u);
  EXPECT_EQ(h.counts[2][2], 1u);
  EXPECT_EQ(h.counts[1][2], 1u);
  EXPECT_EQ(h.counts[2][0], 1u);
  EXPECT_EQ(h.texels, 1u + 1 + 16 + 8 + 4);
  EXPECT_EQ(h.uniform_texels(), 80u);
  EXPECT_EQ(h.texel_bytes(4), 30u * 16);
  EXPECT_EQ(h.uniform_texel_bytes(1), 80u * 4);
}

}  // namespace
}  // namespace atex
