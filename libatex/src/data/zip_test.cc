// Zip reader: round trips through the writer, the real .npz files, and hostile
// archives (truncation, forged sizes/offsets/counts, bad CRC, bit flips).
#include <random>

#include <gtest/gtest.h>
#include <zlib.h>

#include "atex/file_io.h"
#include "atex/zip.h"
#include "core/test_support.h"

namespace atex {
namespace {

std::vector<uint8_t> Bytes(const std::string& s) { return std::vector<uint8_t>(s.begin(), s.end()); }

std::vector<uint8_t> TwoMemberArchive(bool deflate) {
  ZipWriter writer;
  const std::vector<uint8_t> a = Bytes("hello, zip");
  std::vector<uint8_t> b(5000);
  for (size_t i = 0; i < b.size(); ++i) b[i] = static_cast<uint8_t>(i % 7);
  EXPECT_TRUE(writer.Add("a.txt", a.data(), a.size(), deflate).ok());
  EXPECT_TRUE(writer.Add("dir/b.bin", b.data(), b.size(), deflate).ok());
  return writer.Finish();
}

TEST(Zip, RoundTripStoredAndDeflated) {
  for (bool deflate : {false, true}) {
    const std::vector<uint8_t> archive = TwoMemberArchive(deflate);
    auto zip = ZipArchive::FromView(archive.data(), archive.size(), "mem");
    ASSERT_TRUE(zip.ok()) << zip.status().ToString();
    ASSERT_EQ(zip->entries().size(), 2u);
    EXPECT_EQ(zip->entries()[1].name, "dir/b.bin");
    EXPECT_EQ(zip->entries()[1].method, deflate ? 8 : 0);
    auto a = zip->Extract("a.txt");
    ASSERT_TRUE(a.ok()) << a.status().ToString();
    EXPECT_EQ(*a, Bytes("hello, zip"));
    auto b = zip->Extract("dir/b.bin");
    ASSERT_TRUE(b.ok());
    ASSERT_EQ(b->size(), 5000u);
    EXPECT_EQ((*b)[4999], 4999 % 7);
    EXPECT_EQ(zip->Extract("missing").status().code(), StatusCode::kNotFound);
    EXPECT_EQ(zip->StoredView(zip->entries()[0]).ok(), !deflate);
  }
}

TEST(Zip, EmptyMemberAndEmptyArchive) {
  ZipWriter writer;
  ASSERT_TRUE(writer.Add("empty", nullptr, 0, true).ok());
  const std::vector<uint8_t> archive = writer.Finish();
  auto zip = ZipArchive::FromView(archive.data(), archive.size(), "mem");
  ASSERT_TRUE(zip.ok()) << zip.status().ToString();
  auto e = zip->Extract("empty");
  ASSERT_TRUE(e.ok()) << e.status().ToString();
  EXPECT_TRUE(e->empty());
  const std::vector<uint8_t> none = ZipWriter().Finish();
  auto empty = ZipArchive::FromView(none.data(), none.size(), "mem");
  ASSERT_TRUE(empty.ok());
  EXPECT_TRUE(empty->entries().empty());
}

TEST(Zip, ArchiveWithCommentIsFound) {
  std::vector<uint8_t> archive = TwoMemberArchive(false);
  // Append a comment: patch the end record's comment length and add the bytes.
  const std::string comment = "a trailing archive comment";
  archive[archive.size() - 2] = static_cast<uint8_t>(comment.size());
  archive.insert(archive.end(), comment.begin(), comment.end());
  auto zip = ZipArchive::FromView(archive.data(), archive.size(), "mem");
  ASSERT_TRUE(zip.ok()) << zip.status().ToString();
  EXPECT_EQ(zip->entries().size(), 2u);
}

TEST(Zip, ReadsRealNpzArchives) {
  ATEX_REQUIRE_DATA_FILE(lego, "dnerf_lego_tiny/tiny_dnerf_data.npz");
  auto zip = ZipArchive::OpenFile(lego.string());
  ASSERT_TRUE(zip.ok()) << zip.status().ToString();
  ASSERT_EQ(zip->entries().size(), 4u);
  const ZipEntry* images = zip->Find("images.npy");
  ASSERT_NE(images, nullptr);
  EXPECT_EQ(images->method, 8);
  EXPECT_EQ(images->uncompressed_size, 9720128u);  // 128-byte header + 81*100*100*3*4
  auto bytes = zip->Extract(*images);
  ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
  EXPECT_EQ(bytes->size(), 9720128u);

  ATEX_REQUIRE_DATA_FILE(garden, "gsplat_test_garden/test_garden.npz");
  auto g = ZipArchive::OpenFile(garden.string());
  ASSERT_TRUE(g.ok()) << g.status().ToString();
  const ZipEntry* means = g->Find("means3d.npy");
  ASSERT_NE(means, nullptr);
  EXPECT_EQ(means->method, 0);
  auto view = g->StoredView(*means);
  ASSERT_TRUE(view.ok()) << view.status().ToString();
  EXPECT_EQ(view->size, 1665320u);
}

TEST(Zip, RejectsNonZipAndTruncation) {
  const std::vector<uint8_t> junk = Bytes("this is not a zip archive at all, just text");
  EXPECT_EQ(ZipArchive::FromView(junk.data(), junk.size(), "junk").status().code(), StatusCode::kBadMagic);
  EXPECT_EQ(ZipArchive::FromView(junk.data(), 5, "tiny").status().code(), StatusCode::kTruncated);
  const std::vector<uint8_t> archive = TwoMemberArchive(true);
  // Every truncation either fails to open or fails to extract; none crashes or succeeds wrongly.
  for (size_t cut = 0; cut < archive.size(); ++cut) {
    auto zip = ZipArchive::FromView(archive.data(), cut, "cut");
    if (!zip.ok()) continue;
    for (const ZipEntry& e : zip->entries()) {
      auto data = zip->Extract(e);
      if (data.ok()) ADD_FAILURE() << "truncated at " << cut << " but member " << e.name << " extracted";
    }
  }
}

TEST(Zip, ForgedFieldsAreRefused) {
  const std::vector<uint8_t> good = TwoMemberArchive(true);
  const size_t end = good.size() - 22;
  const uint32_t cd_offset =
      good[end + 16] | good[end + 17] << 8 | good[end + 18] << 16 | uint32_t(good[end + 19]) << 24;
  auto patch32 = [](std::vector<uint8_t>& b, size_t at, uint32_t v) {
    for (int i = 0; i < 4; ++i) b[at + i] = static_cast<uint8_t>(v >> (8 * i));
  };
  {  // entry count far beyond what the directory can hold
    std::vector<uint8_t> b = good;
    b[end + 10] = b[end + 11] = 0xF0;
    EXPECT_EQ(ZipArchive::FromView(b.data(), b.size(), "m").status().code(), StatusCode::kCorrupt);
  }
  {  // central directory offset past the end
    std::vector<uint8_t> b = good;
    patch32(b, end + 16, 0x7FFFFFF0);
    EXPECT_EQ(ZipArchive::FromView(b.data(), b.size(), "m").status().code(), StatusCode::kTruncated);
  }
  {  // first member: uncompressed size forged to 3 GB (beyond deflate's ratio)
    std::vector<uint8_t> b = good;
    patch32(b, cd_offset + 24, 0xC0000000u);
    auto zip = ZipArchive::FromView(b.data(), b.size(), "m");
    ASSERT_TRUE(zip.ok());
    EXPECT_EQ(zip->Extract(zip->entries()[0]).status().code(), StatusCode::kCorrupt);
  }
  {  // second member: uncompressed size one byte short -> inflates to more than declared
    std::vector<uint8_t> b = good;
    const size_t second = cd_offset + 46 + 5;  // first record: 46 bytes + "a.txt"
    patch32(b, second + 24, 4999);
    auto zip = ZipArchive::FromView(b.data(), b.size(), "m");
    ASSERT_TRUE(zip.ok()) << zip.status().ToString();
    EXPECT_EQ(zip->Extract(zip->entries()[1]).status().code(), StatusCode::kCorrupt);
  }
  {  // CRC mismatch
    std::vector<uint8_t> b = good;
    b[cd_offset + 16] ^= 0xFF;
    auto zip = ZipArchive::FromView(b.data(), b.size(), "m");
    ASSERT_TRUE(zip.ok());
    EXPECT_EQ(zip->Extract(zip->entries()[0]).status().code(), StatusCode::kChecksumMismatch);
  }
  {  // local header offset pointing into the middle of data
    std::vector<uint8_t> b = good;
    patch32(b, cd_offset + 42, 7);
    EXPECT_FALSE(ZipArchive::FromView(b.data(), b.size(), "m").ok());
  }
  {  // unsupported method
    std::vector<uint8_t> b = good;
    b[cd_offset + 10] = 14;  // LZMA
    auto zip = ZipArchive::FromView(b.data(), b.size(), "m");
    ASSERT_TRUE(zip.ok());
    EXPECT_EQ(zip->Extract(zip->entries()[0]).status().code(), StatusCode::kUnsupportedCodec);
  }
}

TEST(Zip, RandomBitFlipsNeverCrash) {
  const std::vector<uint8_t> good = TwoMemberArchive(true);
  std::mt19937 rng(42);
  int failures = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    std::vector<uint8_t> b = good;
    const int flips = 1 + rng() % 4;
    for (int f = 0; f < flips; ++f) b[rng() % b.size()] ^= static_cast<uint8_t>(1u << (rng() % 8));
    auto zip = ZipArchive::FromView(b.data(), b.size(), "flip");
    if (!zip.ok()) {
      ++failures;
      continue;
    }
    for (const ZipEntry& e : zip->entries()) failures += zip->Extract(e).ok() ? 0 : 1;
  }
  EXPECT_GT(failures, 0);
}

TEST(Zip, Zip64RecordsAreRead) {
  // Hand-build a ZIP64 archive: one stored member whose sizes and offset live in
  // the ZIP64 extra field, and a ZIP64 end record + locator.
  const std::vector<uint8_t> data = Bytes("zip64 payload");
  const uint32_t crc = ZipCrc32(data.data(), data.size());
  std::vector<uint8_t> b;
  auto put16 = [&](uint16_t v) { b.push_back(v & 0xFF); b.push_back(v >> 8); };
  auto put32 = [&](uint32_t v) { for (int i = 0; i < 4; ++i) b.push_back(static_cast<uint8_t>(v >> (8 * i))); };
  auto put64 = [&](uint64_t v) { for (int i = 0; i < 8; ++i) b.push_back(static_cast<uint8_t>(v >> (8 * i))); };
  put32(0x04034b50); put16(45); put16(0); put16(0); put16(0); put16(0); put32(crc);
  put32(0xFFFFFFFF); put32(0xFFFFFFFF); put16(1); put16(20); b.push_back('x');
  put16(1); put16(16); put64(data.size()); put64(data.size());
  b.insert(b.end(), data.begin(), data.end());
  const uint64_t cd = b.size();
  put32(0x02014b50); put16(45); put16(45); put16(0); put16(0); put16(0); put16(0); put32(crc);
  put32(0xFFFFFFFF); put32(0xFFFFFFFF); put16(1); put16(28); put16(0); put16(0); put16(0); put32(0);
  put32(0xFFFFFFFF); b.push_back('x');
  put16(1); put16(24); put64(data.size()); put64(data.size()); put64(0);
  const uint64_t cd_size = b.size() - cd;
  const uint64_t z64 = b.size();
  put32(0x06064b50); put64(44); put16(45); put16(45); put32(0); put32(0); put64(1); put64(1); put64(cd_size); put64(cd);
  put32(0x07064b50); put32(0); put64(z64); put32(1);
  put32(0x06054b50); put16(0); put16(0); put16(0xFFFF); put16(0xFFFF); put32(0xFFFFFFFF); put32(0xFFFFFFFF); put16(0);
  auto zip = ZipArchive::FromView(b.data(), b.size(), "zip64");
  ASSERT_TRUE(zip.ok()) << zip.status().ToString();
  ASSERT_EQ(zip->entries().size(), 1u);
  auto x = zip->Extract("x");
  ASSERT_TRUE(x.ok()) << x.status().ToString();
  EXPECT_EQ(*x, data);
}

}  // namespace
}  // namespace atex
