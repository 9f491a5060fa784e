// Export: the GLB is checked by reading it back by hand (not through our importer),
// against the KHR_gaussian_splatting attribute definitions.
#include <cmath>
#include <cstring>
#include <set>

#include <gtest/gtest.h>

#include "atex/converters/gltf.h"
#include "gltf/gltf_test_scene.h"

namespace atex {
namespace {

using testing::GlbParts;
using testing::MakeTestAsset;
using testing::SceneSpec;

GlbParts Export(const Asset& asset, const GltfExportOptions& options = {}) {
  auto glb = EncodeGlb(asset, options);
  EXPECT_TRUE(glb.ok()) << glb.status().ToString();
  return testing::SplitGlb(*glb);
}

const nlohmann::json& Primitive(const GlbParts& p) { return p.json["meshes"][0]["primitives"][0]; }
int Attribute(const GlbParts& p, const std::string& name) { return Primitive(p)["attributes"].at(name).get<int>(); }

TEST(GltfExport, BaseAttributesFollowKhrGaussianSplatting) {
  const Asset asset = MakeTestAsset({.count = 40, .sh_degree = 3, .textures = false, .deformation = false});
  const GlbParts p = Export(asset);
  const auto& prim = Primitive(p);
  EXPECT_EQ(prim["mode"], 0);  // POINTS
  const auto& khr = prim["extensions"]["KHR_gaussian_splatting"];
  EXPECT_EQ(khr["kernel"], "ellipse");
  EXPECT_EQ(khr["colorSpace"], "srgb_rec709_display");
  const Gaussians& g = asset.gaussians;
  const size_t n = g.size();

  const auto pos = testing::ReadFloatAccessor(p, Attribute(p, "POSITION"));
  EXPECT_TRUE(testing::SameBits(pos, g.positions));
  const auto rot = testing::ReadFloatAccessor(p, Attribute(p, "KHR_gaussian_splatting:ROTATION"));
  const auto scale = testing::ReadFloatAccessor(p, Attribute(p, "KHR_gaussian_splatting:SCALE"));
  const auto opacity = testing::ReadFloatAccessor(p, Attribute(p, "KHR_gaussian_splatting:OPACITY"));
  ASSERT_EQ(rot.size(), n * 4);
  for (size_t i = 0; i < n; ++i) {
    const float* q = &g.rotations[i * 4];  // w x y z
    const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    EXPECT_NEAR(rot[i * 4 + 0], q[1] / norm, 1e-6);  // glTF order x y z w
    EXPECT_NEAR(rot[i * 4 + 1], q[2] / norm, 1e-6);
    EXPECT_NEAR(rot[i * 4 + 2], q[3] / norm, 1e-6);
    EXPECT_NEAR(rot[i * 4 + 3], q[0] / norm, 1e-6);
    for (int k = 0; k < 3; ++k)
      EXPECT_NEAR(scale[i * 3 + k], std::exp(g.log_scales[i * 3 + k]), 1e-6 * scale[i * 3 + k]);
    EXPECT_NEAR(opacity[i], 1.0 / (1.0 + std::exp(-g.opacity_logits[i])), 1e-6);
    EXPECT_GE(opacity[i], 0.0f);
    EXPECT_LE(opacity[i], 1.0f);
  }
  // SH_DEGREE_l_COEF_n is our coefficient k = l^2 + n (3DGS order, DC included).
  for (int l = 0; l <= 3; ++l) {
    for (int c = 0; c <= 2 * l; ++c) {
      const std::string name = "KHR_gaussian_splatting:SH_DEGREE_" + std::to_string(l) + "_COEF_" + std::to_string(c);
      const auto coef = testing::ReadFloatAccessor(p, Attribute(p, name));
      const size_t k = size_t(l * l + c);
      for (size_t i = 0; i < n; ++i) {
        for (int ch = 0; ch < 3; ++ch) ASSERT_EQ(coef[i * 3 + ch], g.sh[(i * 16 + k) * 3 + ch]) << name;
      }
    }
  }
  EXPECT_FALSE(prim["attributes"].contains("KHR_gaussian_splatting:SH_DEGREE_4_COEF_0"));
}

// Time-local Gaussians (model.h time_windows) have no place in glTF: without a time the export
// refuses (a player would draw every one at every time); at a time it bakes them like the rest.
TEST(GltfExport, TimeWindowsNeedATime) {
  Asset asset = MakeTestAsset({.count = 16, .sh_degree = 0, .textures = false, .deformation = true});
  asset.gaussians.time_windows.assign(2 * asset.gaussians.size(), 0.0f);
  asset.gaussians.time_windows[1] = 10.0f;
  auto refused = EncodeGlb(asset, {});
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), StatusCode::kUnsupported);
  EXPECT_NE(refused.status().message().find("--time"), std::string::npos) << refused.status().message();
  GltfExportOptions at_time;
  at_time.time = 0.5;
  auto baked = EncodeGlb(asset, at_time);
  EXPECT_TRUE(baked.ok()) << baked.status().ToString();
}

TEST(GltfExport, PositionMinMaxAndAlignment) {
  const Asset asset = MakeTestAsset({.count = 33, .sh_degree = 1});
  const GlbParts p = Export(asset);
  const auto& a = p.json["accessors"][Attribute(p, "POSITION")];
  for (int k = 0; k < 3; ++k) {
    float lo = INFINITY, hi = -INFINITY;
    for (size_t i = 0; i < asset.gaussians.size(); ++i) {
      lo = std::min(lo, asset.gaussians.positions[i * 3 + k]);
      hi = std::max(hi, asset.gaussians.positions[i * 3 + k]);
    }
    EXPECT_EQ(a["min"][k].get<double>(), double(lo));
    EXPECT_EQ(a["max"][k].get<double>(), double(hi));
  }
  // Every vertex attribute starts on a 4-byte boundary and has a 4-byte multiple stride.
  for (auto& [name, index] : Primitive(p)["attributes"].items()) {
    const auto& acc = p.json["accessors"][index.get<int>()];
    const auto& view = p.json["bufferViews"][acc["bufferView"].get<int>()];
    const size_t offset = view.value("byteOffset", size_t{0}) + acc.value("byteOffset", size_t{0});
    EXPECT_EQ(offset % 4, 0u) << name;
    EXPECT_EQ(view.value("byteStride", size_t{4}) % 4, 0u) << name;
    EXPECT_EQ(acc["count"], asset.gaussians.size()) << name;
  }
  EXPECT_EQ(p.json["buffers"].size(), 1u);
  EXPECT_EQ(p.json["buffers"][0]["byteLength"], p.bin.size());
}

TEST(GltfExport, ExtensionsAreUsedButNeverRequired) {
  const Asset asset = MakeTestAsset({});
  const GlbParts p = Export(asset);
  std::set<std::string> used(p.json["extensionsUsed"].begin(), p.json["extensionsUsed"].end());
  EXPECT_TRUE(used.count("KHR_gaussian_splatting"));
  EXPECT_TRUE(used.count("ATEX_gaussian_textures"));
  EXPECT_TRUE(used.count("ATEX_gaussian_deformation"));
  EXPECT_FALSE(p.json.contains("extensionsRequired"));
  const auto& sub = Primitive(p)["extensions"]["KHR_gaussian_splatting"]["extensions"];
  EXPECT_TRUE(sub.contains("ATEX_gaussian_textures"));
  EXPECT_TRUE(sub.contains("ATEX_gaussian_deformation"));
  // Texels are one VEC4 float accessor of exactly sum(h*w) elements.
  const auto& texels = p.json["accessors"][sub["ATEX_gaussian_textures"]["texels"].get<int>()];
  EXPECT_EQ(texels["count"], asset.textures->texel_count());
  EXPECT_EQ(texels["type"], "VEC4");
  const auto& field = sub["ATEX_gaussian_deformation"]["field"];
  EXPECT_EQ(field["grid"]["planes"].size(), asset.deformation->config.grid.multires.size());
  EXPECT_EQ(field["heads"].size(), 4u);  // position, scale, rotation, opacity enabled; sh off
  EXPECT_EQ(p.json["extras"]["atex"]["metadata"]["axes"], "opencv");
}

TEST(GltfExport, NodeRotationTurnsTheSceneUpright) {
  Asset asset = MakeTestAsset({.count = 5, .textures = false, .deformation = false});
  // "opencv" worlds have y down: 180 degrees about x.
  GlbParts p = Export(asset);
  EXPECT_EQ(p.json["nodes"][0]["rotation"], nlohmann::json({1.0, 0.0, 0.0, 0.0}));
  asset.metadata.axes = "blender";  // z up: -90 degrees about x maps +z to +y
  p = Export(asset);
  const auto q = p.json["nodes"][0]["rotation"].get<std::vector<double>>();
  const double x = q[0], y = q[1], z = q[2], w = q[3];
  // Column 2 of R(q) is the image of +z; it must be +y.
  EXPECT_NEAR(2 * (x * z + w * y), 0.0, 1e-12);
  EXPECT_NEAR(2 * (y * z - w * x), 1.0, 1e-12);
  EXPECT_NEAR(1 - 2 * (x * x + y * y), 0.0, 1e-12);
  asset.metadata.axes = "gltf";
  p = Export(asset);
  EXPECT_FALSE(p.json["nodes"][0].contains("rotation"));
  GltfExportOptions options;
  options.up = UpAxis::kNegY;
  p = Export(asset, options);
  EXPECT_EQ(p.json["nodes"][0]["rotation"], nlohmann::json({1.0, 0.0, 0.0, 0.0}));
  asset.metadata.axes = "mystery";
  EXPECT_EQ(EncodeGlb(asset).status().code(), StatusCode::kInvalidArgument);
}

TEST(GltfExport, Deterministic) {
  const Asset asset = MakeTestAsset({});
  auto a = EncodeGlb(asset), b = EncodeGlb(asset);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(*a, *b);
}

TEST(GltfExport, RefusesBadAssets) {
  Asset empty;
  EXPECT_EQ(EncodeGlb(empty).status().code(), StatusCode::kInvalidArgument);
  Asset nan = MakeTestAsset({.count = 4, .textures = false, .deformation = false});
  nan.gaussians.positions[5] = NAN;
  EXPECT_EQ(EncodeGlb(nan).status().code(), StatusCode::kOutOfRange);
  Asset stat = MakeTestAsset({.count = 4, .textures = false, .deformation = false});
  GltfExportOptions options;
  options.time = 0.5;
  EXPECT_EQ(EncodeGlb(stat, options).status().code(), StatusCode::kInvalidArgument);
}

TEST(GltfExport, BakedTimeUsesTheDeformedGaussians) {
  const Asset asset = MakeTestAsset({.count = 20, .sh_degree = 0});
  GltfExportOptions options;
  options.time = 0.75;
  options.deform = [](const Asset& a, double t, Gaussians* out) {
    *out = a.gaussians;
    for (size_t i = 0; i < out->size(); ++i) out->positions[i * 3 + 1] += float(t * (1.0 + double(i)));
    return Status::Ok();
  };
  const GlbParts p = Export(asset, options);
  const auto pos = testing::ReadFloatAccessor(p, Attribute(p, "POSITION"));
  for (size_t i = 0; i < asset.gaussians.size(); ++i) {
    EXPECT_EQ(pos[i * 3 + 1], asset.gaussians.positions[i * 3 + 1] + float(0.75 * (1.0 + double(i))));
  }
  const auto& sub = Primitive(p)["extensions"]["KHR_gaussian_splatting"]["extensions"];
  EXPECT_FALSE(sub["ATEX_gaussian_deformation"].contains("field"));  // motion is baked
  EXPECT_EQ(p.json["extras"]["atex"]["bakedTime"], 0.75);
}

TEST(GltfExport, BakedTimeWithTheRealDeformationField) {
  const Asset asset = MakeTestAsset({.count = 20, .sh_degree = 1});
  GltfExportOptions options;
  options.time = 0.3;
  const GlbParts p = Export(asset, options);
  const auto pos = testing::ReadFloatAccessor(p, Attribute(p, "POSITION"));
  double moved = 0;
  for (size_t i = 0; i < pos.size(); ++i) moved += std::abs(pos[i] - asset.gaussians.positions[i]);
  EXPECT_GT(moved, 1e-3);  // the field does move the test scene
}

#ifdef ATEX_HAVE_MESHOPT
TEST(GltfExport, MeshoptCompressesEveryViewWithAFallbackBuffer) {
  const Asset asset = MakeTestAsset({.count = 300, .sh_degree = 1});
  GltfExportOptions options;
  options.meshopt = true;
  options.meshopt_float_bits = 12;
  const GlbParts p = Export(asset, options);
  ASSERT_EQ(p.json["buffers"].size(), 2u);
  EXPECT_FALSE(p.json["buffers"][1].contains("uri"));
  EXPECT_EQ(p.json["buffers"][1]["extensions"]["EXT_meshopt_compression"]["fallback"], true);
  EXPECT_EQ(p.json["extensionsRequired"], nlohmann::json({"EXT_meshopt_compression"}));
  for (const auto& view : p.json["bufferViews"]) {
    ASSERT_TRUE(view.contains("extensions")) << view.dump();
    const auto& ext = view["extensions"]["EXT_meshopt_compression"];
    EXPECT_EQ(view["buffer"], 1);
    EXPECT_EQ(ext["buffer"], 0);
    EXPECT_EQ(ext["mode"], "ATTRIBUTES");
    EXPECT_EQ(view["byteLength"].get<size_t>(), ext["byteStride"].get<size_t>() * ext["count"].get<size_t>());
    if (view.contains("byteStride")) {
      EXPECT_EQ(view["byteStride"], ext["byteStride"]);
    }
  }
  const auto& rot = p.json["accessors"][Attribute(p, "KHR_gaussian_splatting:ROTATION")];
  EXPECT_EQ(rot["componentType"], 5122);  // normalized signed short, as the extension allows
  EXPECT_EQ(rot["normalized"], true);
  auto plain = EncodeGlb(asset);
  auto packed = EncodeGlb(asset, options);
  EXPECT_LT(packed->size(), plain->size());
}
#endif

}  // namespace
}  // namespace atex
