// Frozen bytes: an accidental change of the format (or of the writer's
// determinism) fails here. The files were produced by atex_write_golden from
// golden_assets.cc; regenerate them only for an intended format change.
#include <gtest/gtest.h>
#include <zstd.h>

#include <cctype>
#include <fstream>
#include <sstream>

#include "atex/checksum.h"
#include "atex/container.h"
#include "atex/file_io.h"
#include "container/asset_compare.h"
#include "container/byte_io.h"
#include "core/test_support.h"
#include "golden_assets.h"

namespace atex {
namespace {

// The zstd release the zstd-coded golden bytes were produced with; another
// release may compress differently (the decoded content must still match).
constexpr unsigned kGoldenZstdVersion = 10504;  // 1.5.4

std::vector<uint8_t> ReadSourceFile(const std::string& relative) {
  auto bytes = ReadFileBytes((testing::SourceDir() / relative).string());
  EXPECT_TRUE(bytes.ok()) << bytes.status().ToString() << " (run atex_write_golden to create it)";
  return bytes.ok() ? *bytes : std::vector<uint8_t>{};
}

std::vector<uint8_t> Encode(const Asset& asset, const WriteOptions& options) {
  auto bytes = EncodeAsset(asset, options);
  EXPECT_TRUE(bytes.ok()) << bytes.status().ToString();
  return bytes.ok() ? *bytes : std::vector<uint8_t>{};
}

TEST(Golden, RawFileMatchesGeneratorAndRewrite) {
  const auto frozen = ReadSourceFile(golden::kGoldenRawFile);
  ASSERT_FALSE(frozen.empty());
  const WriteOptions options = golden::GoldenOptions(Codec::kRaw);
  EXPECT_EQ(Encode(golden::GoldenAsset(), options), frozen) << "the generator no longer produces the frozen bytes";
  auto asset = DecodeAsset(frozen.data(), frozen.size());
  ASSERT_TRUE(asset.ok()) << asset.status().ToString();
  EXPECT_EQ(Encode(*asset, options), frozen) << "read + write with the same options changed the bytes";
}

TEST(Golden, ZstdFileMatchesGeneratorAndRewrite) {
  const auto frozen = ReadSourceFile(golden::kGoldenZstdFile);
  ASSERT_FALSE(frozen.empty());
  auto asset = DecodeAsset(frozen.data(), frozen.size());
  ASSERT_TRUE(asset.ok()) << asset.status().ToString();
  // The content is pinned whatever the zstd release: it equals the raw golden's.
  const auto raw = ReadSourceFile(golden::kGoldenRawFile);
  auto raw_asset = DecodeAsset(raw.data(), raw.size());
  ASSERT_TRUE(raw_asset.ok());
  EXPECT_TRUE(testing::AssetsEqual(*raw_asset, *asset));
  // Every codec of §5 but Draco appears.
  auto info = InspectContainer(frozen.data(), frozen.size());
  ASSERT_TRUE(info.ok());
  std::set<Codec> codecs;
  for (const ChunkInfo& c : info->chunks) codecs.insert(c.codec);
  EXPECT_EQ(codecs, (std::set<Codec>{Codec::kZstd, Codec::kShuffleZstd, Codec::kDeltaShuffleZstd}));
  if (ZSTD_versionNumber() != kGoldenZstdVersion) {
    GTEST_SKIP() << "zstd " << ZSTD_versionString() << " differs from the golden's 1.5.4: bytes not compared";
  }
  const WriteOptions options = golden::GoldenOptions(Codec::kDeltaShuffleZstd);
  EXPECT_EQ(Encode(golden::GoldenAsset(), options), frozen);
  EXPECT_EQ(Encode(*asset, options), frozen);
}

TEST(Golden, DecodedValuesAreTheGeneratorsWithinEncodingPrecision) {
  const auto frozen = ReadSourceFile(golden::kGoldenRawFile);
  auto asset = DecodeAsset(frozen.data(), frozen.size());
  ASSERT_TRUE(asset.ok());
  const Asset original = golden::GoldenAsset();
  testing::Tolerances t;
  t.rotations = 4.0f / 2048;  // f16 of values below 4
  t.log_scales = 0.001f;      // q16
  t.opacities = 0.05f;        // q8 of a range of about 12
  t.sh = 0.01f;
  t.texels = 0.01f;
  t.grids = 0.0001f;
  EXPECT_TRUE(testing::AssetsNear(original, *asset, t));
  EXPECT_EQ(asset->gaussians.positions, original.gaussians.positions);  // f32: exact
  EXPECT_EQ(asset->metadata.extra, original.metadata.extra);
}

// A second, independent writer for the §12 example, following only the tables of
// the spec (header §3, TOC §4, stream header §6, GHDR §7.2, META §7.1).
std::vector<uint8_t> SpecExampleByHand() {
  using container::StoreLE;
  const std::string meta =
      "{\"axes\":\"opencv\",\"background\":[0.0,0.0,0.0],\"bounds_max\":[0.0,0.0,0.0],"
      "\"bounds_min\":[0.0,0.0,0.0],\"extra\":{},\"texture_mode\":\"none\",\"time_max\":1.0,"
      "\"time_min\":0.0,\"units\":\"unknown\"}";
  auto stream = [](uint16_t components, std::vector<float> values) {
    std::vector<uint8_t> s(16 + values.size() * 4, 0);
    StoreLE<uint16_t>(s.data() + 2, components);
    StoreLE<uint64_t>(s.data() + 8, 1);
    for (size_t i = 0; i < values.size(); ++i) StoreLE<float>(s.data() + 16 + 4 * i, values[i]);
    return s;
  };
  std::vector<uint8_t> ghdr(16, 0);
  ghdr[0] = 1;
  const std::vector<std::pair<std::string, std::vector<uint8_t>>> chunks = {
      {"META", std::vector<uint8_t>(meta.begin(), meta.end())},
      {"GHDR", ghdr},
      {"GPOS", stream(3, {1, 2, 3})},
      {"GROT", stream(4, {1, 0, 0, 0})},
      {"GSCL", stream(3, {-1, -2, -3})},
      {"GOPA", stream(1, {0.5f})},
      {"GSH0", stream(3, {0.25f, -0.5f, 1})},
  };
  const size_t toc_end = 32 + 48 * chunks.size();
  size_t size = toc_end;
  for (const auto& c : chunks) size = (size + c.second.size() + 7) / 8 * 8;
  std::vector<uint8_t> f(size, 0);
  const uint8_t magic[8] = {0x89, 'A', 'T', 'E', 'X', 0x0D, 0x0A, 0x1A};
  std::copy(magic, magic + 8, f.begin());
  StoreLE<uint16_t>(f.data() + 8, 1);
  StoreLE<uint64_t>(f.data() + 16, size);
  StoreLE<uint32_t>(f.data() + 24, static_cast<uint32_t>(chunks.size()));
  size_t offset = toc_end;
  for (size_t i = 0; i < chunks.size(); ++i) {
    uint8_t* e = f.data() + 32 + 48 * i;
    std::copy(chunks[i].first.begin(), chunks[i].first.end(), e);
    StoreLE<uint16_t>(e + 4, 1);  // critical
    StoreLE<uint64_t>(e + 8, offset);
    StoreLE<uint64_t>(e + 16, chunks[i].second.size());
    StoreLE<uint64_t>(e + 24, chunks[i].second.size());
    StoreLE<uint32_t>(e + 32, Crc32c(chunks[i].second.data(), chunks[i].second.size()));
    std::copy(chunks[i].second.begin(), chunks[i].second.end(), f.begin() + offset);
    offset = (offset + chunks[i].second.size() + 7) / 8 * 8;
  }
  StoreLE<uint32_t>(f.data() + 28, Crc32c(f.data(), toc_end));
  return f;
}

// The hex dump in format_spec/atex.md §12: "0x0000  89 41 ...  |.ATEX...|".
std::vector<uint8_t> SpecExampleFromSpec() {
  std::ifstream in(testing::SourceDir() / "format_spec/atex.md");
  std::string line;
  bool in_section = false, in_block = false;
  std::vector<uint8_t> bytes;
  while (std::getline(in, line)) {
    if (line.rfind("## 12.", 0) == 0) in_section = true;
    else if (line.rfind("## ", 0) == 0) in_section = false;
    if (!in_section) continue;
    if (line.rfind("```", 0) == 0) {
      if (in_block) break;
      in_block = true;
      continue;
    }
    if (!in_block || line.rfind("0x", 0) != 0) continue;
    std::istringstream tokens(line.substr(0, line.find('|')));
    std::string token;
    tokens >> token;  // offset
    if (std::stoul(token, nullptr, 16) != bytes.size()) return {};  // offsets must be contiguous
    while (tokens >> token) {
      if (token.size() != 2 || !std::isxdigit(token[0]) || !std::isxdigit(token[1])) return {};
      bytes.push_back(static_cast<uint8_t>(std::stoul(token, nullptr, 16)));
    }
  }
  return bytes;
}

TEST(Golden, SpecExampleBytes) {
  const auto written = Encode(golden::SpecExampleAsset(), golden::SpecExampleOptions());
  EXPECT_EQ(written, SpecExampleByHand()) << "EncodeAsset disagrees with the spec's tables";
  EXPECT_EQ(written, SpecExampleFromSpec()) << "EncodeAsset disagrees with the hex dump of format_spec/atex.md §12";
  auto back = DecodeAsset(written.data(), written.size());
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_TRUE(testing::AssetsEqual(golden::SpecExampleAsset(), *back));
}

TEST(Golden, SampleAssetIsReadable) {
  const auto bytes = ReadSourceFile(golden::kSampleFile);
  ASSERT_FALSE(bytes.empty());
  EXPECT_LE(bytes.size(), size_t{400} << 10) << "the sample should stay a few hundred KB at most";
  auto asset = DecodeAsset(bytes.data(), bytes.size());
  ASSERT_TRUE(asset.ok()) << asset.status().ToString();
  EXPECT_TRUE(asset->textures.has_value());
  EXPECT_TRUE(asset->deformation.has_value());
}

}  // namespace
}  // namespace atex
