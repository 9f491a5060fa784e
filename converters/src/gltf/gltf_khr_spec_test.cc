// Conformance with KHR_gaussian_splatting as Khronos publishes it: KhronosGroup/glTF,
// extensions/2.0/Khronos/KHR_gaussian_splatting/README.md at 77b44be (July 2026; its text is that
// of the editorial review 63770cc, April 2026, status "Release Candidate"). The rules below are
// transcribed from that text, not from our code:
//   - attribute table: ROTATION VEC4 float | signed byte normalized | signed short normalized;
//     SCALE VEC3 float | unsigned byte | unsigned byte normalized | unsigned short | unsigned short
//     normalized; OPACITY SCALAR float | unsigned byte normalized | unsigned short normalized;
//     SH_DEGREE_l_COEF_n VEC3 float; POSITION as glTF (plus KHR_mesh_quantization's types).
//   - "Scale values are linear and MUST NOT be negative."
//   - "Rotation values are stored as unit quaternions in the usual glTF order" (x, y, z, w).
//   - OPACITY "stores a normalized linear value between 0.0 (transparent) and 1.0 (opaque)".
//   - COLOR_0 fallback: clamp(0.282095 * SH_0 + 0.5) "decoded from sRGB to linear" for
//     srgb_rec709_display, "because the COLOR_0 attribute contains linear values".
// The January 2026 text (ad9422a) stored SCALE in log-space and listed signed types for it; files
// do not say which text they follow, so signed SCALE accessors are refused in other people's files.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <set>
#include <utility>

#include <gtest/gtest.h>

#include "atex/converters/gltf.h"
#include "gltf/gltf_test_scene.h"

namespace atex {
namespace {

using nlohmann::json;
using testing::GlbParts;

constexpr int kByte = 5120, kUByte = 5121, kShort = 5122, kUShort = 5123, kFloat = 5126;
using TypeSet = std::set<std::pair<int, bool>>;  // (componentType, normalized)
const TypeSet kRotationTypes = {{kFloat, false}, {kByte, true}, {kShort, true}};
const TypeSet kScaleTypes = {{kFloat, false}, {kUByte, false}, {kUByte, true}, {kUShort, false}, {kUShort, true}};
const TypeSet kOpacityTypes = {{kFloat, false}, {kUByte, true}, {kUShort, true}};
const TypeSet kShTypes = {{kFloat, false}};
const TypeSet kPositionTypes = {{kFloat, false}};
const TypeSet kQuantizedPositionTypes = {{kFloat, false}, {kByte, false},   {kByte, true},
                                         {kUByte, false}, {kUByte, true},   {kShort, false},
                                         {kShort, true},  {kUShort, false}, {kUShort, true}};
const TypeSet kColorTypes = {{kFloat, false}, {kUByte, true}, {kUShort, true}};  // glTF 2.0 COLOR_n

double Sigmoid(double x) { return 1 / (1 + std::exp(-x)); }
double SrgbToLinear(double v) { return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4); }

bool Contains(const json& array, const char* name) {
  return array.is_array() && std::find(array.begin(), array.end(), name) != array.end();
}

// Checks one exported document against the extension's rules on the JSON.
void ExpectConformingDocument(const json& doc) {
  EXPECT_TRUE(Contains(doc["extensionsUsed"], "KHR_gaussian_splatting"));
  const bool quantized = Contains(doc.value("extensionsRequired", json::array()), "KHR_mesh_quantization");
  const json& prim = doc["meshes"][0]["primitives"][0];
  EXPECT_EQ(prim["mode"], 0);  // "The mode property of the mesh primitive MUST be POINTS (0)."
  const json& khr = prim["extensions"]["KHR_gaussian_splatting"];
  EXPECT_EQ(khr["kernel"], "ellipse");
  EXPECT_TRUE(khr["colorSpace"] == "srgb_rec709_display" || khr["colorSpace"] == "lin_rec709_display");
  if (khr.contains("projection")) {
    EXPECT_EQ(khr["projection"], "perspective");
  }
  if (khr.contains("sortingMethod")) {
    EXPECT_EQ(khr["sortingMethod"], "cameraDistance");
  }
  const json& attrs = prim["attributes"];
  auto expect = [&](const std::string& name, const char* type, const TypeSet& allowed) {
    ASSERT_TRUE(attrs.contains(name)) << name;
    const json& a = doc["accessors"][attrs[name].get<int>()];
    EXPECT_EQ(a["type"], type) << name;
    const std::pair<int, bool> t{a["componentType"].get<int>(), a.value("normalized", false)};
    EXPECT_TRUE(allowed.count(t)) << name << ": componentType " << t.first << " normalized " << t.second;
  };
  expect("POSITION", "VEC3", quantized ? kQuantizedPositionTypes : kPositionTypes);
  expect("KHR_gaussian_splatting:ROTATION", "VEC4", kRotationTypes);
  expect("KHR_gaussian_splatting:SCALE", "VEC3", kScaleTypes);
  expect("KHR_gaussian_splatting:OPACITY", "SCALAR", kOpacityTypes);
  int degree = -1;
  for (int l = 0; l <= 3 && attrs.contains("KHR_gaussian_splatting:SH_DEGREE_" + std::to_string(l) + "_COEF_0"); ++l) {
    degree = l;
    for (int n = 0; n <= 2 * l; ++n)  // degrees MUST NOT be partially defined
      expect("KHR_gaussian_splatting:SH_DEGREE_" + std::to_string(l) + "_COEF_" + std::to_string(n), "VEC3", kShTypes);
  }
  EXPECT_GE(degree, 0) << "SH_DEGREE_0_COEF_0 is required";
  if (attrs.contains("COLOR_0")) {
    const json& a = doc["accessors"][attrs["COLOR_0"].get<int>()];
    EXPECT_TRUE(a["type"] == "VEC3" || a["type"] == "VEC4");
    EXPECT_TRUE(kColorTypes.count({a["componentType"].get<int>(), a.value("normalized", false)}));
  }
}

TEST(GltfKhrSpec, EveryExportFlavourUsesOnlyTheTypesTheExtensionAllows) {
  const Asset asset = testing::MakeTestAsset({.count = 40, .sh_degree = 2});
  struct Flavour {
    const char* name;
    bool quantize, meshopt, spz;
  };
  for (const Flavour& f : {Flavour{"plain", false, false, false}, Flavour{"quantize", true, false, false},
                           Flavour{"meshopt", false, true, false}, Flavour{"quantize + meshopt", true, true, false},
                           Flavour{"spz", false, false, true}}) {
    SCOPED_TRACE(f.name);
    GltfExportOptions options;
    options.quantize = f.quantize;
    options.meshopt = f.meshopt;
    options.spz = f.spz;
    auto glb = EncodeGlb(asset, options);
    if (f.meshopt && !glb.ok() && glb.status().code() == StatusCode::kUnsupported) continue;  // no meshoptimizer
    ASSERT_TRUE(glb.ok()) << glb.status().ToString();
    ExpectConformingDocument(testing::SplitGlb(*glb).json);
  }
}

// The fallback colour is linear: clamp(0.5 + C0 * SH_0) decoded from sRGB (our colorSpace), 8-bit.
TEST(GltfKhrSpec, ColorFallbackHoldsTheLinearDiffuseColourAndTheOpacity) {
  Asset asset = testing::MakeTestAsset({.count = 64, .sh_degree = 1, .textures = false, .deformation = false});
  asset.gaussians.sh[0] = 0.0f;  // colour 0.5: sRGB 0.5 is linear 0.214 (55 of 255), not 128
  const GlbParts p = testing::SplitGlb(*EncodeGlb(asset));
  const json& prim = p.json["meshes"][0]["primitives"][0];
  ASSERT_EQ(prim["extensions"]["KHR_gaussian_splatting"]["colorSpace"], "srgb_rec709_display");
  const json& a = p.json["accessors"][prim["attributes"]["COLOR_0"].get<int>()];
  ASSERT_EQ(a["componentType"], kUByte);
  ASSERT_TRUE(a.value("normalized", false));
  const json& v = p.json["bufferViews"][a["bufferView"].get<int>()];
  const size_t start = v.value("byteOffset", size_t{0}) + a.value("byteOffset", size_t{0});
  const size_t stride = v.value("byteStride", size_t{4});
  const Gaussians& g = asset.gaussians;
  const size_t k_count = size_t(g.sh_coeffs());
  for (size_t i = 0; i < g.size(); ++i) {
    for (int c = 0; c < 3; ++c) {
      const double srgb = std::clamp(0.5 + 0.2820947917738781 * g.sh[i * k_count * 3 + size_t(c)], 0.0, 1.0);
      EXPECT_NEAR(p.bin[start + i * stride + size_t(c)] / 255.0, SrgbToLinear(srgb), 0.5 / 255 + 1e-9) << i;
    }
    EXPECT_NEAR(p.bin[start + i * stride + 3] / 255.0, Sigmoid(g.opacity_logits[i]), 0.5 / 255 + 1e-9) << i;
  }
  EXPECT_EQ(p.bin[start + 0], 55);
}

#ifdef ATEX_HAVE_TINYGLTF

// A hand-written file in the layout of the extension's "glTF JSON Example" (two splats, SH degree
// 1, COLOR_0), each attribute with the component type given. Integer values are stored as given.
struct SpecAttribute {
  int component = kFloat;
  bool normalized = false;
  std::vector<double> values;
};
std::vector<uint8_t> SpecExampleGlb(const std::map<std::string, SpecAttribute>& overrides, bool ours = false) {
  std::map<std::string, std::pair<const char*, SpecAttribute>> attrs = {
      {"POSITION", {"VEC3", {kFloat, false, {1, 2, 3, -1, 0, 0.5}}}},
      {"COLOR_0", {"VEC4", {kUByte, true, {55, 55, 55, 255, 0, 0, 0, 64}}}},
      {"KHR_gaussian_splatting:SCALE", {"VEC3", {kFloat, false, {0.5, 0.25, 0.125, 2, 1, 0.01}}}},
      {"KHR_gaussian_splatting:ROTATION", {"VEC4", {kFloat, false, {0, 0, 0, 1, 0, 1, 0, 0}}}},
      {"KHR_gaussian_splatting:OPACITY", {"SCALAR", {kFloat, false, {1.0, 0.25}}}},
      {"KHR_gaussian_splatting:SH_DEGREE_0_COEF_0", {"VEC3", {kFloat, false, {0, 0.5, -1, 1, 1, 1}}}},
      {"KHR_gaussian_splatting:SH_DEGREE_1_COEF_0", {"VEC3", {kFloat, false, {0.1, 0, 0, 0, 0, 0}}}},
      {"KHR_gaussian_splatting:SH_DEGREE_1_COEF_1", {"VEC3", {kFloat, false, {0, 0.2, 0, 0, 0, 0}}}},
      {"KHR_gaussian_splatting:SH_DEGREE_1_COEF_2", {"VEC3", {kFloat, false, {0, 0, 0.3, 0, 0, 0}}}}};
  for (const auto& [name, a] : overrides) attrs.at(name).second = a;
  std::vector<uint8_t> bin;
  json views = json::array(), accessors = json::array(), attributes = json::object();
  for (const auto& [name, entry] : attrs) {
    const auto& [type, a] = entry;
    const size_t comps = std::string(type) == "SCALAR" ? 1 : std::string(type) == "VEC3" ? 3 : 4;
    const size_t size = a.component == kFloat ? 4 : (a.component == kShort || a.component == kUShort) ? 2 : 1;
    const size_t stride = (comps * size + 3) / 4 * 4;  // glTF: vertex attribute elements 4-byte aligned
    const size_t offset = bin.size();
    bin.resize(offset + 2 * stride, 0);
    for (size_t i = 0; i < a.values.size(); ++i) {
      uint8_t* at = &bin[offset + (i / comps) * stride + (i % comps) * size];
      const double x = a.values[i];
      if (a.component == kFloat) {
        const float f = float(x);
        std::memcpy(at, &f, 4);
      } else if (size == 2) {
        const uint16_t u = a.component == kShort ? uint16_t(int16_t(x)) : uint16_t(x);
        std::memcpy(at, &u, 2);
      } else {
        *at = a.component == kByte ? uint8_t(int8_t(x)) : uint8_t(x);
      }
    }
    views.push_back({{"buffer", 0}, {"byteOffset", offset}, {"byteLength", 2 * stride}, {"byteStride", stride}});
    json accessor = {{"bufferView", views.size() - 1}, {"componentType", a.component}, {"count", 2}, {"type", type}};
    if (a.normalized) accessor["normalized"] = true;
    if (name == "POSITION") accessor["min"] = {-1, 0, 0.5}, accessor["max"] = {1, 2, 3};
    accessors.push_back(accessor);
    attributes[name] = accessors.size() - 1;
  }
  json khr = {{"kernel", "ellipse"},
              {"colorSpace", "srgb_rec709_display"},
              {"sortingMethod", "cameraDistance"},
              {"projection", "perspective"}};
  json doc = {{"asset", {{"version", "2.0"}}},
              {"extensionsUsed", {"KHR_gaussian_splatting"}},
              {"buffers", {{{"byteLength", bin.size()}}}},
              {"bufferViews", views},
              {"accessors", accessors},
              {"meshes",
               {{{"primitives",
                  {{{"mode", 0}, {"attributes", attributes}, {"extensions", {{"KHR_gaussian_splatting", khr}}}}}}}}},
              {"nodes", {{{"mesh", 0}}}},
              {"scenes", {{{"nodes", {0}}}}},
              {"scene", 0}};
  if (ours) {
    Metadata metadata;
    metadata.axes = "gltf";
    doc["extras"] = {{"atex", {{"version", 1}, {"metadata", MetadataToJson(metadata)}}}};
  }
  return testing::JoinGlb(doc, bin);
}

StatusOr<Asset> Import(const std::vector<uint8_t>& glb) { return DecodeGltf(glb.data(), glb.size()); }

// The linear reading, pinned on the example's float values: a log-space reader would get
// exp(0.5) = 1.65 for the first scale, a logit reader sigmoid(1) = 0.73 for the first opacity.
TEST(GltfKhrSpec, HandWrittenSpecExampleImportsWithLinearScalesAndOpacities) {
  auto asset = Import(SpecExampleGlb({}));
  ASSERT_TRUE(asset.ok()) << asset.status().ToString();
  const Gaussians& g = asset->gaussians;
  ASSERT_EQ(g.size(), 2u);
  ASSERT_EQ(g.sh_degree, 1);
  const double scales[6] = {0.5, 0.25, 0.125, 2, 1, 0.01};
  for (int k = 0; k < 6; ++k) EXPECT_NEAR(std::exp(double(g.log_scales[size_t(k)])), scales[k], 1e-6 * scales[k]);
  EXPECT_NEAR(Sigmoid(g.opacity_logits[1]), 0.25, 1e-6);
  EXPECT_GT(Sigmoid(g.opacity_logits[0]), 0.999);  // opacity 1 (its logit clamped to a finite one)
  // (x, y, z, w) = (0, 1, 0, 0) is our (w, x, y, z) = (0, 0, 1, 0).
  EXPECT_EQ(g.rotations[4], 0.0f);
  EXPECT_EQ(g.rotations[6], 1.0f);
  EXPECT_EQ(g.rotations[0], 1.0f);
  // SH_DEGREE_1_COEF_n is the m = n - 1 coefficient, our k = 1 + n; DC is SH_DEGREE_0_COEF_0.
  EXPECT_EQ(g.sh[1 * 3 + 0], 0.1f);
  EXPECT_EQ(g.sh[2 * 3 + 1], 0.2f);
  EXPECT_EQ(g.sh[3 * 3 + 2], 0.3f);
  EXPECT_EQ(g.sh[0 * 3 + 1], 0.5f);
}

// Quantised storage the extension allows: SCALE unsigned short normalized and unsigned byte (not
// normalized), ROTATION signed byte normalized, OPACITY unsigned byte normalized.
TEST(GltfKhrSpec, HandWrittenQuantizedSpecExampleImports) {
  auto asset = Import(SpecExampleGlb({
      {"KHR_gaussian_splatting:SCALE", {kUShort, true, {65535, 13107, 6554, 655, 65535, 32768}}},
      {"KHR_gaussian_splatting:ROTATION", {kByte, true, {0, 0, 0, 127, 0, 127, 0, 0}}},
      {"KHR_gaussian_splatting:OPACITY", {kUByte, true, {255, 64}}},
  }));
  ASSERT_TRUE(asset.ok()) << asset.status().ToString();
  const Gaussians& g = asset->gaussians;
  const double stored[6] = {65535, 13107, 6554, 655, 65535, 32768};
  for (int k = 0; k < 6; ++k)
    EXPECT_NEAR(std::exp(double(g.log_scales[size_t(k)])), stored[k] / 65535, 1e-6 * stored[k] / 65535) << k;
  EXPECT_NEAR(Sigmoid(g.opacity_logits[1]), 64.0 / 255, 1e-6);
  EXPECT_NEAR(g.rotations[0], 1, 1e-6);
  EXPECT_NEAR(g.rotations[6], 1, 1e-6);

  auto bytes = Import(SpecExampleGlb({{"KHR_gaussian_splatting:SCALE", {kUByte, false, {1, 2, 3, 4, 5, 6}}}}));
  ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
  for (int k = 0; k < 6; ++k) EXPECT_NEAR(std::exp(double(bytes->gaussians.log_scales[size_t(k)])), k + 1, 1e-5);
}

// Signed SCALE types are not in the extension's table; the superseded text that had them stored
// log-scales. Someone else's file is refused (it does not say which text it follows); our own
// files (extras.atex) with SHORT normalized SCALE, which `atex export --quantize` wrote before it
// used UNSIGNED_SHORT, are linear and still read.
TEST(GltfKhrSpec, SignedScalesAreRefusedExceptInOurEarlierQuantizedFiles) {
  const SpecAttribute signed_scale{kShort, true, {16384, 8192, 4096, 32767, 1, 100}};
  auto foreign = Import(SpecExampleGlb({{"KHR_gaussian_splatting:SCALE", signed_scale}}));
  ASSERT_FALSE(foreign.ok());
  EXPECT_EQ(foreign.status().code(), StatusCode::kUnsupported);
  EXPECT_NE(foreign.status().message().find("KHR_gaussian_splatting:SCALE"), std::string::npos);
  EXPECT_EQ(Import(SpecExampleGlb({{"KHR_gaussian_splatting:SCALE", {kByte, true, {64, 32, 16, 127, 1, 2}}}}))
                .status()
                .code(),
            StatusCode::kUnsupported);

  auto ours = Import(SpecExampleGlb({{"KHR_gaussian_splatting:SCALE", signed_scale}}, true));
  ASSERT_TRUE(ours.ok()) << ours.status().ToString();
  for (int k = 0; k < 6; ++k) {
    EXPECT_NEAR(std::exp(double(ours->gaussians.log_scales[size_t(k)])), signed_scale.values[size_t(k)] / 32767,
                1e-6 * signed_scale.values[size_t(k)] / 32767);
  }
  // Even in our files only the SHORT normalized layout was ever written.
  EXPECT_EQ(Import(SpecExampleGlb({{"KHR_gaussian_splatting:SCALE", {kByte, true, {64, 32, 16, 127, 1, 2}}}}, true))
                .status()
                .code(),
            StatusCode::kUnsupported);
  // And our earlier --quantize files were unsigned-in-disguise: a negative stored value is refused.
  EXPECT_EQ(Import(SpecExampleGlb({{"KHR_gaussian_splatting:SCALE", {kShort, true, {-5, 1, 1, 1, 1, 1}}}}, true))
                .status()
                .code(),
            StatusCode::kOutOfRange);
}

#endif  // ATEX_HAVE_TINYGLTF

}  // namespace
}  // namespace atex
