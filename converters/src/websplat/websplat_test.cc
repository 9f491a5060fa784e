// The web viewers' static formats (.splat, .ksplat, PlayCanvas SOG and compressed
// PLY) on hostile input: truncations, wrong counts, huge declared sizes, damaged
// metadata and images give a numbered error naming the position, never a crash or
// a large allocation. No Node needed (the real files are websplat_real_test.cc).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <functional>
#include <string>

#include <nlohmann/json.hpp>

#include "atex/converters/convert.h"
#include "atex/converters/ply.h"
#include "atex/converters/web_splats.h"
#include "atex/file_io.h"
#include "atex/zip.h"
#include "convert/bytes.h"
#include "core/test_support.h"

namespace atex {
namespace {

namespace fs = std::filesystem;
constexpr double kShC0 = 0.28209479177387814;

// ---- hostile inputs (no Node needed) ------------------------------------------

std::vector<uint8_t> SplatRows(size_t n) {
  std::vector<uint8_t> out(n * 32, 0);
  for (size_t i = 0; i < n; ++i) {
    uint8_t* row = &out[i * 32];
    const float values[6] = {float(i), 1, 2, 0.1f, 0.2f, 0.3f};
    std::memcpy(row, values, sizeof values);
    row[24] = 200, row[25] = 100, row[26] = 50, row[27] = 128;
    row[28] = 255, row[29] = 128, row[30] = 128, row[31] = 128;
  }
  return out;
}

TEST(WebSplatsHostile, SplatSizesAndValues) {
  auto bytes = SplatRows(3);
  auto g = ReadSplatGaussiansFromMemory(bytes.data(), bytes.size());
  ASSERT_TRUE(g.ok()) << g.status().ToString();
  EXPECT_EQ(g->size(), 3u);
  EXPECT_NEAR(std::exp(g->log_scales[1]), 0.2, 1e-6);
  EXPECT_NEAR(g->sh[0], (200 / 255.0 - 0.5) / kShC0, 1e-5);
  auto truncated = ReadSplatGaussiansFromMemory(bytes.data(), bytes.size() - 5);
  EXPECT_EQ(truncated.status().code(), StatusCode::kCorrupt);
  EXPECT_NE(truncated.status().message().find("byte 64"), std::string::npos) << truncated.status().ToString();
  float bad = -1;
  std::memcpy(&bytes[32 + 16], &bad, 4);
  auto negative = ReadSplatGaussiansFromMemory(bytes.data(), bytes.size());
  EXPECT_EQ(negative.status().code(), StatusCode::kCorrupt);
  EXPECT_NE(negative.status().message().find("Gaussian 1"), std::string::npos);
  WebSplatLimits limits;
  limits.max_gaussians = 2;
  EXPECT_EQ(ReadSplatGaussiansFromMemory(SplatRows(3).data(), 96, limits).status().code(), StatusCode::kLimitExceeded);
}

// A level-0 .ksplat of `n` Gaussians in one section, written from the layout
// GaussianSplats3D documents in its SplatBuffer (header 4096 bytes, section header 1024).
std::vector<uint8_t> Ksplat(uint32_t n) {
  using converters::bytes::StoreLE;
  std::vector<uint8_t> out(4096 + 1024 + size_t(n) * 44, 0);
  out[0] = 0, out[1] = 1;
  StoreLE<uint32_t>(&out[4], 1), StoreLE<uint32_t>(&out[8], 1), StoreLE<uint32_t>(&out[12], n),
      StoreLE<uint32_t>(&out[16], n);
  uint8_t* s = &out[4096];
  StoreLE<uint32_t>(s, n), StoreLE<uint32_t>(s + 4, n), StoreLE<uint32_t>(s + 8, 256);
  for (uint32_t i = 0; i < n; ++i) {
    uint8_t* row = &out[5120 + size_t(i) * 44];
    const float values[10] = {float(i), 2, 3, 0.5f, 0.5f, 0.5f, 1, 0, 0, 0};
    for (int k = 0; k < 10; ++k) StoreLE<float>(row + 4 * k, values[k]);
    row[40] = 10, row[41] = 20, row[42] = 30, row[43] = 255;
  }
  return out;
}

TEST(WebSplatsHostile, KsplatHeaderSectionsAndTruncation) {
  auto bytes = Ksplat(4);
  auto g = ReadKsplatGaussiansFromMemory(bytes.data(), bytes.size());
  ASSERT_TRUE(g.ok()) << g.status().ToString();
  EXPECT_EQ(g->size(), 4u);
  EXPECT_EQ(g->positions[9], 3.0f);
  EXPECT_EQ(g->rotations[0], 1.0f);
  // Truncated rows, a header shorter than 4096 bytes, a huge section count, a wrong total.
  auto truncated = ReadKsplatGaussiansFromMemory(bytes.data(), bytes.size() - 1);
  EXPECT_EQ(truncated.status().code(), StatusCode::kTruncated);
  EXPECT_NE(truncated.status().message().find("byte 5120"), std::string::npos) << truncated.status().ToString();
  EXPECT_EQ(ReadKsplatGaussiansFromMemory(bytes.data(), 100).status().code(), StatusCode::kTruncated);
  auto huge = bytes;
  converters::bytes::StoreLE<uint32_t>(&huge[4], 0xffffffffu);
  EXPECT_EQ(ReadKsplatGaussiansFromMemory(huge.data(), huge.size()).status().code(), StatusCode::kCorrupt);
  auto rows = bytes;
  converters::bytes::StoreLE<uint32_t>(&rows[4096 + 4], 0x7fffffffu);  // the section's room for rows
  EXPECT_EQ(ReadKsplatGaussiansFromMemory(rows.data(), rows.size()).status().code(), StatusCode::kTruncated);
  converters::bytes::StoreLE<uint32_t>(&rows[4096], 0x7fffffffu);
  converters::bytes::StoreLE<uint32_t>(&rows[16], 0x7fffffffu);  // and a total above the reader's limit
  EXPECT_EQ(ReadKsplatGaussiansFromMemory(rows.data(), rows.size()).status().code(), StatusCode::kLimitExceeded);
  auto total = bytes;
  converters::bytes::StoreLE<uint32_t>(&total[16], 5);
  EXPECT_EQ(ReadKsplatGaussiansFromMemory(total.data(), total.size()).status().code(), StatusCode::kCorrupt);
  auto level = bytes;
  converters::bytes::StoreLE<uint16_t>(&level[20], 3);
  EXPECT_EQ(ReadKsplatGaussiansFromMemory(level.data(), level.size()).status().code(), StatusCode::kUnsupported);
  auto version = bytes;
  version[0] = 7;
  EXPECT_EQ(ReadKsplatGaussiansFromMemory(version.data(), version.size()).status().code(), StatusCode::kBadMagic);
  // Level 1 with buckets that do not cover the rows.
  auto buckets = bytes;
  converters::bytes::StoreLE<uint16_t>(&buckets[20], 1);
  EXPECT_FALSE(ReadKsplatGaussiansFromMemory(buckets.data(), buckets.size()).ok());
}

std::vector<uint8_t> CompressedPly(uint32_t n, uint32_t chunks) {
  std::string header = "ply\nformat binary_little_endian 1.0\nelement chunk " + std::to_string(chunks) + "\n";
  for (const char* name : {"min_x", "min_y", "min_z", "max_x", "max_y", "max_z", "min_scale_x", "min_scale_y",
                           "min_scale_z", "max_scale_x", "max_scale_y", "max_scale_z"}) {
    header += std::string("property float ") + name + "\n";
  }
  header += "element vertex " + std::to_string(n) +
            "\nproperty uint packed_position\nproperty uint packed_rotation\nproperty uint packed_scale\n"
            "property uint packed_color\nend_header\n";
  std::vector<uint8_t> out(header.begin(), header.end());
  for (uint32_t c = 0; c < chunks; ++c) {
    for (float v : {0.f, 0.f, 0.f, 1.f, 2.f, 4.f, -3.f, -3.f, -3.f, -1.f, -1.f, -1.f}) {
      converters::bytes::AppendLE<float>(out, v);
    }
  }
  for (uint32_t i = 0; i < n; ++i) {
    converters::bytes::AppendLE<uint32_t>(out, 0xffffffffu);               // position at the chunk's max
    converters::bytes::AppendLE<uint32_t>(out, (0u << 30) | (512u << 20) | (512u << 10) | 512u);  // ~identity
    converters::bytes::AppendLE<uint32_t>(out, 0);                         // scales at the min
    converters::bytes::AppendLE<uint32_t>(out, 0x80808080u);
  }
  return out;
}

TEST(WebSplatsHostile, CompressedPlyLayoutAndCounts) {
  auto bytes = CompressedPly(300, 2);
  auto g = ReadPlyGaussiansFromMemory(bytes.data(), bytes.size());
  ASSERT_TRUE(g.ok()) << g.status().ToString();
  EXPECT_EQ(g->size(), 300u);
  EXPECT_FLOAT_EQ(g->positions[299 * 3 + 2], 4.0f);
  EXPECT_FLOAT_EQ(g->log_scales[0], -3.0f);
  EXPECT_NEAR(g->rotations[0], 1.0, 1e-2);
  auto wrong_chunks = CompressedPly(300, 1);
  auto refused = ReadPlyGaussiansFromMemory(wrong_chunks.data(), wrong_chunks.size());
  EXPECT_EQ(refused.status().code(), StatusCode::kCorrupt);
  EXPECT_NE(refused.status().message().find("chunks"), std::string::npos);
  auto truncated = ReadPlyGaussiansFromMemory(bytes.data(), bytes.size() - 3);
  EXPECT_EQ(truncated.status().code(), StatusCode::kTruncated);
  EXPECT_NE(truncated.status().message().find("vertex"), std::string::npos) << truncated.status().ToString();
  // A huge declared vertex count is refused before anything is allocated.
  std::string text(bytes.begin(), bytes.end());
  const size_t at = text.find("element vertex 300");
  text.replace(at, 18, "element vertex 4000000000");
  std::string chunk_count = "element chunk " + std::to_string((4000000000ull + 255) / 256);
  text.replace(text.find("element chunk 2"), 15, chunk_count);
  auto huge = ReadPlyGaussiansFromMemory(reinterpret_cast<const uint8_t*>(text.data()), text.size());
  EXPECT_EQ(huge.status().code(), StatusCode::kTruncated);
}

TEST(WebSplatsHostile, SogMetaAndImages) {
  if (!SogAvailable()) GTEST_SKIP() << "this build has no libwebp (SOG)";
  ATEX_REQUIRE_DATA_FILE(meta_path, "splats/playbot_lod6/meta.json");
  // The shared SOG as a bundle, then damaged copies of it.
  auto bundle = [&](const std::function<void(std::string& name, std::vector<uint8_t>& bytes)>& edit) {
    ZipWriter zip;
    for (const auto& entry : fs::directory_iterator(meta_path.parent_path())) {
      if (entry.path().extension() != ".webp" && entry.path().filename() != "meta.json") continue;
      std::string name = entry.path().filename().string();
      std::vector<uint8_t> bytes = *ReadFileBytes(entry.path().string());
      edit(name, bytes);
      EXPECT_TRUE(zip.Add(name, bytes.data(), bytes.size(), false).ok());
    }
    return zip.Finish();
  };
  auto intact = bundle([](std::string&, std::vector<uint8_t>&) {});
  auto g = ReadSogBundleFromMemory(intact.data(), intact.size());
  ASSERT_TRUE(g.ok()) << g.status().ToString();
  EXPECT_EQ(g->size(), 1873u);
  EXPECT_EQ(ReadSogBundleFromMemory(intact.data(), intact.size() / 2).status().code() == StatusCode::kOk, false);
  auto edit_meta = [&](const std::function<void(nlohmann::json&)>& change) {
    return bundle([&](std::string& name, std::vector<uint8_t>& bytes) {
      if (name != "meta.json") return;
      auto meta = nlohmann::json::parse(bytes.begin(), bytes.end());
      change(meta);
      const std::string text = meta.dump();
      bytes.assign(text.begin(), text.end());
    });
  };
  auto huge_count = edit_meta([](nlohmann::json& m) { m["count"] = 100000000; });
  auto r = ReadSogBundleFromMemory(huge_count.data(), huge_count.size());
  EXPECT_EQ(r.status().code(), StatusCode::kCorrupt);  // the images are far too small for that count
  EXPECT_NE(r.status().message().find("means_l.webp"), std::string::npos) << r.status().ToString();
  auto no_version = edit_meta([](nlohmann::json& m) { m.erase("version"); });
  EXPECT_EQ(ReadSogBundleFromMemory(no_version.data(), no_version.size()).status().code(), StatusCode::kUnsupported);
  auto short_book = edit_meta([](nlohmann::json& m) { m["scales"]["codebook"].erase(0); });
  EXPECT_EQ(ReadSogBundleFromMemory(short_book.data(), short_book.size()).status().code(), StatusCode::kCorrupt);
  auto missing = edit_meta([](nlohmann::json& m) { m["quats"]["files"][0] = "nowhere.webp"; });
  EXPECT_EQ(ReadSogBundleFromMemory(missing.data(), missing.size()).status().code(), StatusCode::kNotFound);
  // An image whose header declares 16384 x 16384 pixels: refused before decoding.
  auto giant = bundle([](std::string& name, std::vector<uint8_t>& bytes) {
    if (name != "scales.webp") return;
    const uint8_t vp8l[] = {'R', 'I', 'F', 'F', 26, 0, 0, 0, 'W', 'E', 'B', 'P', 'V', 'P', '8', 'L',
                            14, 0, 0, 0, 0x2f, 0xff, 0xff, 0xff, 0xff, 0x0f, 0, 0, 0, 0, 0, 0, 0, 0};
    bytes.assign(std::begin(vp8l), std::end(vp8l));
  });
  auto refused = ReadSogBundleFromMemory(giant.data(), giant.size());
  EXPECT_FALSE(refused.ok());
  EXPECT_NE(refused.status().message().find("scales.webp"), std::string::npos) << refused.status().ToString();
  auto not_webp = bundle([](std::string& name, std::vector<uint8_t>& bytes) {
    if (name == "sh0.webp") bytes.resize(10);
  });
  EXPECT_EQ(ReadSogBundleFromMemory(not_webp.data(), not_webp.size()).status().code(), StatusCode::kCorrupt);
}

TEST(WebSplatsConvert, FormatsByNameAndRefusedAsOutput) {
  EXPECT_EQ(FileFormatFromPath("a.splat"), FileFormat::kSplat);
  EXPECT_EQ(FileFormatFromPath("a.KSPLAT"), FileFormat::kKsplat);
  EXPECT_EQ(FileFormatFromPath("a.sog"), FileFormat::kSog);
  EXPECT_EQ(FileFormatFromPath("dir/meta.json"), FileFormat::kSog);
  EXPECT_EQ(FileFormatFromPath("a.compressed.ply"), FileFormat::kPly);
  testing::TempDir dir;
  const auto bytes = SplatRows(2);
  ASSERT_TRUE(WriteFileAtomic((dir / "in.splat").string(), bytes).ok());
  auto report = ConvertFile((dir / "in.splat").string(), (dir / "out.ply").string());
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_EQ(report->gaussians, 2u);
  EXPECT_EQ(ConvertFile((dir / "out.ply").string(), (dir / "out.splat").string()).status().code(),
            StatusCode::kUnsupported);
}

}  // namespace
}  // namespace atex
