// Hostile input: every truncation of the golden files and thousands of random
// bit flips and overwrites give a clean error, never a crash (run under ASan and
// UBSan by tests/sanitize.sh).
#include <gtest/gtest.h>

#include <random>

#include "atex/container.h"
#include "atex/file_io.h"
#include "core/test_support.h"
#include "golden_assets.h"

namespace atex {
namespace {

std::vector<uint8_t> Load(const char* relative) {
  auto bytes = ReadFileBytes((testing::SourceDir() / relative).string());
  EXPECT_TRUE(bytes.ok()) << bytes.status().ToString();
  return bytes.ok() ? *bytes : std::vector<uint8_t>{};
}

std::vector<std::vector<uint8_t>> Files() {
  std::vector<std::vector<uint8_t>> files = {Load(golden::kGoldenRawFile), Load(golden::kGoldenZstdFile)};
  for (auto& [name, bytes] : golden::FuzzSeeds()) {
    if (name.find("draco") != std::string::npos) files.push_back(bytes);
  }
  return files;
}

ReadOptions NoChecksums() {
  ReadOptions r;
  r.verify_checksums = false;
  return r;
}

TEST(HostileInput, EveryTruncationIsReportedAsTruncated) {
  for (const auto& file : Files()) {
    ASSERT_FALSE(file.empty());
    ASSERT_TRUE(DecodeAsset(file.data(), file.size()).ok());
    for (size_t cut = 0; cut < file.size(); ++cut) {
      // A copy of exactly `cut` bytes, so that ASan sees any read past the end.
      const std::vector<uint8_t> part(file.begin(), file.begin() + cut);
      for (const ReadOptions& options : {ReadOptions{}, NoChecksums()}) {
        auto asset = DecodeAsset(part.data(), part.size(), options);
        ASSERT_FALSE(asset.ok()) << cut;
        ASSERT_EQ(asset.status().code(), StatusCode::kTruncated) << cut << ": " << asset.status().ToString();
      }
      ASSERT_FALSE(InspectContainer(part.data(), part.size()).ok());
    }
  }
}

TEST(HostileInput, EverySingleBitFlipIsDetected) {
  // Every byte is covered by the header CRC, a chunk CRC, or the zero-padding
  // rule, so each flip must be refused when checksums are on.
  std::mt19937_64 rng(42);
  int refused = 0;
  for (const auto& file : Files()) {
    for (int i = 0; i < 1500; ++i) {
      auto damaged = file;
      const size_t bit = rng() % (damaged.size() * 8);
      damaged[bit / 8] ^= static_cast<uint8_t>(1u << (bit % 8));
      auto asset = DecodeAsset(damaged.data(), damaged.size());
      ASSERT_FALSE(asset.ok()) << "flip of bit " << bit << " went unnoticed";
      ++refused;
      // Without checksums the structural checks run on damaged data: no crash,
      // and a success must still be a valid asset.
      auto unchecked = DecodeAsset(damaged.data(), damaged.size(), NoChecksums());
      if (unchecked.ok()) {
        ASSERT_TRUE(ValidateAsset(*unchecked).ok());
      }
    }
  }
  EXPECT_GE(refused, 3000);
}

TEST(HostileInput, RandomOverwritesWithoutChecksums) {
  std::mt19937_64 rng(7);
  int decoded = 0, refused = 0;
  for (const auto& file : Files()) {
    for (int i = 0; i < 1500; ++i) {
      auto damaged = file;
      const int edits = 1 + static_cast<int>(rng() % 8);
      for (int k = 0; k < edits; ++k) {
        const size_t at = rng() % damaged.size();
        switch (rng() % 4) {
          case 0: damaged[at] = static_cast<uint8_t>(rng()); break;
          case 1: damaged[at] = 0xFF; break;
          case 2: damaged[at] = 0; break;
          default: damaged[at] ^= 0x80; break;
        }
      }
      auto asset = DecodeAsset(damaged.data(), damaged.size(), NoChecksums());
      if (asset.ok()) {
        ASSERT_TRUE(ValidateAsset(*asset).ok());
        ++decoded;
      } else {
        ASSERT_NE(asset.status().code(), StatusCode::kInternal) << asset.status().ToString();
        ASSERT_FALSE(asset.status().message().empty());
        ++refused;
      }
    }
  }
  EXPECT_GT(refused, 0);
  std::printf("random overwrites: %d decoded, %d refused\n", decoded, refused);
}

TEST(HostileInput, ForgedCountsDoNotAllocate) {
  // A file whose TOC claims huge raw sizes for small chunks: refused by the
  // decoded-size limit before anything is allocated, or by the codec layer
  // once the real output is shorter.
  auto file = Load(golden::kGoldenZstdFile);
  ASSERT_FALSE(file.empty());
  auto info = InspectContainer(file.data(), file.size());
  ASSERT_TRUE(info.ok());
  ReadOptions r = NoChecksums();
  for (size_t i = 0; i < info->chunks.size(); ++i) {
    if (info->chunks[i].codec == Codec::kRaw) continue;
    auto damaged = file;
    const uint64_t huge = uint64_t{1} << 40;
    for (int k = 0; k < 8; ++k) damaged[32 + 48 * i + 24 + k] = static_cast<uint8_t>((huge + info->chunks[i].codec_skip) >> (8 * k));
    auto asset = DecodeAsset(damaged.data(), damaged.size(), r);
    ASSERT_FALSE(asset.ok());
    EXPECT_TRUE(asset.status().code() == StatusCode::kLimitExceeded || asset.status().code() == StatusCode::kCorrupt)
        << asset.status().ToString();
    r.max_decoded_bytes = uint64_t{1} << 62;  // and with no limit: the codec notices the short output
    r.max_expansion_ratio = 0;                 // (nor the decompression-bomb ratio)
    asset = DecodeAsset(damaged.data(), damaged.size(), r);
    ASSERT_FALSE(asset.ok());
    EXPECT_EQ(asset.status().code(), StatusCode::kCorrupt) << asset.status().ToString();
    r = NoChecksums();
  }
}

}  // namespace
}  // namespace atex
