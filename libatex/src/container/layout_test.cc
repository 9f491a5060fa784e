#include "container/layout.h"

#include <gtest/gtest.h>

#include "atex/checksum.h"
#include "container/byte_io.h"

namespace atex::container {
namespace {

OutputChunk Chunk(const std::string& type, bool critical, std::vector<uint8_t> bytes) {
  OutputChunk c;
  c.type = type;
  c.flags = critical ? 1 : 0;
  c.raw_size = bytes.size();
  c.stored = std::move(bytes);
  return c;
}

std::vector<uint8_t> Sample() {
  return AssembleContainer({Chunk("AAAA", true, {1, 2, 3, 4, 5}), Chunk("BBBB", false, {}),
                            Chunk("CCC1", false, std::vector<uint8_t>(13, 9))});
}

// Recomputes the header CRC from its definition (§3) after a deliberate edit, so
// that the check under test is the one that fires.
void FixHeaderCrc(std::vector<uint8_t>& f) {
  const uint32_t count = LoadLE<uint32_t>(f.data() + 24);
  const size_t toc_end = 32 + 48 * size_t{count};
  if (toc_end > f.size()) return;  // the CRC cannot be computed; the size check fires first anyway
  StoreLE<uint32_t>(f.data() + 28, 0);
  StoreLE<uint32_t>(f.data() + 28, Crc32c(f.data(), toc_end));
}

StatusCode Parse(const std::vector<uint8_t>& f) { return ParseContainer(f.data(), f.size(), true).status().code(); }

TEST(Layout, AssembledFileIsCanonical) {
  const auto f = Sample();
  // 32 + 3*48 = 176; chunk 0 at 176 (5 bytes, padded to 8), chunk 1 at 184 (0
  // bytes), chunk 2 at 184 (13 bytes, padded to 16): 200.
  ASSERT_EQ(f.size(), 200u);
  auto parsed = ParseContainer(f.data(), f.size(), true);
  ASSERT_TRUE(parsed.ok()) << parsed.status().ToString();
  ASSERT_EQ(parsed->entries.size(), 3u);
  EXPECT_EQ(parsed->entries[0].offset, 176u);
  EXPECT_EQ(parsed->entries[1].offset, 184u);
  EXPECT_EQ(parsed->entries[2].offset, 184u);
  EXPECT_EQ(parsed->entries[2].stored_size, 13u);
  EXPECT_EQ(parsed->entries[0].crc, Crc32c(f.data() + 176, 5));
  EXPECT_TRUE(parsed->entries[0].critical());
  EXPECT_FALSE(parsed->entries[1].critical());
  EXPECT_EQ(parsed->file_size, 200u);
  EXPECT_EQ(parsed->version_major, 1);
  EXPECT_EQ(parsed->version_minor, 0);
  // Header bytes by the spec.
  EXPECT_EQ((std::vector<uint8_t>(f.begin(), f.begin() + 8)),
            (std::vector<uint8_t>{0x89, 0x41, 0x54, 0x45, 0x58, 0x0D, 0x0A, 0x1A}));
  EXPECT_EQ(LoadLE<uint64_t>(f.data() + 16), 200u);
  EXPECT_EQ(LoadLE<uint32_t>(f.data() + 24), 3u);
}

TEST(Layout, EmptyContainer) {
  const auto f = AssembleContainer(std::vector<OutputChunk>{});
  ASSERT_EQ(f.size(), 32u);
  EXPECT_TRUE(ParseContainer(f.data(), f.size(), true).ok());
}

TEST(Layout, HeaderCrc) {
  auto f = Sample();
  f[80 + 24] ^= 1;  // TOC entry 1's raw size, edited without fixing the CRC
  EXPECT_EQ(Parse(f), StatusCode::kChecksumMismatch);
  f = Sample();
  f[28] ^= 0x10;
  EXPECT_EQ(Parse(f), StatusCode::kChecksumMismatch);
  EXPECT_TRUE(ParseContainer(f.data(), f.size(), false).ok());  // CRC checks off
}

TEST(Layout, ShortInputs) {
  const auto f = Sample();
  EXPECT_EQ(ParseContainer(f.data(), 0, true).status().code(), StatusCode::kTruncated);
  EXPECT_EQ(ParseContainer(f.data(), 5, true).status().code(), StatusCode::kTruncated);   // magic prefix
  EXPECT_EQ(ParseContainer(f.data(), 20, true).status().code(), StatusCode::kTruncated);  // inside the header
  const std::vector<uint8_t> text = {'h', 'e', 'l', 'l', 'o'};
  EXPECT_EQ(Parse(text), StatusCode::kBadMagic);
  for (size_t cut = 32; cut < f.size(); ++cut) {
    EXPECT_EQ(ParseContainer(f.data(), cut, true).status().code(), StatusCode::kTruncated) << cut;
  }
}

TEST(Layout, MagicDetectsTextModeMangling) {
  auto f = Sample();
  f.erase(f.begin() + 5);  // CR-LF turned into LF
  EXPECT_EQ(Parse(f), StatusCode::kBadMagic);
  f = Sample();
  f[0] &= 0x7F;  // 7-bit transfer
  EXPECT_EQ(Parse(f), StatusCode::kBadMagic);
}

TEST(Layout, Versions) {
  auto f = Sample();
  StoreLE<uint16_t>(f.data() + 8, 2);
  FixHeaderCrc(f);
  auto parsed = ParseContainer(f.data(), f.size(), true);
  EXPECT_EQ(parsed.status().code(), StatusCode::kUnsupportedVersion);
  EXPECT_NE(parsed.status().message().find("2.0"), std::string::npos);
  EXPECT_NE(parsed.status().message().find("1.1"), std::string::npos);  // this reader's version
  f = Sample();
  StoreLE<uint16_t>(f.data() + 10, 9);  // newer minor: readable
  FixHeaderCrc(f);
  parsed = ParseContainer(f.data(), f.size(), true);
  ASSERT_TRUE(parsed.ok()) << parsed.status().ToString();
  EXPECT_EQ(parsed->version_minor, 9);
}

struct Edit {
  const char* name;
  void (*apply)(std::vector<uint8_t>&);
  StatusCode code;
};

TEST(Layout, StructuralRules) {
  const Edit edits[] = {
      {"file flags", [](std::vector<uint8_t>& f) { f[12] = 1; }, StatusCode::kCorrupt},
      {"toc reserved", [](std::vector<uint8_t>& f) { f[32 + 44] = 1; }, StatusCode::kCorrupt},
      {"chunk flag bit 1", [](std::vector<uint8_t>& f) { f[32 + 4] |= 2; }, StatusCode::kCorrupt},
      {"lower-case type", [](std::vector<uint8_t>& f) { f[32] = 'a'; }, StatusCode::kCorrupt},
      {"space in type", [](std::vector<uint8_t>& f) { f[32 + 3] = ' '; }, StatusCode::kCorrupt},
      {"duplicate type", [](std::vector<uint8_t>& f) { std::copy(f.begin() + 32, f.begin() + 36, f.begin() + 80); },
       StatusCode::kCorrupt},
      {"offset shifted", [](std::vector<uint8_t>& f) { StoreLE<uint64_t>(f.data() + 80 + 8, 192); },
       StatusCode::kCorrupt},
      {"offset unaligned", [](std::vector<uint8_t>& f) { StoreLE<uint64_t>(f.data() + 32 + 8, 177); },
       StatusCode::kCorrupt},
      {"stored beyond file",
       [](std::vector<uint8_t>& f) {
         StoreLE<uint64_t>(f.data() + 128 + 16, 1u << 20);
         StoreLE<uint64_t>(f.data() + 128 + 24, 1u << 20);
       },
       StatusCode::kCorrupt},
      {"stored overflow", [](std::vector<uint8_t>& f) { StoreLE<uint64_t>(f.data() + 128 + 16, ~uint64_t{0}); },
       StatusCode::kCorrupt},
      {"raw size differs for raw", [](std::vector<uint8_t>& f) { StoreLE<uint64_t>(f.data() + 32 + 24, 6); },
       StatusCode::kCorrupt},
      {"padding not zero", [](std::vector<uint8_t>& f) { f[176 + 6] = 1; }, StatusCode::kCorrupt},
      {"last padding not zero", [](std::vector<uint8_t>& f) { f[199] = 1; }, StatusCode::kCorrupt},
      {"chunk count too big", [](std::vector<uint8_t>& f) { StoreLE<uint32_t>(f.data() + 24, 4); },
       StatusCode::kCorrupt},
      {"chunk count huge", [](std::vector<uint8_t>& f) { StoreLE<uint32_t>(f.data() + 24, 0xFFFFFFFFu); },
       StatusCode::kCorrupt},
      {"chunk count small (gap at end)", [](std::vector<uint8_t>& f) { StoreLE<uint32_t>(f.data() + 24, 2); },
       StatusCode::kCorrupt},
      {"zstd with an element size",
       [](std::vector<uint8_t>& f) {
         f[80 + 6] = 1;
         f[80 + 7] = 4;
       },
       StatusCode::kCorrupt},
      {"known type wrong critical bit", [](std::vector<uint8_t>& f) { std::memcpy(f.data() + 32, "GSTA", 4); },
       StatusCode::kCorrupt},
      {"draco outside GPOS",
       [](std::vector<uint8_t>& f) {
         f[128 + 6] = 4;
         f[128 + 7] = 4;
         StoreLE<uint32_t>(f.data() + 128 + 36, 3);
         StoreLE<uint32_t>(f.data() + 128 + 40, 1);
         StoreLE<uint64_t>(f.data() + 128 + 24, 13);
       },
       StatusCode::kCorrupt},
  };
  for (const Edit& e : edits) {
    auto f = Sample();
    e.apply(f);
    FixHeaderCrc(f);
    EXPECT_EQ(Parse(f), e.code) << e.name << ": " << ParseContainer(f.data(), f.size(), true).status().ToString();
  }
}

TEST(Layout, SizeFieldAgainstRealSize) {
  auto f = Sample();
  f.resize(f.size() + 8, 0);  // trailing bytes the header does not announce
  EXPECT_EQ(Parse(f), StatusCode::kCorrupt);
  StoreLE<uint64_t>(f.data() + 16, f.size());  // announced, but no chunk covers them
  FixHeaderCrc(f);
  EXPECT_EQ(Parse(f), StatusCode::kCorrupt);
  f = Sample();
  StoreLE<uint64_t>(f.data() + 16, f.size() + 1);
  FixHeaderCrc(f);
  EXPECT_EQ(Parse(f), StatusCode::kTruncated);
}

TEST(Layout, UnknownCodecOnUnknownChunkIsListedNotRefused) {
  auto f = Sample();
  f[128 + 6] = 7;  // CCC1 (non-critical, unknown) with a future codec 7
  StoreLE<uint64_t>(f.data() + 128 + 24, 1000);
  FixHeaderCrc(f);
  auto parsed = ParseContainer(f.data(), f.size(), true);
  ASSERT_TRUE(parsed.ok()) << parsed.status().ToString();
  EXPECT_EQ(static_cast<int>(parsed->entries[2].codec.codec), 7);
}

TEST(Layout, ChunkCrc) {
  auto f = Sample();
  auto parsed = ParseContainer(f.data(), f.size(), true);
  ASSERT_TRUE(parsed.ok());
  EXPECT_TRUE(VerifyChunkCrc(f.data(), parsed->entries[0], 0).ok());
  f[178] ^= 0x40;
  const Status s = VerifyChunkCrc(f.data(), parsed->entries[0], 0);
  EXPECT_EQ(s.code(), StatusCode::kChecksumMismatch);
  EXPECT_NE(s.message().find("'AAAA' (#0) at byte 176"), std::string::npos) << s.message();
}

}  // namespace
}  // namespace atex::container
