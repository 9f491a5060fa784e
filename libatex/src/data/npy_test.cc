// .npy/.npz: header variants written by numpy, the real data files, and
// refusals (Fortran order, pickles, forged shapes, bad headers).
#include <cmath>
#include <cstring>

#include <gtest/gtest.h>

#include "atex/npy.h"
#include "core/test_support.h"

namespace atex {
namespace {

// An .npy byte string with a given header text (padded as numpy does) and payload.
std::vector<uint8_t> MakeNpy(const std::string& dict, const std::vector<uint8_t>& payload, int major = 1) {
  std::string header = dict;
  const size_t prefix = major == 1 ? 10 : 12;
  while ((prefix + header.size() + 1) % 64 != 0) header += ' ';
  header += '\n';
  std::vector<uint8_t> out = {0x93, 'N', 'U', 'M', 'P', 'Y', static_cast<uint8_t>(major), 0};
  const uint32_t len = static_cast<uint32_t>(header.size());
  out.push_back(len & 0xFF);
  out.push_back((len >> 8) & 0xFF);
  if (major != 1) {
    out.push_back((len >> 16) & 0xFF);
    out.push_back(len >> 24);
  }
  out.insert(out.end(), header.begin(), header.end());
  out.insert(out.end(), payload.begin(), payload.end());
  return out;
}

template <typename T>
std::vector<uint8_t> Raw(const std::vector<T>& v) {
  std::vector<uint8_t> out(v.size() * sizeof(T));
  if (!v.empty()) std::memcpy(out.data(), v.data(), out.size());
  return out;
}

TEST(Npy, ParsesTheHeaderVariantsNumpyWrites) {
  const std::vector<float> values = {1.5f, -2.0f, 3.25f, 0.0f, 8.0f, 9.5f};
  for (const std::string& dict : {
           std::string("{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3), }"),
           std::string("{\"descr\": \"<f4\", \"fortran_order\": False, \"shape\": (2,3)}"),
           std::string("{'shape': (2L, 3L), 'fortran_order': False, 'descr': '<f4'}"),  // Python 2 numpy
       }) {
    for (int major : {1, 2, 3}) {
      const std::vector<uint8_t> bytes = MakeNpy(dict, Raw(values), major);
      auto array = DecodeNpy(bytes.data(), bytes.size(), "t");
      ASSERT_TRUE(array.ok()) << dict << " v" << major << ": " << array.status().ToString();
      EXPECT_EQ(array->shape, (std::vector<int64_t>{2, 3}));
      EXPECT_EQ(array->ToFloat(), values);
    }
  }
}

TEST(Npy, DtypesAndByteOrder) {
  {
    const std::vector<uint8_t> bytes =
        MakeNpy("{'descr': '|u1', 'fortran_order': False, 'shape': (3,), }", {0, 7, 255});
    auto a = DecodeNpy(bytes.data(), bytes.size(), "u1");
    ASSERT_TRUE(a.ok());
    EXPECT_EQ(a->ToDouble(), (std::vector<double>{0, 7, 255}));
  }
  {
    const std::vector<uint8_t> bytes =
        MakeNpy("{'descr': '<i8', 'fortran_order': False, 'shape': (), }", Raw(std::vector<int64_t>{-420}));
    auto a = DecodeNpy(bytes.data(), bytes.size(), "i8");
    ASSERT_TRUE(a.ok());
    EXPECT_TRUE(a->shape.empty());
    EXPECT_EQ(*a->Scalar("i8"), -420.0);
  }
  {  // big-endian float64: 1.0 = 3F F0 00 00 00 00 00 00
    const std::vector<uint8_t> bytes = MakeNpy("{'descr': '>f8', 'fortran_order': False, 'shape': (1,), }",
                                               {0x3F, 0xF0, 0, 0, 0, 0, 0, 0});
    auto a = DecodeNpy(bytes.data(), bytes.size(), ">f8");
    ASSERT_TRUE(a.ok());
    EXPECT_EQ(a->ToDouble()[0], 1.0);
  }
  {  // float16: 0x3C00 = 1, 0xC000 = -2, 0x0001 = 2^-24 (subnormal), 0x7BFF = 65504
    const std::vector<uint8_t> bytes = MakeNpy("{'descr': '<f2', 'fortran_order': False, 'shape': (4,), }",
                                               Raw(std::vector<uint16_t>{0x3C00, 0xC000, 0x0001, 0x7BFF}));
    auto a = DecodeNpy(bytes.data(), bytes.size(), "f2");
    ASSERT_TRUE(a.ok());
    EXPECT_EQ(a->ToDouble(), (std::vector<double>{1.0, -2.0, std::ldexp(1.0, -24), 65504.0}));
  }
  {
    const std::vector<uint8_t> bytes = MakeNpy("{'descr': '|b1', 'fortran_order': False, 'shape': (2,), }", {0, 1});
    auto a = DecodeNpy(bytes.data(), bytes.size(), "b1");
    ASSERT_TRUE(a.ok());
    EXPECT_EQ(a->ToDouble(), (std::vector<double>{0, 1}));
  }
  {  // empty array
    const std::vector<uint8_t> bytes = MakeNpy("{'descr': '<f4', 'fortran_order': False, 'shape': (0, 5), }", {});
    auto a = DecodeNpy(bytes.data(), bytes.size(), "empty");
    ASSERT_TRUE(a.ok());
    EXPECT_EQ(a->element_count(), 0u);
  }
}

TEST(Npy, Refusals) {
  auto code = [](const std::vector<uint8_t>& b) { return DecodeNpy(b.data(), b.size(), "x").status().code(); };
  const std::vector<uint8_t> four_floats = Raw(std::vector<float>{1, 2, 3, 4});
  EXPECT_EQ(code(MakeNpy("{'descr': '<f4', 'fortran_order': True, 'shape': (2, 2), }", four_floats)),
            StatusCode::kUnsupported);
  EXPECT_EQ(code(MakeNpy("{'descr': '|O', 'fortran_order': False, 'shape': (1,), }", {0x80, 2, 'N', '.'})),
            StatusCode::kUnsupported);
  EXPECT_EQ(code(MakeNpy("{'descr': [('a', '<f4')], 'fortran_order': False, 'shape': (1,), }", {0, 0, 0, 0})),
            StatusCode::kUnsupported);
  EXPECT_EQ(code(MakeNpy("{'descr': '<U3', 'fortran_order': False, 'shape': (1,), }", std::vector<uint8_t>(12))),
            StatusCode::kUnsupported);
  // Forged shapes: more elements than bytes, overflowing products, and extra bytes.
  EXPECT_EQ(code(MakeNpy("{'descr': '<f4', 'fortran_order': False, 'shape': (1000000000, 1000000000), }", four_floats)),
            StatusCode::kTruncated);
  EXPECT_EQ(code(MakeNpy("{'descr': '<f8', 'fortran_order': False, 'shape': (4611686018427387904, 4), }", four_floats)),
            StatusCode::kTruncated);
  EXPECT_EQ(code(MakeNpy("{'descr': '<f4', 'fortran_order': False, 'shape': (3,), }", four_floats)),
            StatusCode::kCorrupt);
  EXPECT_EQ(code(MakeNpy("{'descr': '<f4', 'fortran_order': False, 'shape': (5,), }", four_floats)),
            StatusCode::kTruncated);
  // Malformed headers.
  EXPECT_EQ(code(MakeNpy("{'descr': '<f4', 'shape': (4,), }", four_floats)), StatusCode::kCorrupt);
  EXPECT_EQ(code(MakeNpy("{'descr': '<f4', 'fortran_order': False, 'shape': (-4,), }", four_floats)),
            StatusCode::kCorrupt);
  EXPECT_EQ(code(MakeNpy("{'descr': '<f4', 'fortran_order': False, 'shape': (4,), 'x': 1}", four_floats)),
            StatusCode::kCorrupt);
  EXPECT_EQ(code(MakeNpy("__import__('os').system('true')", four_floats)), StatusCode::kCorrupt);
  EXPECT_EQ(code(MakeNpy("{'descr': '<f4', 'fortran_order': False, 'shape': (99999999999999999999,), }", four_floats)),
            StatusCode::kCorrupt);
  std::vector<uint8_t> bad_magic = MakeNpy("{'descr': '<f4', 'fortran_order': False, 'shape': (4,), }", four_floats);
  bad_magic[1] = 'X';
  EXPECT_EQ(code(bad_magic), StatusCode::kBadMagic);
  std::vector<uint8_t> v9 = MakeNpy("{'descr': '<f4', 'fortran_order': False, 'shape': (4,), }", four_floats);
  v9[6] = 9;
  EXPECT_EQ(code(v9), StatusCode::kUnsupportedVersion);
  // Header length beyond the data, and every truncation of a valid file.
  const std::vector<uint8_t> good = MakeNpy("{'descr': '<f4', 'fortran_order': False, 'shape': (4,), }", four_floats);
  for (size_t cut = 0; cut < good.size(); ++cut) {
    EXPECT_FALSE(DecodeNpy(good.data(), cut, "cut").ok()) << cut;
  }
}

TEST(Npy, EncodeRoundTripAndNpz) {
  const NpyArray a = NpyArray::FromFloats({2, 2}, {1, 2, 3, 4});
  const NpyArray b = NpyArray::FromDoubles({3}, {0.5, -1, 1e300});
  const std::vector<uint8_t> npy = EncodeNpy(a);
  EXPECT_EQ(npy.size() % 16, 0u);
  auto back = DecodeNpy(npy.data(), npy.size(), "a");
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(back->shape, a.shape);
  EXPECT_EQ(back->data, a.data);
  for (bool compress : {false, true}) {
    const std::vector<uint8_t> npz = EncodeNpz({{"a", a}, {"b", b}}, compress);
    auto arrays = DecodeNpz(npz.data(), npz.size(), "npz");
    ASSERT_TRUE(arrays.ok()) << arrays.status().ToString();
    ASSERT_EQ(arrays->size(), 2u);
    EXPECT_EQ(arrays->at("b").ToDouble(), (std::vector<double>{0.5, -1, 1e300}));
    EXPECT_EQ(arrays->at("a").dtype, NpyDtype::kFloat32);
  }
}

TEST(Npy, ReadsTheRealFiles) {
  ATEX_REQUIRE_DATA_FILE(lego, "dnerf_lego_tiny/tiny_dnerf_data.npz");
  auto arrays = ReadNpzFile(lego.string());
  ASSERT_TRUE(arrays.ok()) << arrays.status().ToString();
  EXPECT_EQ(arrays->at("images").shape, (std::vector<int64_t>{81, 100, 100, 3}));
  EXPECT_EQ(arrays->at("poses").shape, (std::vector<int64_t>{81, 4, 4}));
  EXPECT_NEAR(*arrays->at("focal").Scalar("focal"), 138.8888, 1e-3);
  const std::vector<float> images = arrays->at("images").ToFloat();
  float lo = 1e9f, hi = -1e9f;
  for (float v : images) {
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  EXPECT_GE(lo, 0.0f);
  EXPECT_LE(hi, 1.0f);
  EXPECT_GT(hi, 0.5f);
  // Poses are rigid: the last row is (0, 0, 0, 1).
  const std::vector<double> poses = arrays->at("poses").ToDouble();
  EXPECT_NEAR(poses[15], 1.0, 1e-6);
  EXPECT_NEAR(poses[12], 0.0, 1e-6);

  ATEX_REQUIRE_DATA_FILE(garden, "gsplat_test_garden/test_garden.npz");
  auto g = ReadNpzFile(garden.string());
  ASSERT_TRUE(g.ok()) << g.status().ToString();
  EXPECT_EQ(g->at("means3d").shape, (std::vector<int64_t>{138766, 3}));
  EXPECT_EQ(g->at("colors").dtype, NpyDtype::kUint8);
  EXPECT_EQ(*g->at("width").Scalar("width"), 648.0);
  EXPECT_EQ(*g->at("height").Scalar("height"), 420.0);
  EXPECT_EQ(g->at("Ks").shape, (std::vector<int64_t>{3, 3, 3}));
}

}  // namespace
}  // namespace atex
