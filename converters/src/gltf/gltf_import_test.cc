// Import: our files come back bit for bit; other people's KHR_gaussian_splatting
// files (written here by hand) come back with their node transform baked in.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "atex/converters/gltf.h"
#include "atex/converters/ply.h"
#include "atex/deform.h"
#include "core/test_support.h"
#include "gltf/gltf_test_scene.h"

namespace atex {
namespace {

using testing::MakeTestAsset;
using testing::SameBits;

#ifdef ATEX_HAVE_TINYGLTF

void ExpectSameAsset(const Asset& a, const Asset& b) {
  const Gaussians &x = a.gaussians, &y = b.gaussians;
  EXPECT_EQ(x.sh_degree, y.sh_degree);
  EXPECT_TRUE(SameBits(x.positions, y.positions));
  EXPECT_TRUE(SameBits(x.rotations, y.rotations));
  EXPECT_TRUE(SameBits(x.log_scales, y.log_scales));
  EXPECT_TRUE(SameBits(x.opacity_logits, y.opacity_logits));
  EXPECT_TRUE(SameBits(x.sh, y.sh));
  ASSERT_EQ(a.textures.has_value(), b.textures.has_value());
  if (a.textures) {
    EXPECT_EQ(a.textures->heights, b.textures->heights);
    EXPECT_EQ(a.textures->widths, b.textures->widths);
    EXPECT_EQ(a.textures->axis_u, b.textures->axis_u);
    EXPECT_EQ(a.textures->axis_v, b.textures->axis_v);
    EXPECT_EQ(a.textures->offsets, b.textures->offsets);
    EXPECT_TRUE(SameBits(a.textures->texels, b.textures->texels));
  }
  ASSERT_EQ(a.deformation.has_value(), b.deformation.has_value());
  if (a.deformation) {
    const DeformationField &f = *a.deformation, &h = *b.deformation;
    EXPECT_EQ(f.config.grid.channels, h.config.grid.channels);
    EXPECT_EQ(f.config.grid.base_resolution, h.config.grid.base_resolution);
    EXPECT_EQ(f.config.grid.multires, h.config.grid.multires);
    EXPECT_EQ(f.config.mlp_width, h.config.mlp_width);
    EXPECT_EQ(f.config.trunk_layers, h.config.trunk_layers);
    EXPECT_EQ(f.config.heads, h.config.heads);
    EXPECT_EQ(f.config.sh_coeffs, h.config.sh_coeffs);
    EXPECT_EQ(f.config.aabb_lo, h.config.aabb_lo);
    EXPECT_EQ(f.config.aabb_hi, h.config.aabb_hi);
    EXPECT_EQ(f.config.time_scale, h.config.time_scale);
    EXPECT_EQ(f.config.time_offset, h.config.time_offset);
    ASSERT_EQ(f.planes.size(), h.planes.size());
    for (size_t s = 0; s < f.planes.size(); ++s) {
      for (int p = 0; p < kNumHexPlanes; ++p) EXPECT_TRUE(SameBits(f.planes[s][p], h.planes[s][p]));
    }
    ASSERT_EQ(f.trunk.size(), h.trunk.size());
    for (size_t l = 0; l < f.trunk.size(); ++l) {
      EXPECT_TRUE(SameBits(f.trunk[l].weight, h.trunk[l].weight));
      EXPECT_TRUE(SameBits(f.trunk[l].bias, h.trunk[l].bias));
    }
    for (int hd = 0; hd < kNumDeformHeads; ++hd) {
      for (int k = 0; k < 2; ++k) {
        EXPECT_EQ(f.heads[hd][k].in, h.heads[hd][k].in);
        EXPECT_EQ(f.heads[hd][k].out, h.heads[hd][k].out);
        EXPECT_TRUE(SameBits(f.heads[hd][k].weight, h.heads[hd][k].weight));
        EXPECT_TRUE(SameBits(f.heads[hd][k].bias, h.heads[hd][k].bias));
      }
    }
  }
  EXPECT_EQ(MetadataToJson(a.metadata), MetadataToJson(b.metadata));
}

TEST(GltfImport, GlbRoundTripIsBitExact) {
  for (int degree = 0; degree <= 3; ++degree) {
    const Asset asset = MakeTestAsset({.count = 64, .sh_degree = degree, .seed = uint64_t(10 + degree)});
    auto glb = EncodeGlb(asset);
    ASSERT_TRUE(glb.ok()) << glb.status().ToString();
    auto back = DecodeGltf(glb->data(), glb->size());
    ASSERT_TRUE(back.ok()) << back.status().ToString();
    ExpectSameAsset(asset, *back);
  }
}

TEST(GltfImport, TextGltfWithBinFileRoundTrip) {
  atex::testing::TempDir dir;
  const Asset asset = MakeTestAsset({.count = 17, .sh_degree = 1});
  const std::string path = (dir / "scene with space.gltf").string();
  ASSERT_TRUE(WriteGltfFile(path, asset).ok());
  EXPECT_TRUE(std::filesystem::exists(dir / "scene with space.bin"));
  {
    std::ifstream text_in(path);
    const auto doc = nlohmann::json::parse(text_in);
    EXPECT_EQ(doc["buffers"][0]["uri"], "scene%20with%20space.bin");  // a valid URI reference
  }
  auto back = ReadGltfFile(path);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  ExpectSameAsset(asset, *back);
  // The same text file cannot be decoded from memory: its buffer is an external file.
  std::ifstream in(path, std::ios::binary);
  std::vector<uint8_t> text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(DecodeGltf(text.data(), text.size()).status().code(), StatusCode::kUnsupported);
  // And the .glb form through files.
  ASSERT_TRUE(WriteGltfFile((dir / "s.glb").string(), asset).ok());
  auto glb_back = ReadGltfFile((dir / "s.glb").string());
  ASSERT_TRUE(glb_back.ok()) << glb_back.status().ToString();
  ExpectSameAsset(asset, *glb_back);
}

TEST(GltfImport, BakedFileImportsAsTheStaticSnapshot) {
  const Asset asset = MakeTestAsset({.count = 30, .sh_degree = 1});
  GltfExportOptions options;
  options.time = 0.4;
  auto glb = EncodeGlb(asset, options);
  ASSERT_TRUE(glb.ok());
  auto back = DecodeGltf(glb->data(), glb->size());
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_FALSE(back->deformation.has_value());
  Gaussians deformed;
  ASSERT_TRUE(DeformForward(*asset.deformation, asset.gaussians, 0.4, &deformed, nullptr).ok());
  EXPECT_TRUE(SameBits(back->gaussians.positions, deformed.positions));
  EXPECT_TRUE(SameBits(back->gaussians.rotations, deformed.rotations));
  EXPECT_TRUE(SameBits(back->gaussians.opacity_logits, deformed.opacity_logits));
  EXPECT_TRUE(back->textures.has_value());
}

TEST(GltfImport, WithoutRawParametersTheActivatedValuesAreInverted) {
  const Asset asset = MakeTestAsset({.count = 25, .sh_degree = 0, .textures = false, .deformation = false});
  GltfExportOptions options;
  options.raw_parameters = false;
  auto glb = EncodeGlb(asset, options);
  ASSERT_TRUE(glb.ok());
  auto back = DecodeGltf(glb->data(), glb->size());
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  const Gaussians &a = asset.gaussians, &b = back->gaussians;
  EXPECT_TRUE(SameBits(a.positions, b.positions));
  for (size_t i = 0; i < a.size(); ++i) {
    const float* q = &a.rotations[i * 4];
    const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (int k = 0; k < 4; ++k) EXPECT_NEAR(b.rotations[i * 4 + k], q[k] / norm, 1e-6);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(b.log_scales[i * 3 + k], a.log_scales[i * 3 + k], 1e-5);
    EXPECT_NEAR(b.opacity_logits[i], a.opacity_logits[i], 1e-4);
  }
}

TEST(GltfImport, ExportedWithoutTexturesImportsAsUntextured) {
  const Asset asset = MakeTestAsset({.count = 20, .sh_degree = 1});
  ASSERT_EQ(asset.metadata.texture_mode, "adaptive");
  GltfExportOptions options;
  options.textures = false;  // `atex export --no-textures`: the metadata still says "adaptive"
  auto glb = EncodeGlb(asset, options);
  ASSERT_TRUE(glb.ok());
  auto back = DecodeGltf(glb->data(), glb->size());
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_FALSE(back->textures.has_value());
  EXPECT_EQ(back->metadata.texture_mode, "none");
  EXPECT_TRUE(SameBits(back->gaussians.positions, asset.gaussians.positions));
}

#ifdef ATEX_HAVE_MESHOPT
TEST(GltfImport, MeshoptLosslessFloatsComeBackExactly) {
  const Asset asset = MakeTestAsset({.count = 200, .sh_degree = 2});
  GltfExportOptions options;
  options.meshopt = true;  // meshopt_float_bits = 0: floats unfiltered, raw parameters exact
  auto glb = EncodeGlb(asset, options);
  ASSERT_TRUE(glb.ok()) << glb.status().ToString();
  auto back = DecodeGltf(glb->data(), glb->size());
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  ExpectSameAsset(asset, *back);
}

TEST(GltfImport, MeshoptLossyStaysWithinTheFilterPrecision) {
  const Asset asset = MakeTestAsset({.count = 200, .sh_degree = 1});
  GltfExportOptions options;
  options.meshopt = true;
  options.meshopt_float_bits = 14;
  options.raw_parameters = false;
  auto glb = EncodeGlb(asset, options);
  ASSERT_TRUE(glb.ok()) << glb.status().ToString();
  auto back = DecodeGltf(glb->data(), glb->size());
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  const Gaussians &a = asset.gaussians, &b = back->gaussians;
  // EXPONENTIAL keeps `bits` of signed mantissa with one exponent per element (meshopt 0.18
  // shares it between the components): error <= 2^-(bits-1) of the element's largest component.
  const double rel = std::ldexp(1.0, -13);
  for (size_t i = 0; i < a.size(); ++i) {
    const double largest =
        std::max({std::abs(a.positions[i * 3]), std::abs(a.positions[i * 3 + 1]), std::abs(a.positions[i * 3 + 2])});
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(b.positions[i * 3 + k], a.positions[i * 3 + k], rel * largest) << i;
  }
  for (size_t i = 0; i < a.size(); ++i) {
    // 16-bit QUATERNION filter: the decoded rotation is within ~1e-4 of the unit quaternion (up to sign).
    const float* q = &a.rotations[i * 4];
    const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    double dot = 0, len = 0;
    for (int k = 0; k < 4; ++k) {
      dot += b.rotations[i * 4 + k] * q[k] / norm;
      len += b.rotations[i * 4 + k] * b.rotations[i * 4 + k];
    }
    EXPECT_GT(std::abs(dot) / std::sqrt(len), 1 - 1e-6) << i;
  }
  ASSERT_TRUE(back->deformation.has_value());
  EXPECT_NEAR(back->deformation->planes[0][0][3], asset.deformation->planes[0][0][3],
              rel * std::abs(asset.deformation->planes[0][0][3]));
}
#endif

// A hand-written KHR_gaussian_splatting file (the layout of the extension's README
// example): two splats, SH degree 1, a node with translation, rotation and uniform scale.
std::vector<uint8_t> ForeignGlb(const std::vector<float>& node_rotation_xyzw,
                                const char* colour_space = "srgb_rec709_display") {
  std::vector<float> pos = {1, 0, 0, 0, 2, 0};
  std::vector<float> rot = {0, 0, 0, 1, 0, 0.70710678f, 0, 0.70710678f};
  std::vector<float> scale = {0.1f, 0.2f, 0.3f, 0.5f, 0.5f, 0.5f};
  std::vector<float> opacity = {0.25f, 1.0f};
  std::vector<float> sh0 = {0.1f, 0.2f, 0.3f, -0.1f, 0.0f, 0.4f};
  std::vector<float> sh1[3] = {{0.3f, 0, 0, 0, 0, 0}, {0, 0.2f, 0, 0, 0, 0}, {0, 0, 0.1f, 0.5f, 0.5f, 0.5f}};
  std::vector<uint8_t> bin;
  nlohmann::json views = nlohmann::json::array(), accessors = nlohmann::json::array(), attributes;
  auto add = [&](const std::string& name, const std::vector<float>& v, const char* type) {
    views.push_back({{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", v.size() * 4}});
    const auto* b = reinterpret_cast<const uint8_t*>(v.data());
    bin.insert(bin.end(), b, b + v.size() * 4);
    accessors.push_back({{"bufferView", views.size() - 1}, {"componentType", 5126}, {"count", 2}, {"type", type}});
    attributes[name] = accessors.size() - 1;
  };
  add("POSITION", pos, "VEC3");
  accessors.back()["min"] = {0, 0, 0};
  accessors.back()["max"] = {1, 2, 0};
  add("KHR_gaussian_splatting:ROTATION", rot, "VEC4");
  add("KHR_gaussian_splatting:SCALE", scale, "VEC3");
  add("KHR_gaussian_splatting:OPACITY", opacity, "SCALAR");
  add("KHR_gaussian_splatting:SH_DEGREE_0_COEF_0", sh0, "VEC3");
  for (int c = 0; c < 3; ++c) add("KHR_gaussian_splatting:SH_DEGREE_1_COEF_" + std::to_string(c), sh1[c], "VEC3");
  nlohmann::json doc = {
      {"asset", {{"version", "2.0"}}},
      {"extensionsUsed", {"KHR_gaussian_splatting"}},
      {"buffers", {{{"byteLength", bin.size()}}}},
      {"bufferViews", views},
      {"accessors", accessors},
      {"meshes",
       {{{"primitives",
          {{{"mode", 0},
            {"attributes", attributes},
            {"extensions",
             {{"KHR_gaussian_splatting", {{"kernel", "ellipse"}, {"colorSpace", colour_space}}}}}}}}}}},
      {"nodes",
       {{{"children", {1}}, {"translation", {10, 0, 0}}},
        {{"mesh", 0}, {"rotation", node_rotation_xyzw}, {"scale", {2, 2, 2}}}}},
      {"scenes", {{{"nodes", {0}}}}},
      {"scene", 0}};
  return testing::JoinGlb(doc, bin);
}

TEST(GltfImport, ForeignFileBakesTheNodeTransform) {
  const float h = 0.70710678f;
  const auto glb = ForeignGlb({0, h, 0, h});  // 90 degrees about +y: x -> -z, z -> x
  auto asset = DecodeGltf(glb.data(), glb.size());
  ASSERT_TRUE(asset.ok()) << asset.status().ToString();
  const Gaussians& g = asset->gaussians;
  ASSERT_EQ(g.size(), 2u);
  EXPECT_EQ(asset->metadata.axes, "gltf");
  // World = T(10,0,0) * R_y(90) * S(2): (1,0,0) -> (0,0,-2) -> (10,0,-2); (0,2,0) -> (10,4,0).
  EXPECT_NEAR(g.positions[0], 10, 1e-5);
  EXPECT_NEAR(g.positions[1], 0, 1e-5);
  EXPECT_NEAR(g.positions[2], -2, 1e-5);
  EXPECT_NEAR(g.positions[3], 10, 1e-5);
  EXPECT_NEAR(g.positions[4], 4, 1e-5);
  EXPECT_NEAR(g.positions[5], 0, 1e-5);
  EXPECT_NEAR(std::exp(g.log_scales[0]), 0.2, 1e-6);
  EXPECT_NEAR(std::exp(g.log_scales[2]), 0.6, 1e-6);
  // Splat 0 had the identity rotation: now the node's (w, x, y, z) = (h, 0, h, 0).
  EXPECT_NEAR(g.rotations[0], h, 1e-6);
  EXPECT_NEAR(g.rotations[2], h, 1e-6);
  // Splat 1 had 90 degrees about y too: now 180 degrees about y.
  EXPECT_NEAR(std::abs(g.rotations[4 + 2]), 1, 1e-6);
  // Opacity 1 is clamped to a finite logit; 0.25 inverts exactly.
  EXPECT_NEAR(g.opacity_logits[0], std::log(0.25 / 0.75), 1e-6);
  EXPECT_TRUE(std::isfinite(g.opacity_logits[1]));
  // SH degree 1: the colour seen along R*d equals the original colour along d.
  // Degree-1 basis (3DGS): -C1*y, C1*z, -C1*x for coefficients 1, 2, 3.
  const double c1 = 0.4886025119029199;
  const float sh1_orig[3][3] = {{0.3f, 0, 0}, {0, 0.2f, 0}, {0, 0, 0.1f}};  // splat 0, coefficients 1..3, RGB
  const double d[3] = {0.6, 0.0, 0.8};
  const double rd[3] = {d[2], d[1], -d[0]};  // R_y(90) d
  for (int ch = 0; ch < 3; ++ch) {
    const double before = -c1 * d[1] * sh1_orig[0][ch] + c1 * d[2] * sh1_orig[1][ch] - c1 * d[0] * sh1_orig[2][ch];
    const double after =
        -c1 * rd[1] * g.sh[(1) * 3 + ch] + c1 * rd[2] * g.sh[(2) * 3 + ch] - c1 * rd[0] * g.sh[(3) * 3 + ch];
    EXPECT_NEAR(after, before, 1e-6) << "channel " << ch;
  }
  EXPECT_EQ(g.sh[0], 0.1f);  // DC is rotation invariant
}

// colorSpace lin_rec709_display: the diffuse colour is sRGB-encoded into ours (3DGS's display
// colour), higher SH degrees scaled by the curve's slope there; srgb_rec709_display is kept as is.
TEST(GltfImport, LinearColourSpaceBecomesDisplayColour) {
  const std::vector<float> identity = {0, 0, 0, 1};
  auto display = DecodeGltf(ForeignGlb(identity).data(), ForeignGlb(identity).size());
  const auto linear_glb = ForeignGlb(identity, "lin_rec709_display");
  auto linear = DecodeGltf(linear_glb.data(), linear_glb.size());
  ASSERT_TRUE(display.ok()) << display.status().ToString();
  ASSERT_TRUE(linear.ok()) << linear.status().ToString();
  EXPECT_FALSE(display->metadata.extra.contains("colour_space"));
  EXPECT_TRUE(linear->metadata.extra.contains("colour_space"));
  const double c0 = 0.28209479177387814;
  const Gaussians& g = linear->gaussians;
  const Gaussians& d = display->gaussians;
  const int k = g.sh_coeffs();
  ASSERT_EQ(k, 4);
  for (size_t i = 0; i < 2; ++i) {
    for (int c = 0; c < 3; ++c) {
      const double lin = std::clamp(0.5 + c0 * d.sh[i * k * 3 + c], 0.0, 1.0);  // the file's values, unchanged
      const double srgb = lin <= 0.0031308 ? 12.92 * lin : 1.055 * std::pow(lin, 1 / 2.4) - 0.055;
      EXPECT_NEAR(0.5 + c0 * g.sh[i * k * 3 + c], srgb, 1e-6) << i << " " << c;
      EXPECT_GT(srgb, lin) << "mid-grey linear values are brighter once encoded";
      const double slope = 1.055 / 2.4 * std::pow(lin, 1 / 2.4 - 1);
      for (int j = 1; j < k; ++j) {
        EXPECT_NEAR(g.sh[(i * k + j) * 3 + c], d.sh[(i * k + j) * 3 + c] * slope, 1e-6) << i << " " << j << " " << c;
      }
    }
  }
  EXPECT_EQ(g.positions, d.positions);
  EXPECT_EQ(g.opacity_logits, d.opacity_logits);
}

TEST(GltfImport, RealPlyGaussiansRoundTripBitExact) {
  ATEX_REQUIRE_DATA_FILE(ply, "splats/kacytran1122_try_iter7000_point_cloud.ply");
  auto g = ReadPlyGaussians(ply.string());
  ASSERT_TRUE(g.ok()) << g.status().ToString();
  Asset asset;
  asset.gaussians = std::move(g).value();
  asset.metadata.axes = "opencv";
  auto glb = EncodeGlb(asset);
  ASSERT_TRUE(glb.ok()) << glb.status().ToString();
  auto back = DecodeGltf(glb->data(), glb->size());
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->gaussians.size(), 9080u);
  ExpectSameAsset(asset, *back);
}

#else
TEST(GltfImport, UnsupportedWithoutTinygltf) {
  const Asset asset = MakeTestAsset({.count = 3});
  auto glb = EncodeGlb(asset);
  ASSERT_TRUE(glb.ok());
  EXPECT_EQ(DecodeGltf(glb->data(), glb->size()).status().code(), StatusCode::kUnsupported);
}
#endif

}  // namespace
}  // namespace atex
