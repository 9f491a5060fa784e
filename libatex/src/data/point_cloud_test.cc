// Point cloud readers (atex/point_cloud.h): PLY in its three encodings with colours
// from red/green/blue or f_dc, other elements skipped; COLMAP points3D.txt and .bin
// against each other on the same points (fixtures written here in the documented
// layouts); and hostile inputs: every truncation, forged counts and lengths,
// non-finite coordinates, bad headers.
#include <cmath>
#include <cstring>
#include <string>

#include <gtest/gtest.h>

#include "atex/file_io.h"
#include "atex/point_cloud.h"
#include "core/test_support.h"

namespace atex {
namespace {

const uint8_t* Bytes(const std::string& s) { return reinterpret_cast<const uint8_t*>(s.data()); }

// Appends `v` as `n` bytes, little- or big-endian.
template <typename T>
void Put(std::string* out, T v, bool big = false) {
  uint8_t b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  if (big) std::reverse(b, b + sizeof(T));
  out->append(reinterpret_cast<const char*>(b), sizeof(T));
}

// The fixture's three points.
constexpr float kPoints[3][3] = {{0.5f, -1.25f, 2.0f}, {3.0f, 0.0f, -0.75f}, {-2.5f, 1.5f, 0.125f}};
constexpr uint8_t kColours[3][3] = {{255, 0, 128}, {10, 20, 30}, {0, 255, 64}};

void ExpectFixture(const PointCloud& c, bool colours = true) {
  ASSERT_EQ(c.size(), 3u);
  for (int i = 0; i < 3; ++i) {
    for (int a = 0; a < 3; ++a) {
      EXPECT_FLOAT_EQ(c.positions[3 * i + a], kPoints[i][a]) << i << " " << a;
      if (colours) {
        EXPECT_NEAR(c.colours[3 * i + a], kColours[i][a] / 255.0, 1e-6) << i << " " << a;
      }
    }
  }
  EXPECT_EQ(c.has_colours(), colours);
}

// A PLY with a leading `camera` element (skipped), the vertices (double x, float y, float z,
// uchar colours, a list of indices), then faces with lists.
std::string FixturePly(const std::string& format) {
  std::string s = "ply\nformat " + format + " 1.0\ncomment fixture\nelement camera 1\nproperty float focal\n"
                  "element vertex 3\nproperty double x\nproperty float y\nproperty float z\n"
                  "property uchar red\nproperty uchar green\nproperty uchar blue\n"
                  "property list uchar int tags\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
  const bool big = format == "binary_big_endian";
  if (format == "ascii") {
    s += "1.5\n";
    for (int i = 0; i < 3; ++i) {
      char line[200];
      std::snprintf(line, sizeof(line), "%.9g %.9g %.9g %d %d %d 2 7 8\n", kPoints[i][0], kPoints[i][1], kPoints[i][2],
                    kColours[i][0], kColours[i][1], kColours[i][2]);
      s += line;
    }
    s += "3 0 1 2\n";
    return s;
  }
  Put(&s, 1.5f, big);
  for (int i = 0; i < 3; ++i) {
    Put(&s, double(kPoints[i][0]), big);
    Put(&s, kPoints[i][1], big);
    Put(&s, kPoints[i][2], big);
    for (int a = 0; a < 3; ++a) Put(&s, kColours[i][a]);
    Put(&s, uint8_t(2));
    Put(&s, int32_t(7), big);
    Put(&s, int32_t(8), big);
  }
  Put(&s, uint8_t(3));
  for (int k = 0; k < 3; ++k) Put(&s, int32_t(k), big);
  return s;
}

TEST(PlyPoints, ReadsAllThreeEncodings) {
  for (const char* format : {"ascii", "binary_little_endian", "binary_big_endian"}) {
    SCOPED_TRACE(format);
    const std::string ply = FixturePly(format);
    auto c = ParsePlyPoints(Bytes(ply), ply.size(), "fixture.ply");
    ASSERT_TRUE(c.ok()) << c.status().ToString();
    ExpectFixture(*c);
  }
}

TEST(PlyPoints, ColoursFromShDcAndNoColours) {
  // An INRIA 3DGS-like vertex: x y z nx ny nz f_dc_0..2 opacity.
  std::string s = "ply\nformat binary_little_endian 1.0\nelement vertex 1\n";
  for (const char* p : {"x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2", "opacity"}) {
    s += std::string("property float ") + p + "\n";
  }
  s += "end_header\n";
  const float values[10] = {1, 2, 3, 0, 0, 0, 0.0f, 1.0f, -10.0f, 0.3f};
  for (float v : values) Put(&s, v);
  auto c = ParsePlyPoints(Bytes(s), s.size(), "gs.ply");
  ASSERT_TRUE(c.ok()) << c.status().ToString();
  ASSERT_EQ(c->size(), 1u);
  EXPECT_FLOAT_EQ(c->positions[2], 3.0f);
  EXPECT_NEAR(c->colours[0], 0.5, 1e-6);
  EXPECT_NEAR(c->colours[1], 0.5 + 0.28209479177387814, 1e-6);
  EXPECT_EQ(c->colours[2], 0.0f);  // clamped

  const std::string bare = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                           "property float z\nend_header\n1 2 3\n4 5 6\n";
  auto b = ParsePlyPoints(Bytes(bare), bare.size(), "bare.ply");
  ASSERT_TRUE(b.ok()) << b.status().ToString();
  EXPECT_EQ(b->size(), 2u);
  EXPECT_FALSE(b->has_colours());
  EXPECT_FLOAT_EQ(b->positions[5], 6.0f);
}

TEST(PlyPoints, WriteAndReadBack) {
  const testing::TempDir dir;
  PointCloud cloud;
  for (int i = 0; i < 3; ++i) {
    cloud.positions.insert(cloud.positions.end(), kPoints[i], kPoints[i] + 3);
    for (int a = 0; a < 3; ++a) cloud.colours.push_back(kColours[i][a] / 255.0f);
  }
  ASSERT_TRUE(WritePlyPoints((dir / "c.ply").string(), cloud).ok());
  auto back = ReadPointCloud((dir / "c.ply").string());
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  ExpectFixture(*back);
  PointCloud bad = cloud;
  bad.colours.pop_back();
  EXPECT_EQ(WritePlyPoints((dir / "bad.ply").string(), bad).code(), StatusCode::kInvalidArgument);
}

TEST(PlyPoints, HostileInputs) {
  // Every truncation before the end of the vertex data is an error, never a crash (the
  // reader stops after the vertex element, so the faces may be cut).
  const std::string good = FixturePly("binary_little_endian");
  const size_t vertex_end = good.find("end_header\n") + 11 + 4 + 3 * 28;
  for (size_t n = 0; n < vertex_end; ++n) {
    EXPECT_FALSE(ParsePlyPoints(Bytes(good), n, "cut.ply").ok()) << n;
  }
  EXPECT_TRUE(ParsePlyPoints(Bytes(good), vertex_end, "cut.ply").ok());
  const std::string ascii = FixturePly("ascii");
  for (size_t n = 0; n + 1 < ascii.rfind("3 0 1 2\n"); ++n) {
    EXPECT_FALSE(ParsePlyPoints(Bytes(ascii), n, "cut.ply").ok()) << n;
  }
  auto code = [](const std::string& s) { return ParsePlyPoints(Bytes(s), s.size(), "h.ply").status().code(); };
  const std::string head = "ply\nformat binary_little_endian 1.0\n";
  const std::string xyz = "property float x\nproperty float y\nproperty float z\n";
  EXPECT_EQ(code("plx\n"), StatusCode::kBadMagic);
  EXPECT_EQ(code("ply\nformat ascii 1.0\nelement vertex 1\n"), StatusCode::kTruncated);  // no end_header
  EXPECT_EQ(code("ply\nformat ascii 2.0\nend_header\n"), StatusCode::kCorrupt);
  EXPECT_EQ(code("ply\nformat zip 1.0\nend_header\n"), StatusCode::kCorrupt);
  EXPECT_EQ(code("ply\nelement vertex 0\n" + xyz + "end_header\n"), StatusCode::kCorrupt);  // no format
  EXPECT_EQ(code(head + "property float x\nend_header\n"), StatusCode::kCorrupt);         // before element
  EXPECT_EQ(code(head + "element vertex 1\nproperty float128 x\nend_header\n"), StatusCode::kCorrupt);
  EXPECT_EQ(code(head + "element vertex -1\n" + xyz + "end_header\n"), StatusCode::kCorrupt);
  EXPECT_EQ(code(head + "element vertex 1\nproperty float x\nproperty float y\nend_header\n" + std::string(8, '\0')),
            StatusCode::kCorrupt);  // no z
  EXPECT_EQ(code(head + "element face 0\nproperty list uchar int v\nend_header\n"), StatusCode::kCorrupt);  // no vertex
  EXPECT_EQ(code(head + "element vertex 1\nproperty list float int x\nend_header\n"), StatusCode::kCorrupt);
  // A forged count, far beyond the bytes present, and beyond the limit.
  EXPECT_EQ(code(head + "element vertex 200000000\n" + xyz + "end_header\n" + std::string(12, '\0')),
            StatusCode::kTruncated);
  EXPECT_EQ(code(head + "element vertex 99999999999999\n" + xyz + "end_header\n"), StatusCode::kLimitExceeded);
  // A forged list length.
  std::string list = head + "element vertex 1\n" + xyz + "property list uint uchar l\nend_header\n";
  Put(&list, 1.0f), Put(&list, 2.0f), Put(&list, 3.0f), Put(&list, uint32_t(0xFFFFFFF0u));
  EXPECT_EQ(code(list), StatusCode::kCorrupt);
  // Non-finite coordinates.
  std::string nan = head + "element vertex 1\n" + xyz + "end_header\n";
  Put(&nan, 1.0f), Put(&nan, std::nanf("")), Put(&nan, 3.0f);
  EXPECT_EQ(code(nan), StatusCode::kOutOfRange);
  EXPECT_EQ(code("ply\nformat ascii 1.0\nelement vertex 1\n" + xyz + "end_header\n1 inf 2\n"),
            StatusCode::kOutOfRange);
  EXPECT_EQ(code("ply\nformat ascii 1.0\nelement vertex 1\n" + xyz + "end_header\n1 x 2\n"), StatusCode::kCorrupt);
  // A header with no newline within the limit.
  EXPECT_EQ(code("ply\n" + std::string(70000, 'a')), StatusCode::kTruncated);
}

// COLMAP fixtures in the documented layouts (atex/point_cloud.h): three points whose
// tracks have 2, 0 and 1 observations.
std::string FixtureColmapText() {
  std::string s =
      "# 3D point list with one line of data per point:\n"
      "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
      "# Number of points: 3, mean track length: 1\n";
  const int tracks[3] = {2, 0, 1};
  for (int i = 0; i < 3; ++i) {
    char line[300];
    std::snprintf(line, sizeof(line), "%d %.17g %.17g %.17g %d %d %d 0.5", 10 + i, double(kPoints[i][0]),
                  double(kPoints[i][1]), double(kPoints[i][2]), kColours[i][0], kColours[i][1], kColours[i][2]);
    s += line;
    for (int k = 0; k < tracks[i]; ++k) {
      std::snprintf(line, sizeof(line), " %d %d", k + 1, 100 + k);
      s += line;
    }
    s += i == 1 ? "\r\n\n" : "\n";  // a CRLF line and a blank line
  }
  return s;
}

std::string FixtureColmapBinary() {
  std::string s;
  Put(&s, uint64_t(3));
  const int tracks[3] = {2, 0, 1};
  for (int i = 0; i < 3; ++i) {
    Put(&s, uint64_t(10 + i));
    for (int a = 0; a < 3; ++a) Put(&s, double(kPoints[i][a]));
    for (int a = 0; a < 3; ++a) Put(&s, kColours[i][a]);
    Put(&s, 0.5);
    Put(&s, uint64_t(tracks[i]));
    for (int k = 0; k < tracks[i]; ++k) Put(&s, uint32_t(k + 1)), Put(&s, uint32_t(100 + k));
  }
  return s;
}

TEST(ColmapPoints, TextAndBinaryAgree) {
  const std::string text = FixtureColmapText(), bin = FixtureColmapBinary();
  ASSERT_EQ(bin.size(), 8 + 3 * 51 + 3 * 8u);  // 43 + 8 bytes per point, 8 per track entry
  auto t = ParseColmapPointsText(text, "points3D.txt");
  auto b = ParseColmapPointsBinary(Bytes(bin), bin.size(), "points3D.bin");
  ASSERT_TRUE(t.ok()) << t.status().ToString();
  ASSERT_TRUE(b.ok()) << b.status().ToString();
  ExpectFixture(*t);
  ExpectFixture(*b);
  EXPECT_EQ(t->positions, b->positions);
  EXPECT_EQ(t->colours, b->colours);
  // Through files, chosen by extension.
  const testing::TempDir dir;
  ASSERT_TRUE(WriteFileAtomic((dir / "points3D.txt").string(), text.data(), text.size()).ok());
  ASSERT_TRUE(WriteFileAtomic((dir / "points3D.bin").string(), bin.data(), bin.size()).ok());
  auto ft = ReadPointCloud((dir / "points3D.txt").string());
  auto fb = ReadPointCloud((dir / "points3D.bin").string());
  ASSERT_TRUE(ft.ok() && fb.ok());
  EXPECT_EQ(ft->positions, fb->positions);
  EXPECT_EQ(ReadPointCloud((dir / "points3D.xyz").string()).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(ReadPointCloud((dir / "absent.bin").string()).status().code(), StatusCode::kNotFound);
  // An empty model is valid: no points.
  auto empty = ParseColmapPointsText("# nothing\n", "e.txt");
  ASSERT_TRUE(empty.ok());
  EXPECT_EQ(empty->size(), 0u);
}

TEST(ColmapPoints, HostileText) {
  auto code = [](const std::string& s) { return ParseColmapPointsText(s, "h.txt").status().code(); };
  EXPECT_EQ(code("1 0 0 0 1 2 3\n"), StatusCode::kCorrupt);                 // no error field
  EXPECT_EQ(code("1 0 0 0 1 2 3 0.1 5\n"), StatusCode::kCorrupt);           // odd track
  EXPECT_EQ(code("1 0 0 0 300 2 3 0.1\n"), StatusCode::kCorrupt);           // colour > 255
  EXPECT_EQ(code("1 0 0 0 -1 2 3 0.1\n"), StatusCode::kCorrupt);
  EXPECT_EQ(code("1 nan 0 0 1 2 3 0.1\n"), StatusCode::kCorrupt);           // non-finite
  EXPECT_EQ(code("1 1e999 0 0 1 2 3 0.1\n"), StatusCode::kCorrupt);
  EXPECT_EQ(code("x 0 0 0 1 2 3 0.1\n"), StatusCode::kCorrupt);
  EXPECT_EQ(code("1 0 0 0 1 2 3 0.1 1 z\n"), StatusCode::kCorrupt);
  const auto s = ParseColmapPointsText("# ok\n1 0 0 0 1 2 3 0.1\n2 0 0 0 1 2 3 0.1 4\n", "h.txt").status();
  EXPECT_NE(s.message().find("line 3"), std::string::npos) << s.ToString();  // errors name the line
  // Every truncation of the fixture parses or fails cleanly.
  const std::string text = FixtureColmapText();
  for (size_t n = 0; n < text.size(); ++n) (void)ParseColmapPointsText(std::string_view(text).substr(0, n), "cut");
}

TEST(ColmapPoints, HostileBinary) {
  const std::string good = FixtureColmapBinary();
  for (size_t n = 0; n < good.size(); ++n) {
    EXPECT_FALSE(ParseColmapPointsBinary(Bytes(good), n, "cut.bin").ok()) << n;
  }
  auto code = [](const std::string& s) { return ParseColmapPointsBinary(Bytes(s), s.size(), "h.bin").status().code(); };
  EXPECT_EQ(code(good + "x"), StatusCode::kCorrupt);  // trailing byte
  std::string forged = good;
  forged[0] = '\x7f';  // 127 points announced, 3 present
  EXPECT_EQ(code(forged), StatusCode::kTruncated);
  std::string huge;
  Put(&huge, uint64_t(1) << 60);
  EXPECT_EQ(code(huge), StatusCode::kLimitExceeded);
  std::string track = good;
  const uint64_t forged_track = uint64_t(1) << 61;  // the first point's track length
  std::memcpy(&track[8 + 43], &forged_track, 8);
  EXPECT_EQ(code(track), StatusCode::kTruncated);
  std::string nan = good;
  const double inf = INFINITY;
  std::memcpy(&nan[8 + 8 + 8], &inf, 8);  // the first point's y
  EXPECT_EQ(code(nan), StatusCode::kOutOfRange);
  std::string none;
  Put(&none, uint64_t(0));
  auto empty = ParseColmapPointsBinary(Bytes(none), none.size(), "e.bin");
  ASSERT_TRUE(empty.ok());
  EXPECT_EQ(empty->size(), 0u);
}

}  // namespace
}  // namespace atex
