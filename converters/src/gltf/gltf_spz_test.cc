// KHR_gaussian_splatting_compression_spz_2: the base attributes as one SPZ stream. Round trip
// within SPZ's quantisation, the stream's axes (SPZ's RUB storage of glTF's LUF), the document's
// shape (required extension, accessors without data) and hostile files.
#include <cmath>

#include <gtest/gtest.h>

#include "atex/converters/gltf.h"
#include "atex/converters/spz.h"
#include "gltf/gltf_spz.h"
#include "gltf/gltf_test_scene.h"

namespace atex {
namespace {

#ifdef ATEX_HAVE_TINYGLTF

using testing::JoinGlb;
using testing::MakeTestAsset;
using testing::SplitGlb;

double Sigmoid(double x) { return 1.0 / (1.0 + std::exp(-x)); }

// The unit quaternion (w, x, y, z) of Gaussian i, sign fixed so that w >= 0.
std::array<double, 4> UnitRotation(const Gaussians& g, size_t i) {
  std::array<double, 4> q;
  double norm = 0;
  for (int k = 0; k < 4; ++k) norm += double(g.rotations[i * 4 + k]) * g.rotations[i * 4 + k];
  norm = std::sqrt(norm) * (g.rotations[i * 4] < 0 ? -1 : 1);
  for (int k = 0; k < 4; ++k) q[size_t(k)] = g.rotations[i * 4 + k] / norm;
  return q;
}

// Within SPZ's quantisation: 2^-12 positions, 1/16 log-scales, 8-bit opacity and colour, rotations
// to a few thousandths, degree-1 SH to 5 bits.
void ExpectNearSpz(const Gaussians& a, const Gaussians& b) {
  ASSERT_EQ(a.size(), b.size());
  ASSERT_EQ(a.sh_degree, b.sh_degree);
  const size_t k = size_t(a.sh_coeffs());
  for (size_t i = 0; i < a.size(); ++i) {
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(a.positions[i * 3 + c], b.positions[i * 3 + c], 1e-3) << "Gaussian " << i;
      EXPECT_NEAR(a.log_scales[i * 3 + c], b.log_scales[i * 3 + c], 0.04) << "Gaussian " << i;
      EXPECT_NEAR(0.28209479 * a.sh[i * k * 3 + c], 0.28209479 * b.sh[i * k * 3 + c], 0.01) << "Gaussian " << i;
      for (size_t j = 1; j < 4 && j < k; ++j) {
        EXPECT_NEAR(a.sh[(i * k + j) * 3 + c], b.sh[(i * k + j) * 3 + c], 0.07) << "Gaussian " << i << " coef " << j;
      }
    }
    EXPECT_NEAR(Sigmoid(a.opacity_logits[i]), Sigmoid(b.opacity_logits[i]), 0.004) << "Gaussian " << i;
    const auto qa = UnitRotation(a, i), qb = UnitRotation(b, i);
    double dot = 0;
    for (int c = 0; c < 4; ++c) dot += qa[size_t(c)] * qb[size_t(c)];
    EXPECT_GT(std::fabs(dot), 0.999) << "Gaussian " << i;
  }
}

GltfExportOptions SpzOptions() {
  GltfExportOptions options;
  options.spz = true;
  return options;
}

TEST(GltfSpz, RoundTripKeepsTheModelWithinSpzQuantisation) {
  const Asset asset = MakeTestAsset({.count = 2000, .sh_degree = 3, .seed = 11});
  auto glb = EncodeGlb(asset, SpzOptions());
  ASSERT_TRUE(glb.ok()) << glb.status().message();
  auto back = DecodeGltf(glb->data(), glb->size());
  ASSERT_TRUE(back.ok()) << back.status().message();
  ExpectNearSpz(asset.gaussians, back->gaussians);
  // The extensions ride along unchanged: textures and the deformation field are ours, not SPZ's.
  ASSERT_TRUE(back->textures.has_value());
  EXPECT_EQ(back->textures->texels, asset.textures->texels);
  ASSERT_TRUE(back->deformation.has_value());
  EXPECT_EQ(back->deformation->trunk[0].weight, asset.deformation->trunk[0].weight);

  // Much smaller than float accessors (and their bit-exact raw copies).
  auto plain = EncodeGlb(asset);
  ASSERT_TRUE(plain.ok());
  const Asset base_only = [&] {
    Asset a = asset;
    a.textures.reset(), a.deformation.reset();
    a.metadata.texture_mode = "none";
    return a;
  }();
  auto spz_base = EncodeGlb(base_only, SpzOptions());
  GltfExportOptions floats;
  floats.raw_parameters = false, floats.color_fallback = false;
  auto float_base = EncodeGlb(base_only, floats);
  ASSERT_TRUE(spz_base.ok() && float_base.ok());
  EXPECT_LT(spz_base->size() * 5, float_base->size()) << spz_base->size() << " vs " << float_base->size();
}

TEST(GltfSpz, TheDocumentRequiresTheExtensionAndItsAccessorsHoldNoData) {
  const Asset asset = MakeTestAsset({.count = 300, .sh_degree = 1, .textures = false, .deformation = false});
  auto glb = EncodeGlb(asset, SpzOptions());
  ASSERT_TRUE(glb.ok()) << glb.status().message();
  const nlohmann::json doc = SplitGlb(*glb).json;
  EXPECT_NE(std::find(doc["extensionsRequired"].begin(), doc["extensionsRequired"].end(), gltf::kKhrSpz2),
            doc["extensionsRequired"].end());
  const nlohmann::json& primitive = doc["meshes"][0]["primitives"][0];
  const nlohmann::json& ext = primitive["extensions"]["KHR_gaussian_splatting"]["extensions"][gltf::kKhrSpz2];
  ASSERT_TRUE(ext.contains("bufferView"));
  for (const auto& [name, index] : primitive["attributes"].items()) {
    const nlohmann::json& accessor = doc["accessors"][index.get<size_t>()];
    EXPECT_FALSE(accessor.contains("bufferView")) << name;
    EXPECT_EQ(accessor["count"], 300) << name;
  }
  EXPECT_TRUE(doc["accessors"][primitive["attributes"]["POSITION"].get<size_t>()].contains("min"));
  EXPECT_FALSE(primitive["attributes"].contains("COLOR_0"));
}

TEST(GltfSpz, TheStreamStoresSpzAxesOfGltfCoordinates) {
  // The extension reads the stream with SPZ's LUF option, i.e. as glTF's axes: a reader that
  // applies RUB -> LUF (x and z change sign) to the stored values must get the glTF positions.
  const Asset asset = MakeTestAsset({.count = 40, .sh_degree = 0, .textures = false, .deformation = false});
  auto stream = gltf::EncodeSpzForGltf(asset.gaussians);
  ASSERT_TRUE(stream.ok()) << stream.status().message();
  SpzReadOptions stored;
  stored.axes = SpzAxes::kStored;
  auto raw = DecodeSpz(stream->data(), stream->size(), stored);
  ASSERT_TRUE(raw.ok()) << raw.status().message();
  for (size_t i = 0; i < asset.gaussians.size(); ++i) {
    EXPECT_NEAR(-raw->positions[i * 3 + 0], asset.gaussians.positions[i * 3 + 0], 1e-3);
    EXPECT_NEAR(raw->positions[i * 3 + 1], asset.gaussians.positions[i * 3 + 1], 1e-3);
    EXPECT_NEAR(-raw->positions[i * 3 + 2], asset.gaussians.positions[i * 3 + 2], 1e-3);
  }
  SpzInfo info;
  ASSERT_TRUE(DecodeSpz(stream->data(), stream->size(), stored, &info).ok());
  EXPECT_EQ(info.version, gltf::kSpzInGltfVersion);
}

TEST(GltfSpz, MeshoptAndSpzExcludeEachOther) {
  GltfExportOptions options = SpzOptions();
  options.meshopt = true;
  auto glb = EncodeGlb(MakeTestAsset({.count = 10}), options);
  ASSERT_FALSE(glb.ok());
  EXPECT_EQ(glb.status().code(), StatusCode::kInvalidArgument);
}

TEST(GltfSpz, HostileFilesGetErrorsNamingTheExtension) {
  const Asset asset = MakeTestAsset({.count = 200, .sh_degree = 1, .textures = false, .deformation = false});
  auto glb = EncodeGlb(asset, SpzOptions());
  ASSERT_TRUE(glb.ok());
  const testing::GlbParts parts = SplitGlb(*glb);
  const nlohmann::json& ext =
      parts.json["meshes"][0]["primitives"][0]["extensions"]["KHR_gaussian_splatting"]["extensions"][gltf::kKhrSpz2];
  const size_t view = ext["bufferView"].get<size_t>();
  auto decode = [](const nlohmann::json& json, const std::vector<uint8_t>& bin) {
    const std::vector<uint8_t> file = JoinGlb(json, bin);
    return DecodeGltf(file.data(), file.size());
  };
  {  // The view runs past the buffer.
    nlohmann::json json = parts.json;
    json["bufferViews"][view]["byteLength"] = parts.bin.size() + 16;
    auto r = decode(json, parts.bin);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.status().message().find("bufferViews"), std::string::npos) << r.status().message();
  }
  {  // A bufferView index that does not exist.
    nlohmann::json json = parts.json;
    json["meshes"][0]["primitives"][0]["extensions"]["KHR_gaussian_splatting"]["extensions"][gltf::kKhrSpz2]
        ["bufferView"] = 99;
    EXPECT_FALSE(decode(json, parts.bin).ok());
  }
  {  // The accessors count other Gaussians than the stream holds.
    nlohmann::json json = parts.json;
    json["accessors"][json["meshes"][0]["primitives"][0]["attributes"]["POSITION"].get<size_t>()]["count"] = 199;
    auto r = decode(json, parts.bin);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), StatusCode::kCorrupt) << r.status().message();
  }
  {  // Every byte of the stream flipped in turn, then truncated streams: errors or a model, never a crash.
    const size_t offset = parts.json["bufferViews"][view].value("byteOffset", size_t{0});
    const size_t length = parts.json["bufferViews"][view]["byteLength"].get<size_t>();
    for (size_t i = 0; i < length; i += 7) {
      std::vector<uint8_t> bin = parts.bin;
      bin[offset + i] ^= 0x5a;
      (void)decode(parts.json, bin);
    }
    for (size_t cut : {size_t{0}, size_t{1}, length / 2, length - 1}) {
      nlohmann::json json = parts.json;
      json["bufferViews"][view]["byteLength"] = cut;
      EXPECT_FALSE(decode(json, parts.bin).ok()) << "stream cut to " << cut << " bytes";
    }
  }
}

#endif  // ATEX_HAVE_TINYGLTF

}  // namespace
}  // namespace atex
