// Versioning rules of format_spec/atex.md §10 and the reader's refusal of
// structurally valid but inconsistent files.
#include <gtest/gtest.h>

#include "atex/checksum.h"
#include "atex/container.h"
#include "container/asset_compare.h"
#include "container/byte_io.h"
#include "container/layout.h"
#include "container/synthetic_asset.h"

namespace atex {
namespace {

using container::OutputChunk;

std::vector<uint8_t> Encode(const Asset& asset, Codec codec = Codec::kShuffleZstd) {
  WriteOptions w;
  w.codec = codec;
  auto bytes = EncodeAsset(asset, w);
  EXPECT_TRUE(bytes.ok()) << bytes.status().ToString();
  return bytes.ok() ? *bytes : std::vector<uint8_t>{};
}

// The chunks of a file, as they are stored, for rebuilding it with edits.
std::vector<OutputChunk> Chunks(const std::vector<uint8_t>& file) {
  auto parsed = container::ParseContainer(file.data(), file.size(), true);
  EXPECT_TRUE(parsed.ok());
  std::vector<OutputChunk> chunks;
  for (const auto& e : parsed->entries) {
    OutputChunk c;
    c.type = e.type;
    c.flags = e.flags;
    c.codec = e.codec;
    c.raw_size = e.raw_size;
    c.stored.assign(file.begin() + e.offset, file.begin() + e.offset + e.stored_size);
    chunks.push_back(std::move(c));
  }
  return chunks;
}

OutputChunk RawChunk(const std::string& type, bool critical, std::vector<uint8_t> bytes) {
  OutputChunk c;
  c.type = type;
  c.flags = critical ? 1 : 0;
  c.raw_size = bytes.size();
  c.stored = std::move(bytes);
  return c;
}

void SetMinor(std::vector<uint8_t>& f, uint16_t minor) {
  container::StoreLE<uint16_t>(f.data() + 10, minor);
  const uint32_t count = container::LoadLE<uint32_t>(f.data() + 24);
  container::StoreLE<uint32_t>(f.data() + 28, 0);
  container::StoreLE<uint32_t>(f.data() + 28, Crc32c(f.data(), 32 + 48 * size_t{count}));
}

Asset Sample() {
  container::SyntheticAssetOptions o;
  o.gaussians = 64;
  o.sh_degree = 2;
  return container::MakeSyntheticAsset(o);
}

TEST(Compatibility, UnknownNonCriticalChunkIsSkippedAndListed) {
  const Asset asset = Sample();
  auto chunks = Chunks(Encode(asset));
  chunks.insert(chunks.begin() + 3, RawChunk("XTRA", false, {1, 2, 3, 4, 5, 6, 7}));
  chunks.push_back(RawChunk("ZZ99", false, std::vector<uint8_t>(100, 0xAB)));
  auto file = container::AssembleContainer(chunks);
  SetMinor(file, 3);  // as a 1.3 writer would
  auto back = DecodeAsset(file.data(), file.size());
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_TRUE(testing::AssetsEqual(asset, *back));
  auto info = InspectContainer(file.data(), file.size());
  ASSERT_TRUE(info.ok());
  EXPECT_EQ(info->version_minor, 3);
  int unknown = 0;
  for (const ChunkInfo& c : info->chunks) {
    if (!c.known) {
      ++unknown;
      EXPECT_TRUE(c.type == "XTRA" || c.type == "ZZ99");
    }
  }
  EXPECT_EQ(unknown, 2);
}

TEST(Compatibility, UnknownCodecOnSkippedChunkIsFine) {
  const Asset asset = Sample();
  auto chunks = Chunks(Encode(asset));
  OutputChunk future = RawChunk("FUTR", false, {9, 9, 9});
  future.codec.codec = static_cast<Codec>(12);
  future.raw_size = 77;
  chunks.push_back(future);
  const auto file = container::AssembleContainer(chunks);
  EXPECT_TRUE(DecodeAsset(file.data(), file.size()).ok());
}

// GTWN (1.1): time windows belong to a 4D asset. A file that has them without the deformation
// field's chunks is corrupt (format_spec §7).
TEST(Compatibility, TimeWindowsWithoutADeformationFieldAreCorrupt) {
  Asset asset = Sample();
  asset.gaussians.time_windows.assign(2 * asset.gaussians.size(), 0.0f);
  asset.gaussians.time_windows[1] = 3.0f;
  const auto file = Encode(asset);
  ASSERT_FALSE(file.empty());
  auto chunks = Chunks(file);
  std::erase_if(chunks, [](const OutputChunk& c) { return c.type == "DCFG" || c.type == "DGRD" || c.type == "DMLP"; });
  const auto still = container::AssembleContainer(chunks);
  auto back = DecodeAsset(still.data(), still.size());
  ASSERT_FALSE(back.ok());
  EXPECT_EQ(back.status().code(), StatusCode::kCorrupt);
  EXPECT_NE(back.status().message().find("GTWN"), std::string::npos) << back.status().message();
}

TEST(Compatibility, UnknownCriticalChunkIsRefusedByName) {
  auto chunks = Chunks(Encode(Sample()));
  chunks.push_back(RawChunk("NEW1", true, {1}));
  const auto file = container::AssembleContainer(chunks);
  auto back = DecodeAsset(file.data(), file.size());
  ASSERT_FALSE(back.ok());
  EXPECT_EQ(back.status().code(), StatusCode::kUnknownCriticalChunk);
  EXPECT_NE(back.status().message().find("'NEW1'"), std::string::npos) << back.status().message();
  // InspectContainer still lists it.
  auto info = InspectContainer(file.data(), file.size());
  ASSERT_TRUE(info.ok());
  EXPECT_FALSE(info->chunks.back().known);
  EXPECT_TRUE(info->chunks.back().critical());
}

TEST(Compatibility, NewerMajorRefusedNewerMinorAccepted) {
  const Asset asset = Sample();
  auto file = Encode(asset);
  SetMinor(file, 65535);
  auto back = DecodeAsset(file.data(), file.size());
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_TRUE(testing::AssetsEqual(asset, *back));
  container::StoreLE<uint16_t>(file.data() + 8, 2);
  back = DecodeAsset(file.data(), file.size());
  ASSERT_FALSE(back.ok());
  EXPECT_EQ(back.status().code(), StatusCode::kUnsupportedVersion);
  EXPECT_NE(back.status().message().find("2.65535"), std::string::npos) << back.status().message();
}

TEST(Compatibility, ChunkOrderIsFree) {
  const Asset asset = Sample();
  auto chunks = Chunks(Encode(asset));
  std::reverse(chunks.begin(), chunks.end());
  const auto file = container::AssembleContainer(chunks);
  auto back = DecodeAsset(file.data(), file.size());
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_TRUE(testing::AssetsEqual(asset, *back));
}

// Files whose every chunk is intact but which contradict themselves.
TEST(Compatibility, InconsistentFilesAreCorrupt) {
  const Asset asset = Sample();
  const auto base = Chunks(Encode(asset, Codec::kRaw));
  auto find = [](std::vector<OutputChunk>& chunks, const std::string& type) -> OutputChunk& {
    for (auto& c : chunks) {
      if (c.type == type) return c;
    }
    throw std::runtime_error("no chunk " + type);
  };
  auto decode = [](const std::vector<OutputChunk>& chunks) {
    const auto file = container::AssembleContainer(chunks);
    return DecodeAsset(file.data(), file.size()).status();
  };
  {
    auto chunks = base;
    chunks.erase(chunks.begin() + 3);  // GROT
    const Status s = decode(chunks);
    EXPECT_EQ(s.code(), StatusCode::kCorrupt);
    EXPECT_NE(s.message().find("'GROT' is missing"), std::string::npos) << s.message();
  }
  {
    auto chunks = base;
    container::StoreLE<uint64_t>(find(chunks, "GHDR").stored.data(), 65);  // N says 65, streams hold 64
    const Status s = decode(chunks);
    EXPECT_EQ(s.code(), StatusCode::kCorrupt);
    EXPECT_NE(s.message().find("GOPA"), std::string::npos) << s.message();
  }
  {
    auto chunks = base;
    find(chunks, "GHDR").stored[8] = 1;  // degree 1, but GSHR holds degree 2's 24 components
    EXPECT_EQ(decode(chunks).code(), StatusCode::kCorrupt);
  }
  {
    auto chunks = base;
    for (size_t i = 0; i < chunks.size(); ++i) {
      if (chunks[i].type == "TEXL") chunks.erase(chunks.begin() + i);
    }
    const Status s = decode(chunks);
    EXPECT_EQ(s.code(), StatusCode::kCorrupt);
    EXPECT_NE(s.message().find("TLAY and TEXL"), std::string::npos) << s.message();
  }
  {
    auto chunks = base;
    for (size_t i = 0; i < chunks.size(); ++i) {
      if (chunks[i].type == "DMLP") chunks.erase(chunks.begin() + i);
    }
    EXPECT_EQ(decode(chunks).code(), StatusCode::kCorrupt);
  }
  {
    auto chunks = base;
    // A texture grows from 1x1 to 2x2 in TLAY without new texels.
    auto& tlay = find(chunks, "TLAY").stored;
    size_t i = 0;
    while ((tlay[i] & 0x0F) != 0) ++i;
    tlay[i] |= 0x05;
    const Status s = decode(chunks);
    EXPECT_EQ(s.code(), StatusCode::kCorrupt);
    EXPECT_NE(s.message().find("TEXL"), std::string::npos) << s.message();
  }
  {
    auto chunks = base;
    auto& meta = find(chunks, "META");
    const std::string text = "{\"texture_mode\":\"none\"}";  // but TLAY/TEXL are present
    meta.stored.assign(text.begin(), text.end());
    meta.raw_size = text.size();
    EXPECT_EQ(decode(chunks).code(), StatusCode::kCorrupt);
  }
}

}  // namespace
}  // namespace atex
