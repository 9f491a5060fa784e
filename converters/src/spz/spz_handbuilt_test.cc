// SPZ reading of hand-built files: legacy versions 1 and 2 (gzip), version 4 with extensions,
// and hostile headers and streams. The writer's round trips and real files are in spz_test.cc.
#include <gtest/gtest.h>
#include <zlib.h>
#include <zstd.h>

#include <cmath>
#include <cstring>
#include <random>

#include "atex/converters/spz.h"
#include "convert/bytes.h"
#include "convert/test_gaussians.h"
#include "spz/spz_container.h"
#include "spz/spz_packed.h"

namespace atex {
namespace {

using converters::bytes::AppendLE;
using converters::testing::RandomGaussians;

float Sigmoid(float x) { return 1.0f / (1.0f + std::exp(-x)); }

std::vector<uint8_t> Gzip(const std::vector<uint8_t>& raw) {
  z_stream s{};
  deflateInit2(&s, 6, Z_DEFLATED, 16 + MAX_WBITS, 8, Z_DEFAULT_STRATEGY);
  std::vector<uint8_t> out(deflateBound(&s, raw.size()) + 32);
  s.next_in = const_cast<Bytef*>(raw.data());
  s.avail_in = static_cast<uInt>(raw.size());
  s.next_out = out.data();
  s.avail_out = static_cast<uInt>(out.size());
  deflate(&s, Z_FINISH);
  out.resize(s.total_out);
  deflateEnd(&s);
  return out;
}

std::vector<uint8_t> LegacyHeader(uint32_t version, uint32_t n, uint8_t degree, uint8_t fractional_bits) {
  std::vector<uint8_t> raw;
  AppendLE<uint32_t>(raw, 0x5053474e);
  AppendLE<uint32_t>(raw, version);
  AppendLE<uint32_t>(raw, n);
  raw.push_back(degree);
  raw.push_back(fractional_bits);
  raw.push_back(0);
  raw.push_back(0);
  return raw;
}

TEST(SpzLegacy, ReadsHandMadeVersion2And1) {
  // Two Gaussians written by hand following the v2 layout: positions (24-bit, 8
  // fractional bits), alphas, colours, scales, rotations as x, y, z bytes.
  std::vector<uint8_t> raw = LegacyHeader(2, 2, 0, 8);
  const int32_t fixed[6] = {256, -512, 128, 0, 1, -1};  // 1, -2, 0.5 | 0, 1/256, -1/256
  for (int32_t f : fixed) {
    raw.push_back(f & 0xff);
    raw.push_back((f >> 8) & 0xff);
    raw.push_back((f >> 16) & 0xff);
  }
  raw.push_back(255);  // alpha: clamped to 254/255 on decode
  raw.push_back(51);   // alpha 0.2
  for (int k = 0; k < 6; ++k) raw.push_back(128);           // colours
  for (int k = 0; k < 6; ++k) raw.push_back(160 - 16 * k);  // scales: ln s = 0, -1, ...
  raw.push_back(128);  // rotation 0: x = 0.5/127.5 ~ 0, so close to identity
  raw.push_back(127);
  raw.push_back(127);
  raw.push_back(255);  // rotation 1: x = 1 -> 180 degrees about x
  raw.push_back(127);
  raw.push_back(127);
  const auto file = Gzip(raw);
  SpzReadOptions stored;
  stored.axes = SpzAxes::kStored;
  SpzInfo info;
  auto g = DecodeSpz(file.data(), file.size(), stored, &info);
  ASSERT_TRUE(g.ok()) << g.status().ToString();
  EXPECT_EQ(info.version, 2);
  ASSERT_EQ(g->size(), 2u);
  const float expected_pos[6] = {1, -2, 0.5f, 0, 1.0f / 256, -1.0f / 256};
  for (int k = 0; k < 6; ++k) EXPECT_FLOAT_EQ(g->positions[k], expected_pos[k]);
  EXPECT_NEAR(Sigmoid(g->opacity_logits[0]), 254.0f / 255, 1e-6);
  EXPECT_NEAR(Sigmoid(g->opacity_logits[1]), 0.2f, 1e-6);
  for (int k = 0; k < 6; ++k) EXPECT_FLOAT_EQ(g->log_scales[k], 0.0f - k);
  EXPECT_NEAR(g->rotations[0], 1.0f, 1e-3);  // w
  EXPECT_NEAR(g->rotations[4], 0.0f, 1e-6);  // w of a 180 degree turn
  EXPECT_NEAR(g->rotations[5], 1.0f, 1e-6);  // x
  EXPECT_NEAR(g->sh[0], (128 / 255.0f - 0.5f) / 0.15f, 1e-6);

  // Version 1: positions as halves (1.0 = 0x3c00, -2.0 = 0xc000, 0.5 = 0x3800).
  std::vector<uint8_t> v1 = LegacyHeader(1, 1, 0, 0);
  for (uint16_t h : {0x3c00, 0xc000, 0x3800}) AppendLE<uint16_t>(v1, h);
  v1.push_back(128);
  for (int k = 0; k < 3; ++k) v1.push_back(128);
  for (int k = 0; k < 3; ++k) v1.push_back(160);
  for (int k = 0; k < 3; ++k) v1.push_back(127);
  const auto file1 = Gzip(v1);
  auto g1 = DecodeSpz(file1.data(), file1.size(), stored);
  ASSERT_TRUE(g1.ok()) << g1.status().ToString();
  EXPECT_FLOAT_EQ(g1->positions[0], 1.0f);
  EXPECT_FLOAT_EQ(g1->positions[1], -2.0f);
  EXPECT_FLOAT_EQ(g1->positions[2], 0.5f);
}

TEST(SpzLegacy, HostilePayloads) {
  // Header announcing more Gaussians than the payload holds.
  std::vector<uint8_t> raw = LegacyHeader(3, 1000000, 3, 12);
  raw.resize(raw.size() + 500, 7);
  auto file = Gzip(raw);
  auto g = DecodeSpz(file.data(), file.size());
  ASSERT_FALSE(g.ok());
  EXPECT_EQ(g.status().code(), StatusCode::kTruncated) << g.status().ToString();

  struct Case {
    std::vector<uint8_t> raw;
    StatusCode code;
  };
  std::vector<Case> cases = {
      {LegacyHeader(4, 1, 0, 12), StatusCode::kUnsupportedVersion},
      {LegacyHeader(0, 1, 0, 12), StatusCode::kCorrupt},
      {LegacyHeader(3, 1, 7, 12), StatusCode::kOutOfRange},
      {LegacyHeader(3, 1, 0, 40), StatusCode::kOutOfRange},
      {std::vector<uint8_t>(10, 0), StatusCode::kTruncated},
  };
  cases[4].raw[0] = 'N';
  for (const auto& c : cases) {
    auto f = Gzip(c.raw);
    auto result = DecodeSpz(f.data(), f.size());
    ASSERT_FALSE(result.ok());
    EXPECT_EQ(result.status().code(), c.code) << result.status().ToString();
  }

  // Decompression cap.
  std::vector<uint8_t> big = LegacyHeader(3, 100000, 0, 12);
  big.resize(big.size() + 100000 * 20, 0);
  auto bomb = Gzip(big);
  SpzReadOptions small;
  small.max_decompressed_bytes = 1 << 20;
  auto capped = DecodeSpz(bomb.data(), bomb.size(), small);
  ASSERT_FALSE(capped.ok());
  EXPECT_EQ(capped.status().code(), StatusCode::kLimitExceeded);

  // Trailing garbage after the gzip member, and a corrupted deflate stream.
  auto good = EncodeSpz(RandomGaussians(5, 0, 1), SpzWriteOptions{.version = 3});
  ASSERT_TRUE(good.ok());
  auto trailing = *good;
  trailing.push_back(0);
  EXPECT_EQ(DecodeSpz(trailing.data(), trailing.size()).status().code(), StatusCode::kCorrupt);
  auto corrupt = *good;
  corrupt[corrupt.size() / 2] ^= 0x5a;
  EXPECT_FALSE(DecodeSpz(corrupt.data(), corrupt.size()).ok());
}

// A v4 file assembled from raw parts.
struct NgspParts {
  uint32_t version = 4;
  uint32_t n = 1;
  uint8_t degree = 0, fractional_bits = 12, flags = 0;
  std::vector<uint8_t> extensions;
  std::vector<std::vector<uint8_t>> streams;  // uncompressed
  int declared_streams = -1;                  // -1: streams.size()
};

std::vector<uint8_t> BuildNgsp(const NgspParts& p) {
  std::vector<uint8_t> out;
  AppendLE<uint32_t>(out, 0x5053474e);
  AppendLE<uint32_t>(out, p.version);
  AppendLE<uint32_t>(out, p.n);
  out.push_back(p.degree);
  out.push_back(p.fractional_bits);
  out.push_back(p.flags);
  out.push_back(static_cast<uint8_t>(p.declared_streams < 0 ? p.streams.size() : p.declared_streams));
  AppendLE<uint32_t>(out, static_cast<uint32_t>(32 + p.extensions.size()));
  out.resize(32, 0);
  out.insert(out.end(), p.extensions.begin(), p.extensions.end());
  std::vector<std::vector<uint8_t>> compressed;
  for (const auto& s : p.streams) {
    std::vector<uint8_t> c(ZSTD_compressBound(s.size()));
    c.resize(ZSTD_compress(c.data(), c.size(), s.data(), s.size(), 3));
    AppendLE<uint64_t>(out, c.size());
    AppendLE<uint64_t>(out, s.size());
    compressed.push_back(std::move(c));
  }
  for (const auto& c : compressed) out.insert(out.end(), c.begin(), c.end());
  return out;
}

NgspParts OneGaussian() {
  NgspParts p;
  p.streams = {std::vector<uint8_t>{0, 16, 0, 0, 0, 0, 0, 0, 0},  // x = 1
               {128},
               {128, 128, 128},
               {160, 160, 160},
               {0, 0, 0, 0}};
  return p;
}

std::vector<uint8_t> Extension(uint32_t type, std::vector<uint8_t> payload) {
  std::vector<uint8_t> out;
  AppendLE<uint32_t>(out, type);
  AppendLE<uint32_t>(out, static_cast<uint32_t>(payload.size()));
  out.insert(out.end(), payload.begin(), payload.end());
  return out;
}

TEST(SpzV4, HandBuiltFileAndExtensions) {
  auto base = BuildNgsp(OneGaussian());
  auto g = DecodeSpz(base.data(), base.size());
  ASSERT_TRUE(g.ok()) << g.status().ToString();
  EXPECT_FLOAT_EQ(g->positions[0], 1.0f);

  // An unknown extension is skipped; the coordinate-system one changes the conversion.
  NgspParts p = OneGaussian();
  p.flags = 0x2;
  p.extensions = Extension(0x12340001, {1, 2, 3});
  auto e = Extension(0xADBE0003, {6, 0, 0, 0});  // RDF: already libatex's axes
  p.extensions.insert(p.extensions.end(), e.begin(), e.end());
  p.streams[0] = {0, 16, 0, 0, 16, 0, 0, 16, 0};  // (1, 1, 1)
  auto file = BuildNgsp(p);
  SpzInfo info;
  auto rdf = DecodeSpz(file.data(), file.size(), {}, &info);
  ASSERT_TRUE(rdf.ok()) << rdf.status().ToString();
  EXPECT_EQ(info.extension_records, 2);
  EXPECT_EQ(info.stored_axes, "RDF");
  EXPECT_FLOAT_EQ(rdf->positions[1], 1.0f);  // not flipped
  EXPECT_FLOAT_EQ(rdf->positions[2], 1.0f);

  p.extensions = Extension(0xADBE0003, {10, 0, 0, 0});  // RFD: a rotated system
  file = BuildNgsp(p);
  auto rotated = DecodeSpz(file.data(), file.size());
  ASSERT_FALSE(rotated.ok());
  EXPECT_EQ(rotated.status().code(), StatusCode::kUnsupported);
  SpzReadOptions stored;
  stored.axes = SpzAxes::kStored;
  EXPECT_TRUE(DecodeSpz(file.data(), file.size(), stored).ok());

  p.extensions = Extension(0x12340001, {1, 2, 3});
  p.extensions.resize(p.extensions.size() - 1);  // payload shorter than announced
  file = BuildNgsp(p);
  EXPECT_EQ(DecodeSpz(file.data(), file.size()).status().code(), StatusCode::kCorrupt);
}

TEST(SpzV4, HostileHeadersAndStreams) {
  struct Case {
    const char* what;
    NgspParts parts;
    StatusCode code;
  };
  std::vector<Case> cases;
  auto add = [&](const char* what, auto mutate, StatusCode code) {
    NgspParts p = OneGaussian();
    mutate(p);
    cases.push_back({what, p, code});
  };
  add("version 5", [](NgspParts& p) { p.version = 5; }, StatusCode::kUnsupportedVersion);
  add("version 3 in NGSP", [](NgspParts& p) { p.version = 3; }, StatusCode::kCorrupt);
  add("SH degree 9", [](NgspParts& p) { p.degree = 9; }, StatusCode::kOutOfRange);
  add("fractional bits 99", [](NgspParts& p) { p.fractional_bits = 99; }, StatusCode::kOutOfRange);
  add("forged count", [](NgspParts& p) { p.n = 0xffffffffu; }, StatusCode::kLimitExceeded);
  add("count vs stream sizes", [](NgspParts& p) { p.n = 1000; }, StatusCode::kCorrupt);
  add("missing SH stream", [](NgspParts& p) { p.degree = 1; }, StatusCode::kCorrupt);
  add("stream count", [](NgspParts& p) { p.declared_streams = 6; }, StatusCode::kCorrupt);
  add("short rotation stream", [](NgspParts& p) { p.streams[4].pop_back(); }, StatusCode::kCorrupt);
  for (const auto& c : cases) {
    auto file = BuildNgsp(c.parts);
    auto g = DecodeSpz(file.data(), file.size());
    ASSERT_FALSE(g.ok()) << c.what;
    EXPECT_EQ(g.status().code(), c.code) << c.what << ": " << g.status().ToString();
  }

  auto base = BuildNgsp(OneGaussian());
  auto reserved = base;
  reserved[25] = 1;
  EXPECT_EQ(DecodeSpz(reserved.data(), reserved.size()).status().code(), StatusCode::kCorrupt);
  auto toc = base;
  toc[18] = 1;  // table of contents 64 KiB beyond the file
  EXPECT_EQ(DecodeSpz(toc.data(), toc.size()).status().code(), StatusCode::kCorrupt);
  auto trailing = base;
  trailing.push_back(0);
  EXPECT_EQ(DecodeSpz(trailing.data(), trailing.size()).status().code(), StatusCode::kCorrupt);
  auto magic = base;
  magic[0] = 'X';
  EXPECT_EQ(DecodeSpz(magic.data(), magic.size()).status().code(), StatusCode::kBadMagic);

  // The TOC declares 9 position bytes but the zstd frame holds 4096: refused
  // without inflating more than announced.
  NgspParts bomb = OneGaussian();
  bomb.streams[0].assign(4096, 0);
  auto bomb_file = BuildNgsp(bomb);
  const size_t toc_entry = 32;
  converters::bytes::StoreLE<uint64_t>(&bomb_file[toc_entry + 8], 9);
  auto result = DecodeSpz(bomb_file.data(), bomb_file.size());
  ASSERT_FALSE(result.ok());
  EXPECT_EQ(result.status().code(), StatusCode::kCorrupt) << result.status().ToString();

  SpzReadOptions small;
  small.max_decompressed_bytes = 10;
  EXPECT_EQ(DecodeSpz(base.data(), base.size(), small).status().code(), StatusCode::kLimitExceeded);

  // Every truncation of a real encoder output fails cleanly.
  auto good = EncodeSpz(RandomGaussians(4, 2, 6));
  ASSERT_TRUE(good.ok());
  for (size_t cut = 0; cut < good->size(); ++cut) ASSERT_FALSE(DecodeSpz(good->data(), cut).ok()) << cut;
}

TEST(SpzV4, DegreeFourIsTruncatedToThree) {
  converters::spz::PackedSpz packed;
  packed.version = 4;
  packed.num_points = 2;
  packed.sh_degree = 4;
  packed.positions.assign(18, 0);
  packed.alphas.assign(2, 200);
  packed.colors.assign(6, 100);
  packed.scales.assign(6, 100);
  packed.rotations.assign(8, 0);
  packed.sh.resize(2 * 24 * 3);
  for (size_t i = 0; i < packed.sh.size(); ++i) packed.sh[i] = static_cast<uint8_t>(i);
  auto bytes = converters::spz::SerializeSpz(packed, {});
  ASSERT_TRUE(bytes.ok());
  SpzInfo info;
  SpzReadOptions stored;
  stored.axes = SpzAxes::kStored;
  auto g = DecodeSpz(bytes->data(), bytes->size(), stored, &info);
  ASSERT_TRUE(g.ok()) << g.status().ToString();
  EXPECT_EQ(info.sh_degree, 4);
  EXPECT_TRUE(info.sh_truncated);
  EXPECT_EQ(g->sh_degree, 3);
  // Gaussian 1, coefficient 15 (the last of degree 3), channel 2 = stored byte 24*3 + 14*3 + 2.
  EXPECT_FLOAT_EQ(g->sh[(1 * 16 + 15) * 3 + 2], (static_cast<uint8_t>(72 + 44) - 128.0f) / 128.0f);
}

TEST(SpzV4, RandomCorruptionNeverCrashes) {
  auto good = EncodeSpz(RandomGaussians(30, 1, 12));
  auto good3 = EncodeSpz(RandomGaussians(30, 1, 12), SpzWriteOptions{.version = 3});
  ASSERT_TRUE(good.ok() && good3.ok());
  std::mt19937 rng(99);
  for (const auto* file : {&*good, &*good3}) {
    for (int trial = 0; trial < 600; ++trial) {
      auto copy = *file;
      const int flips = 1 + trial % 4;
      for (int f = 0; f < flips; ++f) copy[rng() % copy.size()] ^= static_cast<uint8_t>(1 + rng() % 255);
      auto result = DecodeSpz(copy.data(), copy.size());
      if (result.ok()) {
        for (float v : result->positions) ASSERT_TRUE(std::isfinite(v));
        for (float v : result->rotations) ASSERT_TRUE(std::isfinite(v));
        for (float v : result->opacity_logits) ASSERT_TRUE(std::isfinite(v));
      }
    }
  }
}

}  // namespace
}  // namespace atex
