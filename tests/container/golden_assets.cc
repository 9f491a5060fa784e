#include "golden_assets.h"

#include "container/synthetic_asset.h"

namespace atex::golden {

Asset GoldenAsset() {
  container::SyntheticAssetOptions o;
  o.seed = 20261121;
  o.gaussians = 24;
  o.sh_degree = 2;
  o.textures = container::SyntheticTextures::kMixed;
  o.deformation = true;
  o.sh_head = true;
  o.stats = true;
  Asset asset = container::MakeSyntheticAsset(o);
  asset.metadata.extra["purpose"] = "golden file of format_spec/atex.md v1.0";
  return asset;
}

WriteOptions GoldenOptions(Codec codec) {
  WriteOptions w;
  w.codec = codec;
  w.zstd_level = 3;
  w.fallback_to_raw = false;  // every codec appears even where it does not pay
  w.positions = ScalarEncoding::kFloat32;
  w.rotations = ScalarEncoding::kFloat16;
  w.log_scales = ScalarEncoding::kQuant16;
  w.opacities = ScalarEncoding::kQuant8;
  w.sh_dc = ScalarEncoding::kFloat16;
  w.sh_rest = ScalarEncoding::kQuant8;
  w.texels = ScalarEncoding::kQuant8;
  w.deformation_grids = ScalarEncoding::kQuant16;
  return w;
}

Asset SpecExampleAsset() {
  Asset asset;
  Gaussians& g = asset.gaussians;
  g.sh_degree = 0;
  g.positions = {1.0f, 2.0f, 3.0f};
  g.rotations = {1.0f, 0.0f, 0.0f, 0.0f};
  g.log_scales = {-1.0f, -2.0f, -3.0f};
  g.opacity_logits = {0.5f};
  g.sh = {0.25f, -0.5f, 1.0f};
  return asset;
}

WriteOptions SpecExampleOptions() {
  WriteOptions w;
  w.codec = Codec::kRaw;
  return w;
}

Asset SampleAsset() {
  container::SyntheticAssetOptions o;
  o.seed = 7;
  o.gaussians = 2000;
  o.sh_degree = 1;
  o.textures = container::SyntheticTextures::kMixed;
  o.deformation = true;
  o.stats = true;
  Asset asset = container::MakeSyntheticAsset(o);
  asset.metadata.extra["purpose"] = "demo sample: synthetic Gaussians in 16 clusters (not a trained scene)";
  return asset;
}

WriteOptions SampleOptions() {
  WriteOptions w;
  w.codec = Codec::kDeltaShuffleZstd;
  w.zstd_level = 9;
  w.rotations = ScalarEncoding::kFloat16;
  w.log_scales = ScalarEncoding::kFloat16;
  w.opacities = ScalarEncoding::kFloat16;
  w.sh_dc = ScalarEncoding::kFloat16;
  w.sh_rest = ScalarEncoding::kFloat16;
  w.texels = ScalarEncoding::kQuant8;
  w.deformation_grids = ScalarEncoding::kFloat16;
  return w;
}

std::vector<std::pair<std::string, std::vector<uint8_t>>> FuzzSeeds() {
  std::vector<std::pair<std::string, std::vector<uint8_t>>> seeds;
  auto add = [&](const std::string& name, const Asset& asset, const WriteOptions& options) {
    auto bytes = EncodeAsset(asset, options);
    if (bytes.ok()) seeds.emplace_back(name, std::move(bytes).value());
  };
  add("spec_example.atex", SpecExampleAsset(), SpecExampleOptions());
  add("golden_raw.atex", GoldenAsset(), GoldenOptions(Codec::kRaw));
  add("golden_zstd.atex", GoldenAsset(), GoldenOptions(Codec::kDeltaShuffleZstd));
  container::SyntheticAssetOptions o;
  o.seed = 3;
  o.gaussians = 0;
  o.sh_degree = 3;
  add("empty_sh3.atex", container::MakeSyntheticAsset(o), {});
  o.gaussians = 5;
  o.sh_degree = 1;
  o.textures = container::SyntheticTextures::kUniform;
  o.deformation = false;
  o.stats = false;
  WriteOptions zstd;
  zstd.codec = Codec::kZstd;
  add("small_uniform_zstd.atex", container::MakeSyntheticAsset(o), zstd);
  if (HaveDracoCodec()) {
    o.gaussians = 40;
    WriteOptions draco;
    draco.draco_positions = true;
    draco.fallback_to_raw = false;
    add("draco_positions.atex", container::MakeSyntheticAsset(o), draco);
  }
  return seeds;
}

}  // namespace atex::golden
