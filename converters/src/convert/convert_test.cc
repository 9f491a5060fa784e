#include "atex/converters/convert.h"

#include <gtest/gtest.h>

#include <bit>
#include <cstdlib>
#include <fstream>

#include "atex/container.h"
#include "atex/converters/drc.h"
#include "atex/converters/exr_atlas.h"
#include "atex/converters/ply.h"
#include "atex/converters/spz.h"
#include "atex/converters/texture_bake.h"
#include "atex/deform.h"
#include "atex/file_io.h"
#include "convert/test_gaussians.h"
#include "core/test_support.h"

namespace atex {
namespace {

using converters::testing::RandomGaussians;
namespace fs = std::filesystem;

// Whether this build has OpenEXR / Draco (the converters report kUnsupportedCodec otherwise).
bool HaveExr() {
  TexturePool empty;
  empty.RebuildOffsets();
  return EncodeExrAtlas(empty).status().code() != StatusCode::kUnsupportedCodec;
}
bool HaveDraco() {
  return EncodeDracoPointCloud(RandomGaussians(1, 0, 1)).status().code() != StatusCode::kUnsupportedCodec;
}

void ExpectBitEqual(const std::vector<float>& a, const std::vector<float>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) ASSERT_EQ(std::bit_cast<uint32_t>(a[i]), std::bit_cast<uint32_t>(b[i])) << i;
}

TEST(ConvertFormats, Names) {
  EXPECT_EQ(FileFormatFromPath("a/b/scene.PLY"), FileFormat::kPly);
  EXPECT_EQ(FileFormatFromPath("x.spz"), FileFormat::kSpz);
  EXPECT_EQ(FileFormatFromPath("x.atex"), FileFormat::kAtex);
  EXPECT_EQ(FileFormatFromPath("x.exr"), FileFormat::kExrAtlas);
  EXPECT_EQ(FileFormatFromPath("x.drc"), FileFormat::kDraco);
  EXPECT_EQ(FileFormatFromPath("x.glb"), FileFormat::kUnknown);
  EXPECT_EQ(FileFormatFromPath("noext"), FileFormat::kUnknown);
  EXPECT_EQ(*ParseFileFormat("SPZ"), FileFormat::kSpz);
  EXPECT_FALSE(ParseFileFormat("obj").ok());
}

TEST(Convert, PlySpzPlyKeepsCountAndQuantisation) {
  testing::TempDir dir;
  const Gaussians g = RandomGaussians(300, 2, 4);
  const std::string ply = (dir / "in.ply").string(), spz = (dir / "mid.spz").string(),
                    back = (dir / "out.ply").string();
  ASSERT_TRUE(WritePlyGaussians(ply, g).ok());
  auto r1 = ConvertFile(ply, spz);
  ASSERT_TRUE(r1.ok()) << r1.status().ToString();
  EXPECT_EQ(r1->from, FileFormat::kPly);
  EXPECT_EQ(r1->to, FileFormat::kSpz);
  EXPECT_EQ(r1->gaussians, 300u);
  EXPECT_EQ(r1->sh_degree, 2);
  EXPECT_EQ(r1->output_bytes, fs::file_size(spz));
  EXPECT_EQ(r1->input_bytes, fs::file_size(ply));
  EXPECT_LT(r1->output_bytes, r1->input_bytes / 3);
  auto r2 = ConvertFile(spz, back);
  ASSERT_TRUE(r2.ok()) << r2.status().ToString();
  auto out = ReadPlyGaussians(back);
  ASSERT_TRUE(out.ok());
  ASSERT_EQ(out->size(), g.size());
  for (size_t i = 0; i < g.positions.size(); ++i) ASSERT_NEAR(out->positions[i], g.positions[i], 1.0 / 8192 + 1e-6);

  ConvertOptions v3;
  v3.spz_version = 3;
  ASSERT_TRUE(ConvertFile(ply, (dir / "v3.spz").string(), v3).ok());
  SpzInfo info;
  ASSERT_TRUE(ReadSpzGaussians((dir / "v3.spz").string(), {}, &info).ok());
  EXPECT_EQ(info.version, 3);
}

TEST(Convert, AtexRoundTripsThroughPlyBitExactly) {
  testing::TempDir dir;
  const Gaussians g = RandomGaussians(100, 3, 5);
  const std::string ply = (dir / "in.ply").string(), atex = (dir / "s.atex").string(),
                    back = (dir / "out.ply").string();
  ASSERT_TRUE(WritePlyGaussians(ply, g).ok());
  auto r1 = ConvertFile(ply, atex);
  ASSERT_TRUE(r1.ok()) << r1.status().ToString();
  auto asset = ReadAssetFile(atex);
  ASSERT_TRUE(asset.ok()) << asset.status().ToString();
  EXPECT_EQ(asset->metadata.axes, "opencv");
  EXPECT_EQ(asset->metadata.extra["source"]["format"], "ply");
  auto r2 = ConvertFile(atex, back);
  ASSERT_TRUE(r2.ok()) << r2.status().ToString();
  auto out = ReadPlyGaussians(back);
  ASSERT_TRUE(out.ok());
  ExpectBitEqual(out->positions, g.positions);
  ExpectBitEqual(out->rotations, g.rotations);
  ExpectBitEqual(out->sh, g.sh);
}

TEST(Convert, TextureAtlasOutAndBackIn) {
  if (!HaveExr()) GTEST_SKIP() << "built without OpenEXR";
  testing::TempDir dir;
  Asset asset;
  asset.gaussians = RandomGaussians(40, 0, 6);
  TexturePool pool;
  for (size_t i = 0; i < 40; ++i) {
    pool.heights.push_back(i % 3 == 0 ? 2 : 1);
    pool.widths.push_back(i % 5 == 0 ? 4 : 1);
    pool.axis_u.push_back(0);
    pool.axis_v.push_back(2);
  }
  pool.RebuildOffsets();
  for (uint64_t t = 0; t < pool.texel_count() * 4; ++t) pool.texels.push_back(static_cast<float>(t % 37) / 8.0f - 2);
  asset.textures = pool;
  asset.metadata.texture_mode = "adaptive";
  const std::string atex = (dir / "t.atex").string(), exr = (dir / "t.exr").string(),
                    plain = (dir / "plain.atex").string(), merged = (dir / "merged.atex").string();
  ASSERT_TRUE(WriteAssetFile(atex, asset).ok());
  auto r = ConvertFile(atex, exr);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->outputs.size(), 2u);  // atlas + sidecar

  // The same Gaussians without textures, then the atlas put back on them.
  Asset bare = asset;
  bare.textures.reset();
  bare.metadata.texture_mode = "none";
  ASSERT_TRUE(WriteAssetFile(plain, bare).ok());
  ConvertOptions options;
  options.base_asset = plain;
  auto r2 = ConvertFile(exr, merged, options);
  ASSERT_TRUE(r2.ok()) << r2.status().ToString();
  auto back = ReadAssetFile(merged);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  ASSERT_TRUE(back->textures.has_value());
  EXPECT_EQ(back->textures->heights, pool.heights);
  EXPECT_EQ(back->textures->axis_v, pool.axis_v);
  ExpectBitEqual(back->textures->texels, pool.texels);
  EXPECT_EQ(back->metadata.texture_mode, "adaptive");

  // Writing a textured asset to .ply drops (and reports) the textures.
  auto r3 = ConvertFile(atex, (dir / "t.ply").string());
  ASSERT_TRUE(r3.ok());
  ASSERT_EQ(r3->dropped.size(), 1u);
  EXPECT_EQ(r3->dropped[0], "textures");
}

// --bake-textures to .ply: the textured Gaussians are baked (texture_bake.h), not dropped, and
// the file holds the baked count; with --frames the option is refused.
TEST(Convert, BakeTexturesToPly) {
  testing::TempDir dir;
  Asset asset;
  asset.gaussians = RandomGaussians(30, 0, 7);
  TexturePool pool;
  for (size_t i = 0; i < 30; ++i) {
    pool.heights.push_back(i % 2 == 0 ? 2 : 1);
    pool.widths.push_back(i % 2 == 0 ? 2 : 1);
    pool.axis_u.push_back(0);
    pool.axis_v.push_back(1);
  }
  pool.RebuildOffsets();
  for (uint64_t t = 0; t < pool.texel_count() * 4; ++t) pool.texels.push_back((t / 4) % 2 == 0 ? 3.0f : -3.0f);
  asset.textures = pool;
  asset.metadata.texture_mode = "adaptive";
  const std::string atex = (dir / "t.atex").string(), ply = (dir / "t.ply").string();
  ASSERT_TRUE(WriteAssetFile(atex, asset).ok());
  ConvertOptions options;
  options.bake_textures = true;
  auto r = ConvertFile(atex, ply, options);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_TRUE(r->dropped.empty());
  EXPECT_TRUE(r->warnings.empty());
  auto read = ReadAssetFile(atex);
  ASSERT_TRUE(read.ok());
  auto baked = BakeTextures(read->gaussians, *read->textures);
  ASSERT_TRUE(baked.ok());
  EXPECT_GT(baked->size(), 30u);  // some 2x2 textures split
  auto back = ReadPlyGaussians(ply);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->size(), baked->size());
  options.frames = FrameRange{0, 1, 0.5};
  EXPECT_EQ(ConvertFile(atex, (dir / "frames").string(), options).status().code(), StatusCode::kInvalidArgument);
}

TEST(Convert, DracoOutput) {
  if (!HaveDraco()) GTEST_SKIP() << "built without Draco";
  testing::TempDir dir;
  const Gaussians g = RandomGaussians(500, 1, 7);
  const std::string ply = (dir / "in.ply").string(), drc = (dir / "out.drc").string();
  ASSERT_TRUE(WritePlyGaussians(ply, g).ok());
  ConvertOptions options;
  options.draco_bits = 12;
  options.draco_attributes = true;
  auto r = ConvertFile(ply, drc, options);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  auto bytes = ReadFileBytes(drc);
  ASSERT_TRUE(bytes.ok());
  auto pc = DecodeDracoPointCloud(bytes->data(), bytes->size());
  ASSERT_TRUE(pc.ok()) << pc.status().ToString();
  EXPECT_EQ(pc->size(), 500u);
  EXPECT_EQ(pc->rotations.size(), 2000u);
  EXPECT_EQ(pc->colors.size(), 1500u);
}

TEST(Convert, TimeDeformsDynamicAssets) {
  testing::TempDir dir;
  Asset asset;
  asset.gaussians = RandomGaussians(64, 0, 8, 0.9f);
  DeformationConfig config;
  config.grid.channels = 4;
  config.grid.base_resolution = {8, 8, 8, 5};
  config.mlp_width = 16;
  auto field = InitDeformationField(config, 3);
  ASSERT_TRUE(field.ok()) << field.status().ToString();
  // Make the position head's output visible: scale its last layer up.
  for (float& w : field->heads[kHeadPosition][1].weight) w *= 100.0f;
  asset.deformation = *field;
  const std::string atex = (dir / "d.atex").string(), ply = (dir / "t.ply").string();
  ASSERT_TRUE(WriteAssetFile(atex, asset).ok());
  ConvertOptions options;
  options.time = 0.5;
  auto r = ConvertFile(atex, ply, options);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->dropped.size(), 1u);
  EXPECT_EQ(r->dropped[0], "deformation");
  Gaussians expected;
  ASSERT_TRUE(DeformForward(*field, asset.gaussians, 0.5, &expected, static_cast<DeformCache*>(nullptr)).ok());
  auto out = ReadPlyGaussians(ply);
  ASSERT_TRUE(out.ok());
  ExpectBitEqual(out->positions, expected.positions);
  double moved = 0;
  for (size_t i = 0; i < expected.positions.size(); ++i)
    moved += std::fabs(expected.positions[i] - asset.gaussians.positions[i]);
  EXPECT_GT(moved, 0.0);  // the test would be vacuous if the field were the identity

  // A static asset ignores --time with a note.
  const std::string ply_in = (dir / "s.ply").string();
  ASSERT_TRUE(WritePlyGaussians(ply_in, asset.gaussians).ok());
  auto r2 = ConvertFile(ply_in, (dir / "s.spz").string(), options);
  ASSERT_TRUE(r2.ok());
  ASSERT_EQ(r2->notes.size(), 1u);
}

TEST(Convert, ErrorsAreClear) {
  testing::TempDir dir;
  const std::string ply = (dir / "in.ply").string();
  ASSERT_TRUE(WritePlyGaussians(ply, RandomGaussians(5, 0, 1)).ok());
  EXPECT_EQ(ConvertFile(ply, (dir / "out.obj").string()).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(ConvertFile((dir / "absent.ply").string(), (dir / "b.spz").string()).status().code(),
            StatusCode::kNotFound);
  {
    std::ofstream(dir / "x.drc") << "DRACO";
    EXPECT_EQ(ConvertFile((dir / "x.drc").string(), (dir / "b.ply").string()).status().code(),
              StatusCode::kUnsupported);
  }
  EXPECT_EQ(ConvertFile(ply, (dir / "t.exr").string()).status().code(), StatusCode::kInvalidArgument);  // no textures
  EXPECT_EQ(ConvertFile((dir / "t.exr").string(), (dir / "o.atex").string()).status().code(),
            StatusCode::kInvalidArgument);  // no --base
  ConvertOptions frames;  // per-frame export writes .ply or .spz only (frames_test.cc has the rest)
  frames.frames = FrameRange{0, 1, 0.5};
  frames.to = FileFormat::kDraco;
  EXPECT_EQ(ConvertFile(ply, (dir / "frames").string(), frames).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(ConvertFile(ply, ply).status().code(), StatusCode::kInvalidArgument);
  ConvertOptions cancel;
  cancel.progress = [](std::string_view stage, double) { return stage != "write"; };
  EXPECT_EQ(ConvertFile(ply, (dir / "c.spz").string(), cancel).status().code(), StatusCode::kCancelled);
  EXPECT_FALSE(fs::exists(dir / "c.spz"));
  ConvertOptions named;
  named.to = FileFormat::kSpz;
  EXPECT_TRUE(ConvertFile(ply, (dir / "named.bin").string(), named).ok());
}

TEST(ConvertCli, JsonSummary) {
  const char* bin = std::getenv("ATEX_BINARY_DIR");
  ASSERT_NE(bin, nullptr);
  const fs::path atex_bin = fs::path(bin) / "bin" / "atex";
  ASSERT_TRUE(fs::exists(atex_bin)) << atex_bin;
  testing::TempDir dir;
  const std::string ply = (dir / "in.ply").string();
  ASSERT_TRUE(WritePlyGaussians(ply, RandomGaussians(50, 1, 2)).ok());
  const std::string json_path = (dir / "out.json").string();
  const std::string command = atex_bin.string() + " convert " + ply + " " + (dir / "o.spz").string() +
                              " --spz-version 3 --json > " + json_path;
  ASSERT_EQ(std::system(command.c_str()), 0) << command;
  std::ifstream in(json_path);
  const auto json = nlohmann::json::parse(in);
  EXPECT_EQ(json["gaussians"], 50);
  EXPECT_EQ(json["from"], "ply");
  EXPECT_EQ(json["to"], "spz");
  EXPECT_GT(json["output_bytes"].get<int>(), 0);
  // A failure exits non-zero.
  const std::string bad = atex_bin.string() + " convert " + ply + " " + (dir / "o.xyz").string() + " 2> /dev/null";
  EXPECT_NE(std::system(bad.c_str()), 0);
}

}  // namespace
}  // namespace atex
