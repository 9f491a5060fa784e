// SPZ writing and reading: the real biker file, round trips of every degree and version within
// the quantisation, the axes conversion and the writer's refusals. Hand-built files (legacy
// versions, version 4 extensions, hostile input) are in spz_handbuilt_test.cc.
#include "atex/converters/spz.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "atex/converters/ply.h"
#include "atex/file_io.h"
#include "convert/test_gaussians.h"
#include "core/test_support.h"
#include "spz/spz_axes.h"

namespace atex {
namespace {

using converters::spz::AxisFlip;
using converters::testing::RandomGaussians;

const char* kBikerSpz = "splats/playcanvas_biker_v4.spz";

float Sigmoid(float x) { return 1.0f / (1.0f + std::exp(-x)); }

// Quaternion (w, x, y, z) -> rotation matrix, docs/conventions.md section 2.
std::array<double, 9> RotationMatrix(const float* q_in) {
  double n = std::sqrt(double(q_in[0]) * q_in[0] + double(q_in[1]) * q_in[1] + double(q_in[2]) * q_in[2] +
                       double(q_in[3]) * q_in[3]);
  const double w = q_in[0] / n, x = q_in[1] / n, y = q_in[2] / n, z = q_in[3] / n;
  return {1 - 2 * (y * y + z * z), 2 * (x * y - w * z),     2 * (x * z + w * y),
          2 * (x * y + w * z),     1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
          2 * (x * z - w * y),     2 * (y * z + w * x),     1 - 2 * (x * x + y * y)};
}

double QuaternionAlignment(const float* a, const float* b) {  // |<a^, b^>|, 1 = same rotation
  double dot = 0, na = 0, nb = 0;
  for (int k = 0; k < 4; ++k) {
    dot += double(a[k]) * b[k];
    na += double(a[k]) * a[k];
    nb += double(b[k]) * b[k];
  }
  return std::fabs(dot) / std::sqrt(na * nb);
}

// Every attribute of `decoded` within SPZ's quantisation of `original`.
void ExpectWithinQuantisation(const Gaussians& original, const Gaussians& decoded, int fractional_bits) {
  ASSERT_EQ(original.size(), decoded.size());
  ASSERT_EQ(original.sh_degree, decoded.sh_degree);
  const float position_step = std::ldexp(1.0f, -fractional_bits);
  for (size_t i = 0; i < original.positions.size(); ++i) {
    ASSERT_NEAR(decoded.positions[i], original.positions[i], 0.5f * position_step * 1.0001f + 1e-6f) << i;
  }
  for (size_t i = 0; i < original.log_scales.size(); ++i) {
    ASSERT_NEAR(decoded.log_scales[i], original.log_scales[i], 0.5f / 16 + 1e-5f) << i;
  }
  for (size_t i = 0; i < original.size(); ++i) {
    ASSERT_GT(QuaternionAlignment(&original.rotations[i * 4], &decoded.rotations[i * 4]), 1.0 - 1e-5) << i;
    const float a = Sigmoid(original.opacity_logits[i]);
    const float expected = std::clamp(a, 1.0f / 255, 254.0f / 255);  // the decoder's clamp
    ASSERT_NEAR(Sigmoid(decoded.opacity_logits[i]), expected, 0.5f / 255 + 1e-5f) << i;
  }
  const int k_count = original.sh_coeffs();
  for (size_t i = 0; i < original.size(); ++i) {
    for (int k = 0; k < k_count; ++k) {
      // DC: colour step 1/(0.15*255); degree 1: 5 bits of a 1/128 grid; higher: 4 bits.
      const float tolerance = k == 0 ? 0.5f / (0.15f * 255) : k <= 3 ? 4.5f / 128 : 8.5f / 128;
      for (int c = 0; c < 3; ++c) {
        const size_t idx = (i * k_count + k) * 3 + c;
        ASSERT_NEAR(decoded.sh[idx], original.sh[idx], tolerance + 1e-5f) << "Gaussian " << i << " coeff " << k;
      }
    }
  }
}

// ---------------------------------------------------------------------------
// The real v4 file.

TEST(SpzReal, ReadsBikerV4) {
  ATEX_REQUIRE_DATA_FILE(path, kBikerSpz);
  SpzInfo info;
  SpzReadOptions stored;
  stored.axes = SpzAxes::kStored;
  auto g = ReadSpzGaussians(path.string(), stored, &info);
  ASSERT_TRUE(g.ok()) << g.status().ToString();
  EXPECT_EQ(g->size(), 152746u);
  EXPECT_EQ(g->sh_degree, 0);
  EXPECT_EQ(info.version, 4);
  EXPECT_EQ(info.fractional_bits, 12);
  EXPECT_EQ(info.stored_axes, "RUB");
  // Values printed by the reference decoder (npm @adobe/spz 0.2.3, the WASM build of
  // nianticlabs/spz) for the first Gaussian of this file, coordinate system UNSPECIFIED;
  // its quaternion is (x, y, z, w).
  EXPECT_FLOAT_EQ(g->positions[0], -0.1044921875f);
  EXPECT_FLOAT_EQ(g->positions[1], 2.387939453125f);
  EXPECT_FLOAT_EQ(g->positions[2], 0.36083984375f);
  EXPECT_FLOAT_EQ(g->positions[3], -0.1044921875f);
  EXPECT_FLOAT_EQ(g->positions[4], 2.401123046875f);
  EXPECT_FLOAT_EQ(g->positions[5], 0.35546875f);
  EXPECT_NEAR(g->rotations[0], -0.4607956111431122, 1e-6);
  EXPECT_NEAR(g->rotations[1], 0.062269676476716995, 1e-6);
  EXPECT_NEAR(g->rotations[2], 0.8850421905517578, 1e-6);
  EXPECT_NEAR(g->rotations[3], 0.02214032970368862, 1e-6);
  EXPECT_NEAR(g->opacity_logits[0], -2.577688217163086, 1e-5);
  EXPECT_NEAR(g->opacity_logits[1], -2.7725887298583984, 1e-5);
  EXPECT_NEAR(g->sh[0], 0.535947859287262, 1e-6);
  EXPECT_NEAR(g->sh[1], 0.5098040699958801, 1e-6);
  EXPECT_NEAR(g->sh[2], 0.5620916485786438, 1e-6);
  EXPECT_FLOAT_EQ(g->log_scales[0], -6.0625f);
  EXPECT_FLOAT_EQ(g->log_scales[1], -4.1875f);
  EXPECT_FLOAT_EQ(g->log_scales[2], -7.0625f);
  for (float v : g->rotations) ASSERT_TRUE(std::isfinite(v));
  for (float v : g->opacity_logits) ASSERT_TRUE(std::isfinite(v));

  // The default (OpenCV world) flips y and z of the stored RUB data.
  auto cv = ReadSpzGaussians(path.string());
  ASSERT_TRUE(cv.ok());
  EXPECT_FLOAT_EQ(cv->positions[0], -0.1044921875f);
  EXPECT_FLOAT_EQ(cv->positions[1], -2.387939453125f);
  EXPECT_FLOAT_EQ(cv->positions[2], -0.36083984375f);
}

TEST(SpzReal, BikerRewrittenAsV3AndV4DecodesTheSame) {
  ATEX_REQUIRE_DATA_FILE(path, kBikerSpz);
  auto g = ReadSpzGaussians(path.string());
  ASSERT_TRUE(g.ok());
  SpzWriteOptions v4;
  SpzWriteOptions v3;
  v3.version = 3;
  auto bytes4 = EncodeSpz(*g, v4);
  auto bytes3 = EncodeSpz(*g, v3);
  ASSERT_TRUE(bytes4.ok() && bytes3.ok());
  auto back4 = DecodeSpz(bytes4->data(), bytes4->size());
  auto back3 = DecodeSpz(bytes3->data(), bytes3->size());
  ASSERT_TRUE(back4.ok() && back3.ok()) << back4.status().ToString() << back3.status().ToString();
  // Already-quantised positions, scales, colours and alphas re-encode to the same bytes.
  EXPECT_EQ(back4->positions, g->positions);
  EXPECT_EQ(back4->log_scales, g->log_scales);
  EXPECT_EQ(back4->sh, g->sh);
  EXPECT_EQ(back4->opacity_logits, g->opacity_logits);
  for (size_t i = 0; i < g->size(); ++i) {
    ASSERT_GT(QuaternionAlignment(&g->rotations[i * 4], &back4->rotations[i * 4]), 1.0 - 1e-5);
  }
  // v3 and v4 carry the same quantised arrays.
  EXPECT_EQ(back3->positions, back4->positions);
  EXPECT_EQ(back3->rotations, back4->rotations);
  EXPECT_EQ(back3->sh, back4->sh);
}

TEST(SpzReal, PlyToSpzWithinQuantisation) {
  ATEX_REQUIRE_DATA_FILE(path, "splats/kacytran1122_try_iter7000_point_cloud.ply");
  auto ply = ReadPlyGaussians(path.string());
  ASSERT_TRUE(ply.ok());
  // Clamp the values to SPZ's representable ranges first, so that the tolerance
  // check tests rounding and not the format's clamping.
  Gaussians g = *ply;
  for (float& v : g.log_scales) v = std::clamp(v, -10.0f, 5.9f);
  for (size_t i = 0; i < g.size(); ++i) {
    for (int k = 0; k < 16; ++k) {
      for (int c = 0; c < 3; ++c) {
        float& v = g.sh[(i * 16 + k) * 3 + c];
        v = k == 0 ? std::clamp(v, -3.3f, 3.3f) : std::clamp(v, -0.99f, 0.99f);
      }
    }
  }
  for (int version : {3, 4}) {
    SpzWriteOptions options;
    options.version = version;
    auto bytes = EncodeSpz(g, options);
    ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
    SpzInfo info;
    auto back = DecodeSpz(bytes->data(), bytes->size(), {}, &info);
    ASSERT_TRUE(back.ok()) << back.status().ToString();
    EXPECT_EQ(info.version, version);
    ExpectWithinQuantisation(g, *back, info.fractional_bits);
  }
}

// ---------------------------------------------------------------------------
// Synthetic round trips.

TEST(SpzRoundTrip, EveryDegreeAndVersionWithinQuantisation) {
  for (int degree = 0; degree <= 3; ++degree) {
    const Gaussians g = RandomGaussians(500, degree, 40 + degree);
    Gaussians decoded[2];
    for (int v = 0; v < 2; ++v) {
      SpzWriteOptions options;
      options.version = 3 + v;
      auto bytes = EncodeSpz(g, options);
      ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
      SpzInfo info;
      auto back = DecodeSpz(bytes->data(), bytes->size(), {}, &info);
      ASSERT_TRUE(back.ok()) << back.status().ToString();
      EXPECT_EQ(info.version, 3 + v);
      EXPECT_EQ(info.fractional_bits, 12);
      ExpectWithinQuantisation(g, *back, 12);
      decoded[v] = *back;
    }
    // v3 <-> v4: identical quantised content.
    EXPECT_EQ(decoded[0].positions, decoded[1].positions);
    EXPECT_EQ(decoded[0].rotations, decoded[1].rotations);
    EXPECT_EQ(decoded[0].log_scales, decoded[1].log_scales);
    EXPECT_EQ(decoded[0].opacity_logits, decoded[1].opacity_logits);
    EXPECT_EQ(decoded[0].sh, decoded[1].sh);
  }
}

TEST(SpzRoundTrip, FractionalBitsShrinkToFitLargeCoordinates) {
  Gaussians g = RandomGaussians(50, 0, 3, 3000.0f);  // beyond +-2048, the range of 12 bits
  auto bytes = EncodeSpz(g);
  ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
  SpzInfo info;
  auto back = DecodeSpz(bytes->data(), bytes->size(), {}, &info);
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(info.fractional_bits, 11);
  ExpectWithinQuantisation(g, *back, 11);

  SpzWriteOptions strict;
  strict.reduce_fractional_bits_to_fit = false;
  auto refused = EncodeSpz(g, strict);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), StatusCode::kOutOfRange);
}

TEST(SpzRoundTrip, ShBitsOptionAndClamping) {
  Gaussians g = RandomGaussians(10, 1, 8);
  g.log_scales[0] = -30;  // below the format's range: clamps to ln s = -10
  g.sh[3] = 5.0f;         // coefficient 1 (odd in y): stored negated in RUB, clamps to -1
  SpzWriteOptions options;
  options.sh1_bits = 8;
  auto bytes = EncodeSpz(g, options);
  ASSERT_TRUE(bytes.ok());
  auto back = DecodeSpz(bytes->data(), bytes->size());
  ASSERT_TRUE(back.ok());
  EXPECT_FLOAT_EQ(back->log_scales[0], -10.0f);
  EXPECT_FLOAT_EQ(back->sh[3], 1.0f);
  // With 8 bits the degree-1 error is half a 1/128 step.
  for (size_t i = 0; i < g.size(); ++i) {
    for (int k = 1; k < 4; ++k) {
      for (int c = 0; c < 3; ++c) {
        const size_t idx = (i * 4 + k) * 3 + c;
        if (idx == 3) continue;
        ASSERT_NEAR(back->sh[idx], g.sh[idx], 0.5f / 128 + 1e-6f);
      }
    }
  }
}

// ---------------------------------------------------------------------------
// Axes.

// Real SH basis functions 1..15 of 3DGS (constants omitted: signs only matter).
double ShBasis(int k, double x, double y, double z) {
  switch (k) {
    case 1: return -y;
    case 2: return z;
    case 3: return -x;
    case 4: return x * y;
    case 5: return y * z;
    case 6: return 2 * z * z - x * x - y * y;
    case 7: return x * z;
    case 8: return x * x - y * y;
    case 9: return y * (3 * x * x - y * y);
    case 10: return x * y * z;
    case 11: return y * (4 * z * z - x * x - y * y);
    case 12: return z * (2 * z * z - 3 * x * x - 3 * y * y);
    case 13: return x * (4 * z * z - x * x - y * y);
    case 14: return z * (x * x - y * y);
    case 15: return x * (x * x - 3 * y * y);
  }
  return 0;
}

TEST(SpzAxes, ShSignsMatchTheBasisPolynomials) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int mask = 0; mask < 8; ++mask) {
    AxisFlip flip{{mask & 1 ? -1.0f : 1.0f, mask & 2 ? -1.0f : 1.0f, mask & 4 ? -1.0f : 1.0f}};
    for (int trial = 0; trial < 20; ++trial) {
      const double x = u(rng), y = u(rng), z = u(rng);
      for (int k = 1; k <= 15; ++k) {
        // A colour field c(v) = sum_k a_k Y_k(v) seen through the flip: a'_k Y_k(Mv) = a_k Y_k(v).
        const double original = ShBasis(k, x, y, z);
        const double flipped = ShBasis(k, flip.sign[0] * x, flip.sign[1] * y, flip.sign[2] * z);
        ASSERT_NEAR(flip.ShSign(k) * flipped, original, 1e-12) << "k " << k << " mask " << mask;
      }
    }
  }
}

TEST(SpzAxes, OpenCvWriteStoresRubAndConjugatesRotations) {
  const Gaussians g = RandomGaussians(200, 3, 77);
  auto bytes = EncodeSpz(g);  // axes kOpenCv
  ASSERT_TRUE(bytes.ok());
  SpzReadOptions stored;
  stored.axes = SpzAxes::kStored;
  auto raw = DecodeSpz(bytes->data(), bytes->size(), stored);
  auto cv = DecodeSpz(bytes->data(), bytes->size());
  ASSERT_TRUE(raw.ok() && cv.ok());
  ExpectWithinQuantisation(g, *cv, 12);
  const double m[3] = {1, -1, -1};  // RDF -> RUB
  for (size_t i = 0; i < g.size(); ++i) {
    for (int k = 0; k < 3; ++k) ASSERT_FLOAT_EQ(raw->positions[i * 3 + k], m[k] * cv->positions[i * 3 + k]);
    // Stored rotation = M R M.
    const auto r = RotationMatrix(&cv->rotations[i * 4]);
    const auto s = RotationMatrix(&raw->rotations[i * 4]);
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 3; ++b) ASSERT_NEAR(s[a * 3 + b], m[a] * r[a * 3 + b] * m[b], 1e-5);
    }
    // The SH colour seen along direction v in our world equals the stored one along Mv.
    const double v[3] = {0.3, -0.5, 0.81};
    for (int c = 0; c < 3; ++c) {
      double ours = 0, theirs = 0;
      for (int k = 1; k < 16; ++k) {
        ours += cv->sh[(i * 16 + k) * 3 + c] * ShBasis(k, v[0], v[1], v[2]);
        theirs += raw->sh[(i * 16 + k) * 3 + c] * ShBasis(k, m[0] * v[0], m[1] * v[1], m[2] * v[2]);
      }
      ASSERT_NEAR(ours, theirs, 1e-5);
    }
  }
}

TEST(SpzWriter, RefusesBadInput) {
  Gaussians zero_q = RandomGaussians(3, 0, 1);
  std::fill(zero_q.rotations.begin() + 4, zero_q.rotations.begin() + 8, 0.0f);
  auto r = EncodeSpz(zero_q);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kOutOfRange);
  EXPECT_NE(r.status().message().find("Gaussian 1"), std::string::npos);

  Gaussians nan = RandomGaussians(3, 0, 1);
  nan.opacity_logits[2] = std::nanf("");
  EXPECT_EQ(EncodeSpz(nan).status().code(), StatusCode::kOutOfRange);
  EXPECT_EQ(EncodeSpz(Gaussians{}).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(EncodeSpz(RandomGaussians(3, 0, 1), SpzWriteOptions{.version = 2}).status().code(),
            StatusCode::kInvalidArgument);
  EXPECT_EQ(EncodeSpz(RandomGaussians(3, 0, 1), SpzWriteOptions{.sh1_bits = 0}).status().code(),
            StatusCode::kInvalidArgument);
}

TEST(SpzFiles, WriteIsAtomicAndReadable) {
  testing::TempDir dir;
  const std::string path = (dir / "a.spz").string();
  const Gaussians g = RandomGaussians(40, 1, 5);
  ASSERT_TRUE(WriteSpzGaussians(path, g).ok());
  auto back = ReadSpzGaussians(path);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  ExpectWithinQuantisation(g, *back, 12);
  EXPECT_EQ(ReadSpzGaussians((dir / "missing.spz").string()).status().code(), StatusCode::kNotFound);
}

}  // namespace
}  // namespace atex
