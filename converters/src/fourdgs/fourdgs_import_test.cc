// 4DGaussians state_dict -> DeformationField, cfg_args parsing and the whole
// folder import, on checkpoints written here with 4DGaussians' key names.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <random>

#include "atex/converters/fourdgs.h"
#include "atex/converters/ply.h"
#include "atex/deform.h"
#include "atex/file_io.h"
#include "core/test_support.h"
#include "fourdgs/torch_test_util.h"

namespace atex {
namespace {

using fourdgs_testing::StateDictArchive;
using fourdgs_testing::TensorSpec;

const char* kHeadKeys[kNumDeformHeads] = {"pos_deform", "scales_deform", "rotations_deform", "opacity_deform",
                                          "shs_deform"};

// A random field in 4DGaussians' shapes: 48 SH outputs, AABB stored (max, min).
DeformationField RandomFourDgsField(const std::vector<int>& multires, std::array<int, 4> base, int channels,
                                    int width, int trunk_layers, uint64_t seed) {
  DeformationConfig c;
  c.grid.channels = channels;
  c.grid.base_resolution = base;
  c.grid.multires = multires;
  c.mlp_width = width;
  c.trunk_layers = trunk_layers;
  c.heads = {true, true, true, true, true};
  c.sh_coeffs = 16;
  c.aabb_lo = {1.5f, 2.0f, 0.8f};
  c.aabb_hi = {-1.4f, -2.2f, -0.9f};
  c.time_scale = 1.0f;
  c.time_offset = 0.0f;
  auto made = InitDeformationField(c, seed);
  EXPECT_TRUE(made.ok());
  DeformationField f = *made;
  std::mt19937 rng(static_cast<uint32_t>(seed));
  std::uniform_real_distribution<float> u(-0.3f, 0.3f);
  for (auto& scale : f.planes)
    for (auto& plane : scale)
      for (float& v : plane) v += u(rng);  // not the init constants
  for (auto& l : f.trunk)
    for (float& v : l.bias) v = u(rng);
  for (auto& head : f.heads)
    for (auto& l : head)
      for (float& v : l.bias) v = u(rng);
  return f;
}

// The state_dict 4DGaussians' deform_network would save for this field,
// including the keys the importer must ignore.
std::vector<TensorSpec> ToStateDict(const DeformationField& f, bool with_sh_head = true) {
  std::vector<TensorSpec> out;
  out.push_back({"time_poc", {4}, {1, 2, 4, 8}});
  out.push_back({"pos_poc", {10}, std::vector<float>(10, 1.0f)});
  out.push_back({"rotation_scaling_poc", {2}, {1, 2}});
  out.push_back({"opacity_poc", {2}, {1, 2}});
  out.push_back({"timenet.0.weight", {64, 9}, std::vector<float>(64 * 9, 0.01f)});
  out.push_back({"timenet.0.bias", {64}, std::vector<float>(64, 0.0f)});
  out.push_back({"timenet.2.weight", {32, 64}, std::vector<float>(32 * 64, 0.02f)});
  out.push_back({"timenet.2.bias", {32}, std::vector<float>(32, 0.0f)});
  const auto& c = f.config;
  std::vector<float> aabb(c.aabb_lo.begin(), c.aabb_lo.end());
  aabb.insert(aabb.end(), c.aabb_hi.begin(), c.aabb_hi.end());
  out.push_back({"deformation_net.grid.aabb", {2, 3}, aabb});
  for (int s = 0; s < c.grid.scales(); ++s) {
    for (int p = 0; p < kNumHexPlanes; ++p) {
      out.push_back({StrCat("deformation_net.grid.grids.", s, ".", p),
                     {1, c.grid.channels, c.grid.resolution(s, kHexPlaneAxes[p][1]),
                      c.grid.resolution(s, kHexPlaneAxes[p][0])},
                     f.planes[s][p]});
    }
  }
  auto linear = [&](const std::string& prefix, const Linear& l) {
    out.push_back({prefix + ".weight", {l.out, l.in}, l.weight});
    out.push_back({prefix + ".bias", {l.out}, l.bias});
  };
  for (size_t i = 0; i < f.trunk.size(); ++i) linear(StrCat("deformation_net.feature_out.", 2 * i), f.trunk[i]);
  for (int h = 0; h < kNumDeformHeads; ++h) {
    if (!c.heads[h] || (h == kHeadSH && !with_sh_head)) continue;
    linear(StrCat("deformation_net.", kHeadKeys[h], ".1"), f.heads[h][0]);
    linear(StrCat("deformation_net.", kHeadKeys[h], ".3"), f.heads[h][1]);
  }
  return out;
}

TorchStateDict InMemory(const std::vector<TensorSpec>& specs) {
  TorchStateDict state;
  for (const auto& s : specs) state.tensors.push_back({s.name, "float32", s.shape, s.values, true});
  return state;
}

void ExpectSameField(const DeformationField& a, const DeformationField& b) {
  ASSERT_EQ(a.config.grid.scales(), b.config.grid.scales());
  for (int s = 0; s < a.config.grid.scales(); ++s)
    for (int axis = 0; axis < 4; ++axis)
      EXPECT_EQ(a.config.grid.resolution(s, axis), b.config.grid.resolution(s, axis));
  EXPECT_EQ(a.config.grid.channels, b.config.grid.channels);
  EXPECT_EQ(a.config.mlp_width, b.config.mlp_width);
  EXPECT_EQ(a.config.trunk_layers, b.config.trunk_layers);
  EXPECT_EQ(a.config.aabb_lo, b.config.aabb_lo);
  EXPECT_EQ(a.config.aabb_hi, b.config.aabb_hi);
  EXPECT_EQ(a.planes, b.planes);
  ASSERT_EQ(a.trunk.size(), b.trunk.size());
  for (size_t i = 0; i < a.trunk.size(); ++i) EXPECT_EQ(a.trunk[i].weight, b.trunk[i].weight);
  for (int h = 0; h < kNumDeformHeads; ++h) {
    EXPECT_EQ(a.config.heads[h], b.config.heads[h]) << h;
    for (int k = 0; k < 2; ++k) {
      EXPECT_EQ(a.heads[h][k].weight, b.heads[h][k].weight);
      EXPECT_EQ(a.heads[h][k].bias, b.heads[h][k].bias);
    }
  }
}

FourDgsHeadFlags AllOn() {
  FourDgsHeadFlags flags;
  flags.no_do = false;
  flags.no_dshs = false;
  return flags;
}

TEST(FourDgsField, RoundTripInfersShapesFromTensors) {
  // Spatial resolutions (8,10,12) and (12,15,18): base = gcd = (4,5,6), multires [2, 3].
  const DeformationField f = RandomFourDgsField({2, 3}, {4, 5, 6, 7}, 3, 8, 2, 1);
  auto imported = FourDgsFieldFromStateDict(InMemory(ToStateDict(f)), AllOn(), 16, "ckpt");
  ASSERT_TRUE(imported.ok()) << imported.status().ToString();
  ExpectSameField(*imported, f);
  EXPECT_EQ(imported->config.time_scale, 1.0f);
  EXPECT_EQ(imported->config.time_offset, 0.0f);
  EXPECT_EQ(imported->config.sh_coeffs, 16);
}

TEST(FourDgsField, HeadFlagsAndMissingHeads) {
  const DeformationField f = RandomFourDgsField({1, 2}, {3, 3, 3, 4}, 2, 4, 1, 2);
  FourDgsHeadFlags flags;  // 4DGaussians defaults: no_do, no_dshs
  auto defaults = FourDgsFieldFromStateDict(InMemory(ToStateDict(f)), flags, 16, "ckpt");
  ASSERT_TRUE(defaults.ok()) << defaults.status().ToString();
  EXPECT_EQ(defaults->config.heads, (std::array<bool, 5>{true, true, true, false, false}));
  EXPECT_TRUE(defaults->heads[kHeadOpacity][0].weight.empty());

  flags = AllOn();
  flags.no_dr = true;
  auto no_rotation = FourDgsFieldFromStateDict(InMemory(ToStateDict(f, /*with_sh_head=*/false)), flags, 16, "ckpt");
  ASSERT_TRUE(no_rotation.ok()) << no_rotation.status().ToString();
  // Older checkpoints have no shs_deform: the SH head is off whatever the flag.
  EXPECT_EQ(no_rotation->config.heads, (std::array<bool, 5>{true, true, false, true, false}));

  // Without an SH head, any SH degree is fine.
  flags.no_dshs = true;
  EXPECT_TRUE(FourDgsFieldFromStateDict(InMemory(ToStateDict(f)), flags, 1, "ckpt").ok());
}

TEST(FourDgsField, VariantsItCannotReproduceAreRefused) {
  const DeformationField f = RandomFourDgsField({1, 2}, {3, 3, 3, 4}, 2, 4, 1, 3);
  const std::vector<TensorSpec> good = ToStateDict(f);
  auto expect = [&](std::vector<TensorSpec> specs, int sh_coeffs, StatusCode code, const std::string& part) {
    auto r = FourDgsFieldFromStateDict(InMemory(specs), AllOn(), sh_coeffs, "ckpt.pth");
    ASSERT_FALSE(r.ok()) << part;
    EXPECT_EQ(r.status().code(), code) << r.status().ToString();
    EXPECT_NE(r.status().message().find(part), std::string::npos) << r.status().ToString();
    EXPECT_NE(r.status().message().find("ckpt.pth"), std::string::npos) << r.status().ToString();
  };
  auto with = [&](TensorSpec extra) {
    auto specs = good;
    specs.push_back(std::move(extra));
    return specs;
  };
  auto without = [&](const std::string& name) {
    auto specs = good;
    std::erase_if(specs, [&](const TensorSpec& s) { return s.name == name; });
    return specs;
  };
  auto replaced = [&](const std::string& name, TensorSpec spec) {
    auto specs = good;
    for (auto& s : specs)
      if (s.name == name) s = spec;
    return specs;
  };
  expect(with({"deformation_net.static_mlp.1.weight", {4, 4}, std::vector<float>(16)}), 16,
         StatusCode::kUnsupported, "static_mlp");
  expect(with({"deformation_net.empty_voxel.grid", {1, 1, 4, 4, 4}, std::vector<float>(64)}), 16,
         StatusCode::kUnsupported, "empty_voxel");
  expect(with({"deformation_net.mystery.weight", {1}, {0.0f}}), 16, StatusCode::kUnsupported, "mystery");
  expect(good, 4, StatusCode::kUnsupported, "48 outputs");
  expect(without("deformation_net.grid.aabb"), 16, StatusCode::kNotFound, "grid.aabb");
  expect(without("deformation_net.grid.grids.1.3"), 16, StatusCode::kNotFound, "grid.grids.1.3");
  expect(without("deformation_net.pos_deform.3.bias"), 16, StatusCode::kNotFound, "pos_deform.3.bias");
  // grid_pe: the trunk takes 3x the grid features.
  Linear wide = f.trunk[0];
  wide.in *= 3;
  wide.weight.resize(static_cast<size_t>(wide.in) * wide.out);
  expect(replaced("deformation_net.feature_out.0.weight",
                  {"deformation_net.feature_out.0.weight", {wide.out, wide.in}, wide.weight}),
         16, StatusCode::kUnsupported, "grid_pe");
  // Plane shapes that disagree within a scale.
  const auto& xy = good[9];  // deformation_net.grid.grids.0.0
  ASSERT_EQ(xy.name, "deformation_net.grid.grids.0.0");
  expect(replaced(xy.name, {xy.name, {1, 2, 3, 4}, std::vector<float>(24)}), 16, StatusCode::kCorrupt,
         "gives axis 0 resolution");
  // A different time resolution per scale.
  const std::string xt1 = "deformation_net.grid.grids.1.2";
  expect(replaced(xt1, {xt1, {1, 2, 5, 6}, std::vector<float>(60)}), 16, StatusCode::kCorrupt, "grid.grids.1.");
  std::vector<TensorSpec> nan = good;
  nan[12].values[3] = std::numeric_limits<float>::quiet_NaN();
  expect(nan, 16, StatusCode::kOutOfRange, StrCat("'", nan[12].name, "' value 3"));
  auto ints = InMemory(good);
  ints.tensors[10].floating = false;
  ints.tensors[10].dtype = "int64";
  ints.tensors[10].values.clear();
  auto r = FourDgsFieldFromStateDict(ints, AllOn(), 16, "ckpt.pth");
  EXPECT_EQ(r.status().code(), StatusCode::kCorrupt);
  // Degenerate AABB.
  std::vector<TensorSpec> flat = good;
  flat[8].values = {1, 1, 1, 1, 1, 1};
  expect(flat, 16, StatusCode::kCorrupt, "AABB");
}

TEST(FourDgsCfgArgs, ReadsFlagsFromTheNamespaceRepr) {
  const std::string text =
      "Namespace(sh_degree=3, source_path='/data/dynerf/coffee_martini', model_path='output/x', images='images', "
      "resolution=-1, white_background=False, data_device='cuda', eval=True, net_width=128, timebase_pe=4, "
      "defor_depth=0, bounds=1.6, kplanes_config={'grid_dimensions': 2, 'input_coordinate_dim': 4, "
      "'output_coordinate_dim': 16, 'resolution': [64, 64, 64, 150]}, multires=[1, 2], no_dx=False, "
      "no_grid=False, no_ds=False, no_dr=False, no_do=False, no_dshs=False, empty_voxel=False, grid_pe=0, "
      "static_mlp=False, apply_rotation=False, iterations=14000)";
  FourDgsHeadFlags flags;
  ASSERT_TRUE(ParseFourDgsCfgArgs(text, &flags).ok());
  EXPECT_FALSE(flags.no_do);
  EXPECT_FALSE(flags.no_dshs);
  EXPECT_FALSE(flags.no_dx);

  FourDgsHeadFlags partial;
  partial.no_ds = true;
  ASSERT_TRUE(ParseFourDgsCfgArgs("Namespace(no_dr=True, sh_degree=3)", &partial).ok());
  EXPECT_TRUE(partial.no_dr);
  EXPECT_TRUE(partial.no_ds);   // absent: unchanged
  EXPECT_TRUE(partial.no_do);   // default kept

  FourDgsHeadFlags f;
  EXPECT_EQ(ParseFourDgsCfgArgs("Namespace(apply_rotation=True)", &f).code(), StatusCode::kUnsupported);
  EXPECT_EQ(ParseFourDgsCfgArgs("Namespace(grid_pe=2, no_dx=False)", &f).code(), StatusCode::kUnsupported);
  EXPECT_EQ(ParseFourDgsCfgArgs("Namespace(static_mlp=True)", &f).code(), StatusCode::kUnsupported);
  EXPECT_EQ(ParseFourDgsCfgArgs("Namespace(no_dx=maybe)", &f).code(), StatusCode::kCorrupt);
  // Long hostile values are cut, not scanned recursively.
  EXPECT_EQ(ParseFourDgsCfgArgs("Namespace(no_dx=" + std::string(1 << 20, 'T') + ")", &f).code(),
            StatusCode::kCorrupt);
  // A longer name that ends like a flag is not the flag.
  FourDgsHeadFlags g;
  ASSERT_TRUE(ParseFourDgsCfgArgs("Namespace(xno_dx=True)", &g).ok());
  EXPECT_FALSE(g.no_dx);
}

Gaussians SmallGaussians(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  Gaussians g;
  g.sh_degree = 3;
  g.Resize(n);
  for (auto* v : {&g.positions, &g.rotations, &g.log_scales, &g.opacity_logits, &g.sh})
    for (float& x : *v) x = u(rng);
  return g;
}

void WriteText(const std::filesystem::path& path, const std::string& text) {
  ASSERT_TRUE(WriteFileAtomic(path.string(), text.data(), text.size()).ok());
}

void WriteIteration(const std::filesystem::path& dir, const Gaussians& g, const DeformationField& f) {
  std::filesystem::create_directories(dir);
  ASSERT_TRUE(WritePlyGaussians((dir / "point_cloud.ply").string(), g).ok());
  ASSERT_TRUE(
      WriteFileAtomic((dir / "deformation.pth").string(), StateDictArchive(ToStateDict(f), "deformation/")).ok());
}

// Issue 24: a garbled cfg_args (cut, or not a Namespace) silently lost the opacity and SH
// heads to 4DGaussians' defaults; now it is kCorrupt naming the missing switches.
TEST(FourDgsImport, GarbledCfgArgsIsRefused) {
  testing::TempDir tmp;
  WriteIteration(tmp.path() / "point_cloud" / "iteration_1000", SmallGaussians(12, 4),
                 RandomFourDgsField({1, 2}, {3, 4, 3, 5}, 2, 6, 1, 10));
  for (const char* garbled : {"Namespace(no_dx=False, no_ds=False, no_d", "\x00\x17garbage no_dx=False",
                              "Namespace(sh_degree=3)"}) {
    WriteText(tmp.path() / "cfg_args", garbled);
    auto asset = ImportFourDGaussians(tmp.path().string());
    EXPECT_EQ(asset.status().code(), StatusCode::kCorrupt) << garbled;
    EXPECT_NE(asset.status().message().find("no_do"), std::string::npos) << asset.status().ToString();
  }
  FourDgsImportOptions skip;
  skip.read_cfg_args = false;
  EXPECT_TRUE(ImportFourDGaussians(tmp.path().string(), skip).ok());
}

TEST(FourDgsImport, ModelFolderIterationsCfgArgsAndOverrides) {
  testing::TempDir tmp;
  const Gaussians g = SmallGaussians(12, 4);
  const DeformationField early = RandomFourDgsField({1, 2}, {3, 4, 3, 5}, 2, 6, 1, 10);
  const DeformationField late = RandomFourDgsField({1, 2}, {3, 4, 3, 5}, 2, 6, 1, 11);
  WriteIteration(tmp.path() / "point_cloud" / "iteration_1000", g, early);
  WriteIteration(tmp.path() / "point_cloud" / "iteration_3000", g, late);
  std::filesystem::create_directories(tmp.path() / "point_cloud" / "iteration_9000");  // incomplete: skipped
  WriteText(tmp.path() / "cfg_args", "Namespace(no_dx=False, no_ds=False, no_dr=False, no_do=False, no_dshs=True)");

  auto asset = ImportFourDGaussians(tmp.path().string());
  ASSERT_TRUE(asset.ok()) << asset.status().ToString();
  ASSERT_TRUE(asset->deformation.has_value());
  EXPECT_EQ(asset->metadata.extra["iteration"], 3000);
  EXPECT_EQ(asset->deformation->planes, late.planes);
  EXPECT_EQ(asset->deformation->config.heads, (std::array<bool, 5>{true, true, true, true, false}));
  EXPECT_EQ(asset->gaussians.positions, g.positions);
  EXPECT_EQ(asset->gaussians.sh, g.sh);
  EXPECT_EQ(asset->metadata.time_min, 0.0f);
  EXPECT_EQ(asset->metadata.time_max, 1.0f);
  for (int a = 0; a < 3; ++a) {
    float lo = g.positions[a], hi = g.positions[a];
    for (size_t i = 0; i < g.size(); ++i) {
      lo = std::min(lo, g.positions[3 * i + a]);
      hi = std::max(hi, g.positions[3 * i + a]);
    }
    EXPECT_EQ(asset->metadata.bounds_min[a], lo);
    EXPECT_EQ(asset->metadata.bounds_max[a], hi);
  }
  EXPECT_NE(asset->metadata.extra["head_flags"]["from"].get<std::string>().find("cfg_args"), std::string::npos);

  // An explicit iteration, found from the iteration folder itself (cfg_args two levels up), with an override.
  FourDgsImportOptions options;
  options.no_dshs = false;
  auto direct = ImportFourDGaussians((tmp.path() / "point_cloud" / "iteration_1000").string(), options);
  ASSERT_TRUE(direct.ok()) << direct.status().ToString();
  EXPECT_EQ(direct->deformation->planes, early.planes);
  EXPECT_EQ(direct->metadata.extra["iteration"], 1000);
  EXPECT_TRUE(direct->deformation->config.heads[kHeadSH]);

  options = {};
  options.iteration = 1000;
  auto chosen = ImportFourDGaussians(tmp.path().string(), options);
  ASSERT_TRUE(chosen.ok()) << chosen.status().ToString();
  EXPECT_EQ(chosen->deformation->planes, early.planes);

  // The imported field deforms exactly like the field that was saved.
  DeformationField expected = late;
  expected.config.heads[kHeadSH] = false;
  expected.heads[kHeadSH] = {};
  Gaussians a, b;
  ASSERT_TRUE(DeformForward(*asset->deformation, asset->gaussians, 0.35, &a, nullptr).ok());
  ASSERT_TRUE(DeformForward(expected, g, 0.35, &b, nullptr).ok());
  EXPECT_EQ(a.positions, b.positions);
  EXPECT_EQ(a.opacity_logits, b.opacity_logits);

  options = {};
  options.iteration = 2000;
  EXPECT_EQ(ImportFourDGaussians(tmp.path().string(), options).status().code(), StatusCode::kNotFound);
  EXPECT_EQ(ImportFourDGaussians((tmp.path() / "nothing").string()).status().code(), StatusCode::kNotFound);

  WriteText(tmp.path() / "cfg_args", "Namespace(apply_rotation=True)");
  EXPECT_EQ(ImportFourDGaussians(tmp.path().string()).status().code(), StatusCode::kUnsupported);
  options = {};
  options.read_cfg_args = false;
  auto ignoring = ImportFourDGaussians(tmp.path().string(), options);
  ASSERT_TRUE(ignoring.ok()) << ignoring.status().ToString();
  EXPECT_EQ(ignoring->deformation->config.heads, (std::array<bool, 5>{true, true, true, false, false}));
}

TEST(FourDgsImport, ShHeadNeedsDegreeThree) {
  testing::TempDir tmp;
  Gaussians g = SmallGaussians(5, 1);
  g.sh_degree = 1;
  g.sh.resize(5 * 4 * 3);
  WriteIteration(tmp.path(), g, RandomFourDgsField({1}, {3, 3, 3, 3}, 2, 4, 1, 5));
  FourDgsImportOptions options;
  options.no_dshs = false;
  auto r = ImportFourDGaussians(tmp.path().string(), options);
  EXPECT_EQ(r.status().code(), StatusCode::kUnsupported) << r.status().ToString();
  options.no_dshs = true;
  EXPECT_TRUE(ImportFourDGaussians(tmp.path().string(), options).ok());
}

}  // namespace
}  // namespace atex
