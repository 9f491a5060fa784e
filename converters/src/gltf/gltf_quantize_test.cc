// --quantize (KHR_mesh_quantization): the document is read by hand to check what a third-party
// player sees (the node transform applied to the integers lands on the upright asset), and our
// importer must give the asset back within the error bounds stated in gltf_quantize.h.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>

#include <gtest/gtest.h>

#include "atex/converters/gltf.h"
#include "gltf/gltf_test_scene.h"

namespace atex {
namespace {

using nlohmann::json;
using testing::GlbParts;

// A scene with the cases the bounds treat apart: a splat larger than the scene's half-extent
// (clipped), one far below one step (raised to one step), opacities at 0 and 1.
Asset QuantizeTestAsset() {
  Asset asset = testing::MakeTestAsset({.count = 300, .sh_degree = 2});
  Gaussians& g = asset.gaussians;
  g.log_scales[0] = 5.0f;     // e^5 = 148 > half-extent (about 2)
  g.log_scales[4] = -20.0f;   // 2e-9, far below one step (about 6e-5)
  g.opacity_logits[2] = -40;  // opacity 4e-18
  g.opacity_logits[3] = 40;   // opacity 1 - 4e-18
  return asset;
}

std::vector<uint8_t> Encode(const Asset& asset, bool meshopt) {
  GltfExportOptions options;
  options.quantize = true;
  options.meshopt = meshopt;
  auto glb = EncodeGlb(asset, options);
  EXPECT_TRUE(glb.ok()) << glb.status().ToString();
  return glb.ok() ? *glb : std::vector<uint8_t>{};
}

// The half-extent the frame must use, computed here independently.
double Reach(const Gaussians& g) {
  double reach = 0;
  for (int k = 0; k < 3; ++k) {
    double lo = INFINITY, hi = -INFINITY;
    for (size_t i = 0; i < g.size(); ++i) {
      lo = std::min(lo, double(g.positions[i * 3 + k]));
      hi = std::max(hi, double(g.positions[i * 3 + k]));
    }
    reach = std::max(reach, 0.5 * (hi - lo));
  }
  return reach;
}

const json& Attributes(const GlbParts& p) { return p.json["meshes"][0]["primitives"][0]["attributes"]; }

// Component `c` of element `i` of an integer accessor of a plain GLB, as stored.
long Stored(const GlbParts& p, int accessor, size_t i, int c) {
  const json& a = p.json["accessors"][accessor];
  const json& v = p.json["bufferViews"][a["bufferView"].get<int>()];
  const size_t at = v.value("byteOffset", size_t{0}) + a.value("byteOffset", size_t{0}) +
                    i * v["byteStride"].get<size_t>();
  switch (a["componentType"].get<int>()) {
    case 5120: return long(int8_t(p.bin[at + size_t(c)]));
    case 5122: { int16_t x; std::memcpy(&x, &p.bin[at + 2 * size_t(c)], 2); return x; }
    case 5123: { uint16_t x; std::memcpy(&x, &p.bin[at + 2 * size_t(c)], 2); return x; }
    default: ADD_FAILURE() << "component type " << a["componentType"]; return 0;
  }
}

TEST(GltfQuantize, DocumentUsesNormalizedIntegersTheExtensionsAllow) {
  const Asset asset = QuantizeTestAsset();
  const GlbParts p = testing::SplitGlb(Encode(asset, false));
  const json& attrs = Attributes(p);
  auto type_of = [&](const char* name) { return p.json["accessors"][attrs[name].get<int>()]; };
  EXPECT_EQ(type_of("POSITION")["componentType"], 5122);
  EXPECT_EQ(type_of("KHR_gaussian_splatting:ROTATION")["componentType"], 5120);
  EXPECT_EQ(type_of("KHR_gaussian_splatting:SCALE")["componentType"], 5123);  // unsigned: linear, never negative
  EXPECT_EQ(type_of("KHR_gaussian_splatting:OPACITY")["componentType"], 5123);
  for (const char* name : {"POSITION", "KHR_gaussian_splatting:ROTATION", "KHR_gaussian_splatting:SCALE",
                           "KHR_gaussian_splatting:OPACITY"}) {
    EXPECT_TRUE(type_of(name).value("normalized", false)) << name;
  }
  EXPECT_EQ(type_of("KHR_gaussian_splatting:SH_DEGREE_2_COEF_4")["componentType"], 5126);  // float only
  EXPECT_FALSE(attrs.contains("ATEX_gaussian_deformation:RAW_ROTATION"));  // would undo the saving
  // glTF: vertex attribute elements 4-byte aligned; integer accessors' bounds are integers.
  for (const auto& [name, index] : attrs.items()) {
    const json& a = p.json["accessors"][index.get<int>()];
    EXPECT_EQ(a.value("byteOffset", 0) % 4, 0) << name;
    EXPECT_EQ(p.json["bufferViews"][a["bufferView"].get<int>()]["byteStride"].get<int>() % 4, 0) << name;
  }
  EXPECT_TRUE(type_of("POSITION")["min"][0].is_number_integer());
  const json& required = p.json["extensionsRequired"];
  EXPECT_NE(std::find(required.begin(), required.end(), "KHR_mesh_quantization"), required.end());

  // What a player computes: node (T R S) applied to the dequantised integers. It must equal the
  // asset's positions turned upright (metadata.axes "opencv": y down, 180 degrees about x).
  const json& node = p.json["nodes"][0];
  const double s = node["scale"][0].get<double>();
  EXPECT_EQ(node["scale"][1].get<double>(), s);
  EXPECT_EQ(node["scale"][2].get<double>(), s);
  const double reach = Reach(asset.gaussians);
  EXPECT_GE(s, reach);
  EXPECT_LE(s, reach * (1 + 1e-6));
  const std::array<double, 9> r = UpRotationMatrix(UpAxis::kNegY);
  const int position = attrs["POSITION"].get<int>();
  const Gaussians& g = asset.gaussians;
  for (size_t i = 0; i < g.size(); ++i) {
    std::array<double, 3> local;
    for (int k = 0; k < 3; ++k) local[k] = s * std::max(double(Stored(p, position, i, k)) / 32767.0, -1.0);
    for (int row = 0; row < 3; ++row) {
      const double world = node["translation"][row].get<double>() + r[row * 3] * local[0] +
                           r[row * 3 + 1] * local[1] + r[row * 3 + 2] * local[2];
      const double expected = r[row * 3] * g.positions[i * 3] + r[row * 3 + 1] * g.positions[i * 3 + 1] +
                              r[row * 3 + 2] * g.positions[i * 3 + 2];
      EXPECT_NEAR(world, expected, s / 65534 + 1e-6) << "Gaussian " << i << " axis " << row;
    }
  }
  // Scales are in the node's units too: the player multiplies them by s.
  const int scale = attrs["KHR_gaussian_splatting:SCALE"].get<int>();
  EXPECT_EQ(Stored(p, scale, 0, 0), 65535);  // clipped at s
  EXPECT_EQ(Stored(p, scale, 1, 1), 1);      // one step
  for (size_t i = 2; i < g.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(s * double(Stored(p, scale, i, k)) / 65535, std::exp(double(g.log_scales[i * 3 + size_t(k)])),
                  s / 131070 * (1 + 1e-6))
          << "Gaussian " << i;
    }
  }
}

#ifdef ATEX_HAVE_TINYGLTF
TEST(GltfQuantize, ImportIsWithinTheStatedError) {
  const Asset asset = QuantizeTestAsset();
  const Gaussians& g = asset.gaussians;
  const double reach = Reach(g);
  for (bool meshopt : {false, true}) {
#ifndef ATEX_HAVE_MESHOPT
    if (meshopt) continue;
#endif
    SCOPED_TRACE(meshopt ? "quantize + meshopt" : "quantize");
    const std::vector<uint8_t> glb = Encode(asset, meshopt);
    auto back = DecodeGltf(glb.data(), glb.size());
    ASSERT_TRUE(back.ok()) << back.status().ToString();
    const Gaussians& b = back->gaussians;
    ASSERT_EQ(b.size(), g.size());
    const double s = reach * (1 + 1e-6);
    size_t exact_positions = 0;
    for (size_t i = 0; i < g.size(); ++i) {
      for (int k = 0; k < 3; ++k) {
        const size_t j = i * 3 + size_t(k);
        EXPECT_NEAR(b.positions[j], g.positions[j], s / 65534 + 1e-6) << i;
        exact_positions += b.positions[j] == g.positions[j];
        const double want = std::clamp(std::exp(double(g.log_scales[j])), s / 65535, s);
        EXPECT_NEAR(std::exp(double(b.log_scales[j])), want, s / 131070 * (1 + 1e-4)) << i;
      }
      const double norm = std::sqrt(double(g.rotations[i * 4]) * g.rotations[i * 4] +
                                    double(g.rotations[i * 4 + 1]) * g.rotations[i * 4 + 1] +
                                    double(g.rotations[i * 4 + 2]) * g.rotations[i * 4 + 2] +
                                    double(g.rotations[i * 4 + 3]) * g.rotations[i * 4 + 3]);
      double dot = 0;  // q and -q are one rotation (meshopt's QUATERNION filter may flip the sign)
      for (int c = 0; c < 4; ++c) dot += double(b.rotations[i * 4 + c]) * g.rotations[i * 4 + c];
      const double sign = dot < 0 ? -1 : 1;
      for (int c = 0; c < 4; ++c) {
        EXPECT_NEAR(sign * b.rotations[i * 4 + c], g.rotations[i * 4 + c] / norm, 0.5 / 127 + 1e-6) << i;
      }
      const double o = 1 / (1 + std::exp(-double(g.opacity_logits[i])));
      EXPECT_NEAR(1 / (1 + std::exp(-double(b.opacity_logits[i]))), o, 0.5 / 65535 + 1e-6) << i;
    }
    EXPECT_LT(exact_positions, g.size());  // it did quantise
    EXPECT_TRUE(testing::SameBits(b.sh, g.sh));  // SH stays float (no --meshopt-bits)
    ASSERT_TRUE(back->textures.has_value());
    EXPECT_TRUE(testing::SameBits(back->textures->texels, asset.textures->texels));
    ASSERT_TRUE(back->deformation.has_value());
    EXPECT_TRUE(testing::SameBits(back->deformation->planes[0][0], asset.deformation->planes[0][0]));
    EXPECT_EQ(back->metadata.axes, asset.metadata.axes);
  }
}

TEST(GltfQuantize, SmallerThanFloatsAndOnePointScenesWork) {
  Asset asset = testing::MakeTestAsset({.count = 1, .sh_degree = 0, .textures = false, .deformation = false});
  const std::vector<uint8_t> glb = Encode(asset, false);
  auto back = DecodeGltf(glb.data(), glb.size());
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  for (int k = 0; k < 3; ++k) EXPECT_EQ(back->gaussians.positions[size_t(k)], asset.gaussians.positions[size_t(k)]);

  const Asset big = testing::MakeTestAsset({.count = 500, .sh_degree = 0, .textures = false, .deformation = false});
  GltfExportOptions plain;
  plain.raw_parameters = false;
  auto floats = EncodeGlb(big, plain);
  ASSERT_TRUE(floats.ok());
  // Per Gaussian: floats 12 + 16 + 12 + 4 + 12 + 4 = 60 bytes; quantised 8 + 4 + 8 + 4 + 12 + 4 = 40.
  EXPECT_LT(double(Encode(big, false).size()), 0.7 * double(floats->size()));
}

#endif  // ATEX_HAVE_TINYGLTF

TEST(GltfQuantize, NotWithSpz) {
  GltfExportOptions options;
  options.quantize = true;
  options.spz = true;
  EXPECT_EQ(EncodeGlb(testing::MakeTestAsset({.count = 4}), options).status().code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace atex
