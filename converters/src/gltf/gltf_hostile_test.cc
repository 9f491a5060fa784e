// Hostile input: truncations, bit flips and forged documents must give clean errors
// (never a crash, never a huge allocation).
#include <cstring>
#include <fstream>
#include <functional>
#include <random>

#include <gtest/gtest.h>

#include "atex/converters/gltf.h"
#include "core/test_support.h"
#include "gltf/gltf_test_scene.h"

namespace atex {
namespace {

#ifdef ATEX_HAVE_TINYGLTF

using nlohmann::json;
using testing::GlbParts;

std::vector<uint8_t> ValidGlb(bool meshopt = false, bool quantize = false) {
  const Asset asset = testing::MakeTestAsset({.count = 12, .sh_degree = 1});
  GltfExportOptions options;
  options.meshopt = meshopt;
  options.quantize = quantize;
  auto glb = EncodeGlb(asset, options);
  EXPECT_TRUE(glb.ok()) << glb.status().ToString();
  return *glb;
}

StatusCode Decode(const std::vector<uint8_t>& bytes) {
  GltfImportOptions options;
  options.max_decoded_bytes = 64 << 20;
  return DecodeGltf(bytes.data(), bytes.size(), options).status().code();
}

// Applies `edit` to the JSON of a valid GLB and decodes the result.
StatusCode DecodeEdited(const std::function<void(json&)>& edit, bool meshopt = false, bool quantize = false) {
  GlbParts parts = testing::SplitGlb(ValidGlb(meshopt, quantize));
  edit(parts.json);
  return Decode(testing::JoinGlb(parts.json, parts.bin));
}

int AttributeAccessor(const json& doc, const char* name) {
  return doc["meshes"][0]["primitives"][0]["attributes"][name].get<int>();
}

TEST(GltfHostile, EveryTruncationFailsCleanly) {
  for (bool quantize : {false, true}) {
    const std::vector<uint8_t> glb = ValidGlb(false, quantize);
    ASSERT_EQ(Decode(glb), StatusCode::kOk);
    for (size_t cut = 0; cut < glb.size(); cut += (cut < 64 ? 1 : 37)) {
      std::vector<uint8_t> part(glb.begin(), glb.begin() + long(cut));
      EXPECT_NE(Decode(part), StatusCode::kOk) << "cut at " << cut;
    }
  }
}

TEST(GltfHostile, RandomByteFlipsNeverCrash) {
  for (int variant = 0; variant < 4; ++variant) {
    const bool meshopt = variant & 1, quantize = variant & 2;
#ifndef ATEX_HAVE_MESHOPT
    if (meshopt) continue;
#endif
    const std::vector<uint8_t> glb = ValidGlb(meshopt, quantize);
    std::mt19937 rng(7);
    for (int trial = 0; trial < 400; ++trial) {
      std::vector<uint8_t> bytes = glb;
      const int flips = 1 + trial % 4;
      for (int f = 0; f < flips; ++f) bytes[rng() % bytes.size()] ^= uint8_t(1u << (rng() % 8));
      (void)Decode(bytes);  // any status; the point is no crash (ASan/UBSan build checks memory)
    }
  }
}

TEST(GltfHostile, ContainerErrors) {
  std::vector<uint8_t> glb = ValidGlb();
  EXPECT_EQ(Decode({'h', 'e', 'l', 'l', 'o'}), StatusCode::kBadMagic);
  std::vector<uint8_t> v3 = glb;
  v3[4] = 3;
  EXPECT_EQ(Decode(v3), StatusCode::kUnsupportedVersion);
  std::vector<uint8_t> long_header = glb;
  long_header[8] = 0xff, long_header[9] = 0xff, long_header[10] = 0xff;
  EXPECT_EQ(Decode(long_header), StatusCode::kTruncated);
  const std::string not_json = "{\"asset\": ";
  EXPECT_EQ(Decode(std::vector<uint8_t>(not_json.begin(), not_json.end())), StatusCode::kCorrupt);
  std::string deep = "{\"a\":";
  for (int i = 0; i < 200000; ++i) deep += "[";
  for (int i = 0; i < 200000; ++i) deep += "]";
  deep += "}";
  EXPECT_EQ(Decode(std::vector<uint8_t>(deep.begin(), deep.end())), StatusCode::kLimitExceeded);
}

TEST(GltfHostile, ForgedAccessorsAndViews) {
  EXPECT_EQ(DecodeEdited([](json& d) { d["accessors"][AttributeAccessor(d, "POSITION")]["count"] = 1ull << 40; }),
            StatusCode::kCorrupt);
  EXPECT_EQ(DecodeEdited([](json& d) { d["accessors"][AttributeAccessor(d, "POSITION")]["byteOffset"] = 1 << 30; }),
            StatusCode::kCorrupt);
  EXPECT_EQ(DecodeEdited([](json& d) { d["bufferViews"][0]["byteLength"] = 1 << 30; }), StatusCode::kCorrupt);
  EXPECT_EQ(DecodeEdited([](json& d) { d["bufferViews"][0]["byteOffset"] = -4; }), StatusCode::kCorrupt);
  EXPECT_EQ(DecodeEdited([](json& d) { d["bufferViews"][0]["buffer"] = 7; }), StatusCode::kCorrupt);
  EXPECT_EQ(DecodeEdited([](json& d) { d["buffers"][0]["byteLength"] = 1 << 30; }), StatusCode::kTruncated);
  EXPECT_EQ(DecodeEdited([](json& d) { d["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 9999; }),
            StatusCode::kCorrupt);
  EXPECT_EQ(DecodeEdited([](json& d) { d["accessors"][AttributeAccessor(d, "POSITION")]["type"] = "VEC2"; }),
            StatusCode::kCorrupt);
  EXPECT_EQ(DecodeEdited(
                [](json& d) { d["accessors"][AttributeAccessor(d, "KHR_gaussian_splatting:OPACITY")]["count"] = 3; }),
            StatusCode::kCorrupt);
  EXPECT_EQ(DecodeEdited([](json& d) { d["meshes"][0]["primitives"][0]["mode"] = 4; }), StatusCode::kCorrupt);
  EXPECT_EQ(DecodeEdited(
                [](json& d) { d["meshes"][0]["primitives"][0]["attributes"].erase("KHR_gaussian_splatting:SCALE"); }),
            StatusCode::kCorrupt);
  EXPECT_EQ(
      DecodeEdited([](json& d) { d["meshes"][0]["primitives"][0]["extensions"].erase("KHR_gaussian_splatting"); }),
      StatusCode::kUnsupported);
  EXPECT_EQ(DecodeEdited([](json& d) { d["nodes"][0]["children"] = {0}; }), StatusCode::kCorrupt);  // cycle
  EXPECT_EQ(DecodeEdited([](json& d) { d["extras"]["atex"]["version"] = 99; }), StatusCode::kUnsupportedVersion);
  EXPECT_EQ(DecodeEdited([](json& d) { d["extras"]["atex"]["metadata"]["time_min"] = "soon"; }), StatusCode::kCorrupt);
}

TEST(GltfHostile, ForgedExtensionPayloads) {
  auto sub = [](json& d) -> json& {
    return d["meshes"][0]["primitives"][0]["extensions"]["KHR_gaussian_splatting"]["extensions"];
  };
  EXPECT_EQ(DecodeEdited([&](json& d) { sub(d)["ATEX_gaussian_textures"]["texels"] = 12345; }), StatusCode::kCorrupt);
  EXPECT_EQ(
      DecodeEdited([&](json& d) { sub(d)["ATEX_gaussian_textures"]["texels"] = AttributeAccessor(d, "POSITION"); }),
      StatusCode::kCorrupt);
  EXPECT_EQ(DecodeEdited([&](json& d) { sub(d)["ATEX_gaussian_deformation"]["field"]["grid"]["channels"] = 1 << 30; }),
            StatusCode::kOutOfRange);
  EXPECT_EQ(DecodeEdited([&](json& d) { sub(d)["ATEX_gaussian_deformation"]["field"]["grid"]["channels"] = 4; }),
            StatusCode::kCorrupt);  // plane accessors no longer match C*res*res
  EXPECT_EQ(
      DecodeEdited([&](json& d) { sub(d)["ATEX_gaussian_deformation"]["field"]["heads"]["wings"] = json::array(); }),
      StatusCode::kCorrupt);
  EXPECT_EQ(DecodeEdited([&](json& d) { sub(d)["ATEX_gaussian_deformation"]["field"]["trunk"] = json::array(); }),
            StatusCode::kCorrupt);
}

TEST(GltfHostile, BadValuesInTheBinaryData) {
  GlbParts parts = testing::SplitGlb(ValidGlb());
  // Texture side 3 in the layout attribute.
  {
    GlbParts p = parts;
    const auto& a = p.json["accessors"][AttributeAccessor(p.json, "ATEX_gaussian_textures:LAYOUT")];
    const size_t at = p.json["bufferViews"][a["bufferView"].get<int>()]["byteOffset"].get<size_t>();
    p.bin[at] = 3;
    EXPECT_EQ(Decode(testing::JoinGlb(p.json, p.bin)), StatusCode::kOutOfRange);
  }
  // NaN in POSITION.
  {
    GlbParts p = parts;
    const auto& a = p.json["accessors"][AttributeAccessor(p.json, "POSITION")];
    const size_t at = p.json["bufferViews"][a["bufferView"].get<int>()]["byteOffset"].get<size_t>();
    const uint32_t nan_bits = 0x7fc00000;
    std::memcpy(&p.bin[at + 4], &nan_bits, 4);
    EXPECT_EQ(Decode(testing::JoinGlb(p.json, p.bin)), StatusCode::kOutOfRange);
  }
}

// The quantised file's new paths: integer types the extension does not allow, integers that must
// be normalized, and the node's dequantisation frame (uniform, not mirrored, finite).
TEST(GltfHostile, ForgedQuantizedAccessorsAndFrames) {
  auto edit = [](const std::function<void(json&)>& f) { return DecodeEdited(f, false, true); };
  auto accessor = [](json& d, const char* name) -> json& { return d["accessors"][AttributeAccessor(d, name)]; };
  ASSERT_EQ(edit([](json&) {}), StatusCode::kOk);
  EXPECT_EQ(edit([&](json& d) { accessor(d, "KHR_gaussian_splatting:ROTATION")["normalized"] = false; }),
            StatusCode::kCorrupt);
  EXPECT_EQ(edit([&](json& d) { accessor(d, "KHR_gaussian_splatting:OPACITY")["normalized"] = false; }),
            StatusCode::kCorrupt);
  EXPECT_EQ(edit([&](json& d) { accessor(d, "KHR_gaussian_splatting:OPACITY")["componentType"] = 5122; }),
            StatusCode::kCorrupt);  // signed opacity
  EXPECT_EQ(edit([&](json& d) { accessor(d, "KHR_gaussian_splatting:ROTATION")["componentType"] = 5121; }),
            StatusCode::kCorrupt);  // unsigned rotation
  EXPECT_EQ(edit([&](json& d) { accessor(d, "KHR_gaussian_splatting:SCALE")["componentType"] = 5120; }),
            StatusCode::kUnsupported);  // signed byte scales: not in the extension, nor ever written by atex
  EXPECT_EQ(edit([&](json& d) { accessor(d, "KHR_gaussian_splatting:SCALE")["type"] = "VEC4"; }), StatusCode::kCorrupt);
  EXPECT_EQ(edit([&](json& d) { accessor(d, "KHR_gaussian_splatting:SH_DEGREE_0_COEF_0")["componentType"] = 5122; }),
            StatusCode::kCorrupt);  // SH is float only
  // A byteStride smaller than POSITION's 6-byte element.
  EXPECT_EQ(
      edit([&](json& d) { d["bufferViews"][accessor(d, "POSITION")["bufferView"].get<int>()]["byteStride"] = 4; }),
      StatusCode::kCorrupt);
  EXPECT_EQ(edit([](json& d) { d["nodes"][0]["scale"] = {1.0, 2.0, 1.0}; }), StatusCode::kUnsupported);
  // The same in a float file (its node is only the upright turn): refused, not ignored.
  EXPECT_EQ(DecodeEdited([](json& d) { d["nodes"][0]["scale"] = {1.0, 2.0, 1.0}; }), StatusCode::kUnsupported);
  EXPECT_EQ(edit([](json& d) { d["nodes"][0]["scale"] = {0.0, 0.0, 0.0}; }), StatusCode::kUnsupported);
  EXPECT_EQ(edit([](json& d) { d["nodes"][0]["scale"] = {-1.0, -1.0, -1.0}; }), StatusCode::kUnsupported);
  EXPECT_NE(edit([](json& d) { d["nodes"][0]["scale"] = {1e300, 1e300, 1e300}; }), StatusCode::kOk);
  EXPECT_NE(edit([](json& d) { d["nodes"][0]["translation"] = {1e300, 0.0, 0.0}; }), StatusCode::kOk);
  // A negative stored scale (the extension's linear scales must be positive) in the SHORT layout of
  // atex's earlier --quantize files, which our importer still reads.
  GlbParts p = testing::SplitGlb(ValidGlb(false, true));
  json& a = p.json["accessors"][AttributeAccessor(p.json, "KHR_gaussian_splatting:SCALE")];
  a["componentType"] = 5122;
  const size_t at = p.json["bufferViews"][a["bufferView"].get<int>()]["byteOffset"].get<size_t>();
  p.bin[at + 1] = 0x80;  // int16 component 0 of element 0 becomes negative
  EXPECT_EQ(Decode(testing::JoinGlb(p.json, p.bin)), StatusCode::kOutOfRange);
}

TEST(GltfHostile, ExternalUrisStayInTheFolder) {
  atex::testing::TempDir dir;
  GlbParts parts = testing::SplitGlb(ValidGlb());
  for (const char* uri :
       {"../secret.bin", "/etc/passwd", "file:///etc/passwd", "http://example.com/x.bin", "missing.bin"}) {
    json doc = parts.json;
    doc["buffers"][0]["uri"] = uri;
    const std::string text = doc.dump();
    const auto path = dir / "forged.gltf";
    {
      std::ofstream out(path, std::ios::binary);
      out << text;
    }
    auto result = ReadGltfFile(path.string());
    EXPECT_FALSE(result.ok()) << uri;
  }
}

#ifdef ATEX_HAVE_MESHOPT
TEST(GltfHostile, ForgedMeshoptViews) {
  auto first_ext = [](json& d) -> json& { return d["bufferViews"][0]["extensions"]["EXT_meshopt_compression"]; };
  // A count that the compressed bytes cannot hold (expansion bound), and a mismatching byteLength.
  EXPECT_EQ(DecodeEdited([&](json& d) {
              first_ext(d)["count"] = 1 << 24;
              d["bufferViews"][0]["byteLength"] = (1 << 24) * first_ext(d)["byteStride"].get<int>();
            }, true),
            StatusCode::kCorrupt);
  EXPECT_EQ(DecodeEdited([&](json& d) { first_ext(d)["count"] = 3; }, true), StatusCode::kCorrupt);
  EXPECT_EQ(DecodeEdited([&](json& d) { first_ext(d)["byteLength"] = 1 << 30; }, true), StatusCode::kCorrupt);
  EXPECT_EQ(DecodeEdited([&](json& d) { first_ext(d)["buffer"] = 1; }, true), StatusCode::kCorrupt);  // the fallback
  EXPECT_EQ(DecodeEdited([&](json& d) { first_ext(d)["mode"] = "SPLATS"; }, true), StatusCode::kCorrupt);
  EXPECT_EQ(DecodeEdited([&](json& d) { d["bufferViews"][0].erase("extensions"); }, true), StatusCode::kCorrupt);
  EXPECT_EQ(DecodeEdited([&](json& d) { first_ext(d)["byteLength"] = 3; }, true), StatusCode::kCorrupt);
}
#endif

#endif  // ATEX_HAVE_TINYGLTF

}  // namespace
}  // namespace atex
