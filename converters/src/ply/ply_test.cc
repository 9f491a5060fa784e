#include "atex/converters/ply.h"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>

#include "atex/file_io.h"
#include "convert/test_gaussians.h"
#include "core/test_support.h"

namespace atex {
namespace {

using converters::testing::RandomGaussians;

const char* kRealPly = "splats/kacytran1122_try_iter7000_point_cloud.ply";



StatusOr<Gaussians> Parse(const std::string& s) {
  return ReadPlyGaussiansFromMemory(reinterpret_cast<const uint8_t*>(s.data()), s.size());
}

void ExpectBitEqual(const std::vector<float>& a, const std::vector<float>& b, const char* what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  for (size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(std::bit_cast<uint32_t>(a[i]), std::bit_cast<uint32_t>(b[i])) << what << " [" << i << "]";
  }
}

void ExpectSameGaussians(const Gaussians& a, const Gaussians& b) {
  ASSERT_EQ(a.sh_degree, b.sh_degree);
  ExpectBitEqual(a.positions, b.positions, "positions");
  ExpectBitEqual(a.rotations, b.rotations, "rotations");
  ExpectBitEqual(a.log_scales, b.log_scales, "log_scales");
  ExpectBitEqual(a.opacity_logits, b.opacity_logits, "opacity_logits");
  ExpectBitEqual(a.sh, b.sh, "sh");
}

// ---------------------------------------------------------------------------
// The real INRIA file.

TEST(PlyReal, ReadsKnownLayoutAndValues) {
  ATEX_REQUIRE_DATA_FILE(path, kRealPly);
  auto g = ReadPlyGaussians(path.string());
  ASSERT_TRUE(g.ok()) << g.status().ToString();
  EXPECT_EQ(g->size(), 9080u);
  EXPECT_EQ(g->sh_degree, 3);

  // Independent decoding of the raw bytes: the README says every vertex is 62
  // little-endian floats x y z nx ny nz f_dc_0..2 f_rest_0..44 opacity scale_0..2 rot_0..3.
  auto bytes = ReadFileBytes(path.string());
  ASSERT_TRUE(bytes.ok());
  const std::string text(bytes->begin(), bytes->begin() + 4096);
  const size_t data_start = text.find("end_header\n") + std::strlen("end_header\n");
  ASSERT_EQ(bytes->size() - data_start, 9080u * 62 * 4);
  for (size_t i : {size_t{0}, size_t{1}, size_t{4321}, size_t{9079}}) {
    float row[62];
    std::memcpy(row, bytes->data() + data_start + i * 62 * 4, sizeof row);
    for (int k = 0; k < 3; ++k) EXPECT_EQ(g->positions[i * 3 + k], row[k]);
    const float* sh = &g->sh[i * 16 * 3];
    for (int c = 0; c < 3; ++c) EXPECT_EQ(sh[c], row[6 + c]) << "f_dc_" << c;
    for (int c = 0; c < 3; ++c) {
      for (int k = 1; k < 16; ++k) EXPECT_EQ(sh[k * 3 + c], row[9 + c * 15 + (k - 1)]) << "coeff " << k << " ch " << c;
    }
    EXPECT_EQ(g->opacity_logits[i], row[54]);
    for (int k = 0; k < 3; ++k) EXPECT_EQ(g->log_scales[i * 3 + k], row[55 + k]);
    for (int k = 0; k < 4; ++k) EXPECT_EQ(g->rotations[i * 4 + k], row[58 + k]);
  }
}

TEST(PlyReal, RoundTripIsBitExact) {
  ATEX_REQUIRE_DATA_FILE(path, kRealPly);
  auto first = ReadPlyGaussians(path.string());
  ASSERT_TRUE(first.ok()) << first.status().ToString();
  testing::TempDir dir;
  const std::string out = (dir / "copy.ply").string();
  ASSERT_TRUE(WritePlyGaussians(out, *first).ok());
  auto second = ReadPlyGaussians(out);
  ASSERT_TRUE(second.ok()) << second.status().ToString();
  ExpectSameGaussians(*first, *second);
  // PLY -> Gaussians -> PLY again gives identical bytes.
  auto again = EncodePlyGaussians(*second);
  auto written = ReadFileBytes(out);
  ASSERT_TRUE(again.ok() && written.ok());
  EXPECT_EQ(*again, *written);
}

// ---------------------------------------------------------------------------
// Synthetic files in other encodings, property orders and with extra content.

std::string FormatFloat(float v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.9g", v);  // 9 significant digits round-trip every float
  return buf;
}

TEST(PlySynthetic, AsciiWithShuffledPropertiesAndExtraElements) {
  const Gaussians g = RandomGaussians(7, 1, 11);
  // Property order differs from INRIA's, an extra uchar property and a list, plus a
  // 'face' element before the vertices and a 'camera' element after them.
  std::string s = "ply\r\nformat ascii 1.0\r\ncomment made by hand\r\nelement face 2\r\n"
                  "property list uchar int vertex_indices\r\nelement vertex 7\r\n";
  const char* order[] = {"rot_3", "f_rest_8", "x", "red", "opacity", "f_dc_2", "scale_1", "rot_0", "f_rest_0",
                         "y", "f_rest_4", "scale_0", "rot_1", "f_dc_0", "z", "f_rest_1", "f_rest_2", "f_rest_3",
                         "f_rest_5", "f_rest_6", "f_rest_7", "scale_2", "rot_2", "f_dc_1", "tags"};
  for (const char* name : order) {
    if (std::string(name) == "red") {
      s += "property uchar red\r\n";
    } else if (std::string(name) == "tags") {
      s += "property list uchar float tags\r\n";
    } else {
      s += std::string("property float ") + name + "\r\n";
    }
  }
  s += "element camera 1\r\nproperty float fov\r\nend_header\r\n3 0 1 2\r\n4 0 1 2 3\r\n";
  for (size_t i = 0; i < g.size(); ++i) {
    const float* sh = &g.sh[i * 4 * 3];
    for (const char* name_c : order) {
      const std::string name = name_c;
      float v = 0;
      if (name == "red") {
        s += "200 ";
        continue;
      }
      if (name == "tags") {
        s += "2 1.5 -2 ";
        continue;
      }
      if (name == "x" || name == "y" || name == "z") v = g.positions[i * 3 + (name[0] - 'x')];
      if (name == "opacity") v = g.opacity_logits[i];
      if (name.rfind("scale_", 0) == 0) v = g.log_scales[i * 3 + (name[6] - '0')];
      if (name.rfind("rot_", 0) == 0) v = g.rotations[i * 4 + (name[4] - '0')];
      if (name.rfind("f_dc_", 0) == 0) v = sh[name[5] - '0'];
      if (name.rfind("f_rest_", 0) == 0) {
        const int j = name[7] - '0';
        v = sh[(1 + j % 3) * 3 + j / 3];  // channel-major: j = channel * 3 + (coeff - 1)
      }
      s += FormatFloat(v) + " ";
    }
    s += "\n";
  }
  s += "0.7\n";
  auto read = Parse(s);
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  ExpectSameGaussians(g, *read);
}

// Writes g as binary PLY with the given encoding, using double for positions
// (tests type conversion) and float elsewhere.
std::string BinaryPly(const Gaussians& g, bool big_endian) {
  std::string s = std::string("ply\nformat ") + (big_endian ? "binary_big_endian" : "binary_little_endian") +
                  " 1.0\nelement vertex " + std::to_string(g.size()) +
                  "\nproperty double x\nproperty double y\nproperty double z\nproperty float opacity\n"
                  "property float scale_0\nproperty float scale_1\nproperty float scale_2\nproperty float rot_0\n"
                  "property float rot_1\nproperty float rot_2\nproperty float rot_3\nproperty float f_dc_0\n"
                  "property float f_dc_1\nproperty float f_dc_2\nproperty short extra\nend_header\n";
  auto put = [&](auto value) {
    char b[sizeof(value)];
    std::memcpy(b, &value, sizeof value);
    if (big_endian) std::reverse(b, b + sizeof value);
    s.append(b, sizeof value);
  };
  for (size_t i = 0; i < g.size(); ++i) {
    for (int k = 0; k < 3; ++k) put(static_cast<double>(g.positions[i * 3 + k]));
    put(g.opacity_logits[i]);
    for (int k = 0; k < 3; ++k) put(g.log_scales[i * 3 + k]);
    for (int k = 0; k < 4; ++k) put(g.rotations[i * 4 + k]);
    for (int c = 0; c < 3; ++c) put(g.sh[i * 3 + c]);
    put(int16_t{-7});
  }
  return s;
}

TEST(PlySynthetic, BinaryBigAndLittleEndian) {
  const Gaussians g = RandomGaussians(33, 0, 5);
  for (bool big : {false, true}) {
    auto read = Parse(BinaryPly(g, big));
    ASSERT_TRUE(read.ok()) << read.status().ToString();
    ExpectSameGaussians(g, *read);
  }
}

TEST(PlySynthetic, WriterRoundTripsEveryDegree) {
  for (int degree = 0; degree <= 3; ++degree) {
    const Gaussians g = RandomGaussians(20, degree, 100 + degree);
    auto bytes = EncodePlyGaussians(g);
    ASSERT_TRUE(bytes.ok());
    auto read = ReadPlyGaussiansFromMemory(bytes->data(), bytes->size());
    ASSERT_TRUE(read.ok()) << read.status().ToString();
    ExpectSameGaussians(g, *read);
  }
}

TEST(PlySynthetic, EmptyVertexElement) {
  const Gaussians g = RandomGaussians(0, 2, 1);
  auto bytes = EncodePlyGaussians(g);
  ASSERT_TRUE(bytes.ok());
  auto read = ReadPlyGaussiansFromMemory(bytes->data(), bytes->size());
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  EXPECT_EQ(read->size(), 0u);
  EXPECT_EQ(read->sh_degree, 2);
}

// ---------------------------------------------------------------------------
// Hostile input.

TEST(PlyHostile, EveryTruncationFailsCleanly) {
  const Gaussians g = RandomGaussians(3, 1, 9);
  auto bytes = EncodePlyGaussians(g);
  ASSERT_TRUE(bytes.ok());
  for (size_t cut = 0; cut < bytes->size(); ++cut) {
    auto read = ReadPlyGaussiansFromMemory(bytes->data(), cut);
    ASSERT_FALSE(read.ok()) << "cut at " << cut;
  }
}

TEST(PlyHostile, ForgedVertexCountIsRefusedBeforeAllocation) {
  auto bytes = EncodePlyGaussians(RandomGaussians(2, 0, 3));
  ASSERT_TRUE(bytes.ok());
  std::string s(bytes->begin(), bytes->end());
  s.replace(s.find("vertex 2"), 8, "vertex 18446744073709551615");
  auto read = Parse(s);
  ASSERT_FALSE(read.ok());
  EXPECT_EQ(read.status().code(), StatusCode::kTruncated) << read.status().ToString();

  std::string ascii = "ply\nformat ascii 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\n"
                      "property float z\nproperty float opacity\nproperty float scale_0\nproperty float scale_1\n"
                      "property float scale_2\nproperty float rot_0\nproperty float rot_1\nproperty float rot_2\n"
                      "property float rot_3\nproperty float f_dc_0\nproperty float f_dc_1\nproperty float f_dc_2\n"
                      "end_header\n1 2 3\n";
  auto read_ascii = Parse(ascii);
  ASSERT_FALSE(read_ascii.ok());
  EXPECT_EQ(read_ascii.status().code(), StatusCode::kTruncated);
}

TEST(PlyHostile, ForgedListCount) {
  std::string s = "ply\nformat binary_little_endian 1.0\nelement face 1\nproperty list uint float v\n"
                  "element vertex 0\nproperty float x\nend_header\n";
  s += std::string("\xff\xff\xff\x7f", 4);
  auto read = Parse(s);
  ASSERT_FALSE(read.ok());
}

TEST(PlyHostile, HeaderProblemsAreNamed) {
  struct Case {
    std::string text;
    StatusCode code;
  };
  const std::string props = "property float x\nproperty float y\nproperty float z\nproperty float opacity\n"
                            "property float scale_0\nproperty float scale_1\nproperty float scale_2\n"
                            "property float rot_0\nproperty float rot_1\nproperty float rot_2\nproperty float rot_3\n"
                            "property float f_dc_0\nproperty float f_dc_1\nproperty float f_dc_2\n";
  const Case cases[] = {
      {"plz\n", StatusCode::kBadMagic},
      {"", StatusCode::kBadMagic},
      {"ply\nformat binary_little_endian 1.0\nelement vertex 1\n", StatusCode::kTruncated},
      {"ply\nformat binary_middle_endian 1.0\nend_header\n", StatusCode::kUnsupported},
      {"ply\nformat ascii 2.0\nend_header\n", StatusCode::kUnsupported},
      {"ply\nelement vertex 0\nend_header\n", StatusCode::kCorrupt},
      {"ply\nformat ascii 1.0\nproperty float x\nend_header\n", StatusCode::kCorrupt},
      {"ply\nformat ascii 1.0\nelement vertex -3\nend_header\n", StatusCode::kCorrupt},
      {"ply\nformat ascii 1.0\nelement vertex 0\nproperty float128 x\nend_header\n", StatusCode::kCorrupt},
      {"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float x\nend_header\n",
       StatusCode::kCorrupt},
      {"ply\nformat ascii 1.0\nbogus line\nend_header\n", StatusCode::kCorrupt},
      {"ply\nformat ascii 1.0\nelement face 0\nend_header\n", StatusCode::kCorrupt},  // no vertex element
      // Missing rot_3.
      {"ply\nformat ascii 1.0\nelement vertex 0\n" + props.substr(0, props.find("property float rot_3")) +
           "property float f_dc_0\nproperty float f_dc_1\nproperty float f_dc_2\nend_header\n",
       StatusCode::kCorrupt},
      // Ten f_rest values: not a valid SH degree.
      {[&] {
         std::string t = "ply\nformat ascii 1.0\nelement vertex 0\n" + props;
         for (int j = 0; j < 10; ++j) t += "property float f_rest_" + std::to_string(j) + "\n";
         return t + "end_header\n";
       }(),
       StatusCode::kCorrupt},
      // A gap in the f_rest numbering.
      {"ply\nformat ascii 1.0\nelement vertex 0\n" + props + "property float f_rest_1\nend_header\n",
       StatusCode::kCorrupt},
      // A used property as a list.
      {"ply\nformat ascii 1.0\nelement vertex 0\nproperty list uchar float x\nend_header\n", StatusCode::kCorrupt},
  };
  for (const auto& c : cases) {
    auto read = Parse(c.text);
    ASSERT_FALSE(read.ok()) << c.text;
    EXPECT_EQ(read.status().code(), c.code) << c.text << " -> " << read.status().ToString();
    EXPECT_FALSE(read.status().message().empty());
  }
}

TEST(PlyHostile, NonFiniteValuesNameTheVertex) {
  Gaussians g = RandomGaussians(4, 0, 2);
  auto bytes = EncodePlyGaussians(g);
  ASSERT_TRUE(bytes.ok());
  std::string s(bytes->begin(), bytes->end());
  const size_t data = s.find("end_header\n") + 11;
  const float nan = std::nanf("");
  std::memcpy(&s[data + (2 * 17 + 9) * 4], &nan, 4);  // vertex 2, opacity (index 9 in a degree-0 row)
  auto read = Parse(s);
  ASSERT_FALSE(read.ok());
  EXPECT_EQ(read.status().code(), StatusCode::kOutOfRange);
  EXPECT_NE(read.status().message().find("vertex 2"), std::string::npos) << read.status().ToString();
  EXPECT_NE(read.status().message().find("opacity"), std::string::npos);

  // NaN in an ignored property (the normals) is fine.
  std::string t(bytes->begin(), bytes->end());
  std::memcpy(&t[data + (1 * 17 + 3) * 4], &nan, 4);  // vertex 1, nx
  EXPECT_TRUE(Parse(t).ok());

  auto ascii = Parse("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                     "property float z\nproperty float opacity\nproperty float scale_0\nproperty float scale_1\n"
                     "property float scale_2\nproperty float rot_0\nproperty float rot_1\nproperty float rot_2\n"
                     "property float rot_3\nproperty float f_dc_0\nproperty float f_dc_1\nproperty float f_dc_2\n"
                     "end_header\n1 2 inf 0 0 0 0 1 0 0 0 0 0 0\n");
  ASSERT_FALSE(ascii.ok());
  EXPECT_EQ(ascii.status().code(), StatusCode::kOutOfRange);
  auto garbage = Parse("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                       "property float z\nproperty float opacity\nproperty float scale_0\nproperty float scale_1\n"
                       "property float scale_2\nproperty float rot_0\nproperty float rot_1\nproperty float rot_2\n"
                       "property float rot_3\nproperty float f_dc_0\nproperty float f_dc_1\nproperty float f_dc_2\n"
                       "end_header\n1 2 three 0 0 0 0 1 0 0 0 0 0 0\n");
  ASSERT_FALSE(garbage.ok());
  EXPECT_EQ(garbage.status().code(), StatusCode::kCorrupt);
}

TEST(PlyHostile, DoubleBeyondFloatRangeIsRefused) {
  Gaussians g = RandomGaussians(2, 0, 3);
  std::string s = BinaryPly(g, false);
  const size_t data = s.find("end_header\n") + 11;
  const double huge = 1e300;  // finite as a double, Inf as a float
  std::memcpy(&s[data + 8], &huge, 8);  // vertex 0, y
  auto read = Parse(s);
  ASSERT_FALSE(read.ok());
  EXPECT_EQ(read.status().code(), StatusCode::kOutOfRange) << read.status().ToString();
}

TEST(PlyWriter, RefusesInconsistentOrNonFiniteInput) {
  Gaussians g = RandomGaussians(3, 1, 4);
  g.sh.pop_back();
  EXPECT_EQ(EncodePlyGaussians(g).status().code(), StatusCode::kInvalidArgument);
  Gaussians h = RandomGaussians(3, 1, 4);
  h.log_scales[4] = INFINITY;
  EXPECT_EQ(EncodePlyGaussians(h).status().code(), StatusCode::kOutOfRange);
}

TEST(PlyFiles, MissingFileIsNotFound) {
  testing::TempDir dir;
  auto read = ReadPlyGaussians((dir / "absent.ply").string());
  ASSERT_FALSE(read.ok());
  EXPECT_EQ(read.status().code(), StatusCode::kNotFound);
}

}  // namespace
}  // namespace atex
