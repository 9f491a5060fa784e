// splatv: half conversion, the motion fits on analytic motion, the byte layout read
// by hand, the error report against an independent evaluation, and hostile input.
#include <bit>
#include <cmath>
#include <cstring>
#include <random>

#include <gtest/gtest.h>

#include "atex/converters/splatv.h"
#include "gltf/gltf_test_scene.h"
#include "splatv/half.h"
#include "splatv/motion_fit.h"

namespace atex {
namespace {

TEST(SplatvHalf, EveryHalfRoundTrips) {
  for (uint32_t h = 0; h < 65536; ++h) {
    const float f = splatv::HalfToFloat(uint16_t(h));
    if (std::isnan(f)) continue;
    EXPECT_EQ(splatv::FloatToHalf(f), h) << h;
  }
}

TEST(SplatvHalf, RoundsToTheNearestHalf) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> mag(-20.0f, 16.0f);
  for (int i = 0; i < 20000; ++i) {
    const float f = std::ldexp(1.0f + float(rng() % 1000000) / 1e6f, int(mag(rng))) * ((rng() & 1) ? 1 : -1);
    const uint16_t h = splatv::FloatToHalf(f);
    const double got = splatv::HalfToFloat(h);
    // Neighbouring halves are no closer.
    for (int d : {-1, 1}) {
      const uint16_t other = uint16_t(h + d);
      if ((other & 0x7c00) == 0x7c00) continue;
      if ((h & 0x7fff) == 0 && d < 0) continue;
      EXPECT_LE(std::abs(got - f), std::abs(double(splatv::HalfToFloat(other)) - f)) << f;
    }
  }
  EXPECT_EQ(splatv::FloatToHalf(1e6f), 0x7c00);
  EXPECT_EQ(splatv::FloatToHalf(65504.0f), 0x7bff);
  EXPECT_EQ(splatv::FloatToHalf(-0.0f), 0x8000);
}

TEST(SplatvFit, TemporalOpacityRecoversAGaussian) {
  std::vector<double> u;
  std::vector<float> alpha;
  for (int j = 0; j < 33; ++j) {
    u.push_back(j / 32.0);
    const double d = (u.back() - 0.3) / 0.2;
    alpha.push_back(float(0.8 * std::exp(-d * d)));
  }
  const auto fit = splatv::FitTemporalOpacity(u, alpha.data(), alpha.size());
  EXPECT_NEAR(fit.center, 0.3, 1e-3);
  EXPECT_NEAR(fit.width, 0.2, 1e-3);
  EXPECT_NEAR(fit.peak, 0.8, 1e-3);
  std::vector<float> flat(33, 0.6f);
  const auto constant = splatv::FitTemporalOpacity(u, flat.data(), flat.size());
  EXPECT_NEAR(constant.peak, 0.6, 1e-6);
  EXPECT_GE(constant.width, 100.0);
}

// Analytic motion: cubic positions, a slow rotation, a fading opacity.
Status CubicMotion(const Asset& a, double t, Gaussians* out) {
  *out = a.gaussians;
  for (size_t i = 0; i < out->size(); ++i) {
    const double s = double(i % 7) / 7.0;
    out->positions[i * 3 + 0] += float(0.3 * t - 0.2 * t * t + 0.4 * s * t * t * t);
    out->positions[i * 3 + 1] += float(-0.5 * s * t);
    out->positions[i * 3 + 2] += float(0.1 * t * t);
    const double angle = 0.3 * t;  // about z, applied to identity-ish rotations
    out->rotations[i * 4 + 0] = float(std::cos(angle / 2));
    out->rotations[i * 4 + 1] = 0;
    out->rotations[i * 4 + 2] = 0;
    out->rotations[i * 4 + 3] = float(std::sin(angle / 2));
    const double d = (t - 0.6) / 0.3;
    const double alpha = std::clamp(0.9 * std::exp(-d * d), 1e-6, 1 - 1e-6);
    out->opacity_logits[i] = float(std::log(alpha / (1 - alpha)));
  }
  return Status::Ok();
}

Asset MovingAsset(size_t n) {
  Asset asset = testing::MakeTestAsset({.count = n, .sh_degree = 1, .textures = false, .deformation = true});
  return asset;
}

uint32_t U32(const std::vector<uint8_t>& b, size_t at) {
  return uint32_t(b[at]) | uint32_t(b[at + 1]) << 8 | uint32_t(b[at + 2]) << 16 | uint32_t(b[at + 3]) << 24;
}

TEST(SplatvExport, LayoutMatchesTheViewer) {
  const Asset asset = MovingAsset(1500);  // two texture rows
  SplatvOptions options;
  options.deform = CubicMotion;
  auto result = EncodeSplatv(asset, options);
  ASSERT_TRUE(result.ok()) << result.status().ToString();
  const std::vector<uint8_t>& b = result->bytes;
  EXPECT_EQ(U32(b, 0), 0x674bu);
  const uint32_t json_length = U32(b, 4);
  const auto chunks = nlohmann::json::parse(b.begin() + 8, b.begin() + 8 + json_length);
  ASSERT_TRUE(chunks.is_array());
  ASSERT_EQ(chunks.size(), 1u);
  EXPECT_EQ(chunks[0]["type"], "splat");
  EXPECT_EQ(chunks[0]["texwidth"], 4096);
  EXPECT_EQ(chunks[0]["texheight"], 2);
  EXPECT_EQ(chunks[0]["size"], 4096u * 2 * 16);
  EXPECT_EQ(b.size(), 8 + json_length + 4096u * 2 * 16);
  ASSERT_FALSE(chunks[0]["cameras"].empty());
  const auto& cam = chunks[0]["cameras"][0];
  for (const char* key : {"width", "height", "fx", "fy", "position", "rotation"}) EXPECT_TRUE(cam.contains(key)) << key;
  // Gaussian 1100 sits in row 1 at texel x = (1100 & 1023) * 4: word 16 * 1100 of the chunk.
  const size_t base = 8 + json_length + 16 * 4 * 1100;
  const float x = std::bit_cast<float>(U32(b, base));
  const double expected_mean_x = [&] {
    double sum = 0;
    for (int j = 0; j < 32; ++j) {
      Gaussians g;
      (void)CubicMotion(asset, j / 31.0, &g);
      sum += g.positions[1100 * 3];
    }
    return sum / 32;
  }();
  // The rest position is the position at the temporal centre; it lies within the motion's range.
  EXPECT_NEAR(x, expected_mean_x, 0.5);
  // Colour alpha (byte 3 of word 7) is the fitted peak opacity (0.9).
  EXPECT_NEAR(b[base + 7 * 4 + 3], 0.9 * 255, 3);
  // Padding after the last Gaussian never draws.
  auto file = DecodeSplatv(b.data(), b.size());
  ASSERT_TRUE(file.ok()) << file.status().ToString();
  EXPECT_EQ(file->count, 2048u);
  EXPECT_EQ(EvaluateSplatv(*file, 2047, 0.0).opacity, 0.0f);
  EXPECT_EQ(EvaluateSplatv(*file, 2047, 1.0).opacity, 0.0f);
}

TEST(SplatvExport, AnalyticMotionIsReproduced) {
  const Asset asset = MovingAsset(300);
  SplatvOptions options;
  options.deform = CubicMotion;
  auto result = EncodeSplatv(asset, options);
  ASSERT_TRUE(result.ok()) << result.status().ToString();
  const SplatvFitReport& r = result->report;
  // Exactly cubic positions: only half-precision rounding of the coefficients remains.
  EXPECT_LT(r.position_rms_relative, 1e-3);
  EXPECT_LT(r.rotation_rms_deg, 0.5);  // a linear quaternion path approximates a 17-degree turn
  EXPECT_LT(r.opacity_rms, 0.02);
  // The report is the error of the stored values: re-evaluate independently at a sample time.
  auto file = DecodeSplatv(result->bytes.data(), result->bytes.size());
  ASSERT_TRUE(file.ok());
  Gaussians truth;
  (void)CubicMotion(asset, 0.5 * (asset.metadata.time_min + asset.metadata.time_max), &truth);
  double sq = 0;
  for (size_t i = 0; i < asset.gaussians.size(); ++i) {
    const auto s = EvaluateSplatv(*file, i, 0.5);
    for (int k = 0; k < 3; ++k) sq += std::pow(double(s.position[size_t(k)]) - truth.positions[i * 3 + k], 2);
  }
  EXPECT_LT(std::sqrt(sq / double(asset.gaussians.size())), 5 * r.position_rms + 1e-6);
}

TEST(SplatvExport, RealDeformationFieldIsFittedAndReported) {
  const Asset asset = MovingAsset(200);
  auto result = EncodeSplatv(asset);  // DeformForward of the test field
  ASSERT_TRUE(result.ok()) << result.status().ToString();
  const auto& r = result->report;
  EXPECT_EQ(r.samples, 32);
  EXPECT_TRUE(std::isfinite(r.position_rms) && std::isfinite(r.rotation_rms_deg) && std::isfinite(r.opacity_rms));
  EXPECT_LT(r.position_rms_relative, 0.05);
  EXPECT_GT(r.position_rms, 0.0);
}

TEST(SplatvExport, PsnrOfTheBakeIsMeasuredWithTheReferenceRenderer) {
  Asset asset = testing::MakeTestAsset({.count = 300, .sh_degree = 1, .textures = true, .deformation = true});
  SplatvOptions options;
  options.psnr_times = 3;
  SplatvCamera camera;  // looks at the test cube from z = -6 (OpenCV axes)
  camera.width = 160, camera.height = 120, camera.fx = camera.fy = 90;
  camera.position = {0, 0, -6};
  options.cameras = {camera};
  options.deform = CubicMotion;  // exactly representable motion: the picture cost is small
  auto result = EncodeSplatv(asset, options);
  ASSERT_TRUE(result.ok()) << result.status().ToString();
  const auto& r = result->report;
  EXPECT_EQ(r.psnr_frames, 3);
  EXPECT_GT(r.psnr_motion_db, 35.0);
  // Textures and SH degree 1 are not representable: the full comparison costs more.
  EXPECT_GT(r.psnr_full_db, 10.0);
  EXPECT_LT(r.psnr_full_db, r.psnr_motion_db);
}

// The default camera looks horizontally with the asset's world up axis up: its image
// "down" axis (column 1 of the camera-to-world rotation) is minus metadata.up, and
// older files without metadata.up get the rule of metadata.axes ("opencv": up -y).
TEST(SplatvExport, DefaultCameraHasTheWorldUpAxisUp) {
  for (const auto& [up, down] : std::vector<std::pair<std::string, std::array<double, 3>>>{
           {"+z", {0, 0, -1}}, {"-y", {0, 1, 0}}, {"+x", {-1, 0, 0}}, {"", {0, 1, 0}}}) {
    Asset asset = testing::MakeTestAsset({.count = 10, .sh_degree = 0, .textures = false, .deformation = false});
    asset.metadata.axes = "opencv";
    asset.metadata.up = up;
    auto result = EncodeSplatv(asset);
    ASSERT_TRUE(result.ok()) << result.status().ToString();
    auto file = DecodeSplatv(result->bytes.data(), result->bytes.size());
    ASSERT_TRUE(file.ok());
    const auto& r = file->chunks[file->splat_chunk]["cameras"][0]["rotation"];  // rows of camera-to-world
    for (int k = 0; k < 3; ++k)
      EXPECT_NEAR(r[size_t(k)][1].get<double>(), down[size_t(k)], 1e-12) << "up '" << up << "'";
  }
}

TEST(SplatvExport, StaticAssetHasNoMotion) {
  const Asset asset = testing::MakeTestAsset({.count = 10, .sh_degree = 0, .textures = false, .deformation = false});
  auto result = EncodeSplatv(asset);
  ASSERT_TRUE(result.ok()) << result.status().ToString();
  auto file = DecodeSplatv(result->bytes.data(), result->bytes.size());
  ASSERT_TRUE(file.ok());
  for (double u : {0.0, 0.5, 1.0}) {
    const auto s = EvaluateSplatv(*file, 3, u);
    for (int k = 0; k < 3; ++k) EXPECT_EQ(s.position[size_t(k)], asset.gaussians.positions[3 * 3 + k]);
  }
  EXPECT_EQ(result->report.position_rms, 0.0);
}

TEST(SplatvDecode, HostileInput) {
  const Asset asset = testing::MakeTestAsset({.count = 10, .sh_degree = 0, .textures = false, .deformation = false});
  auto result = EncodeSplatv(asset);
  ASSERT_TRUE(result.ok());
  const std::vector<uint8_t>& good = result->bytes;
  for (size_t cut = 0; cut < good.size(); cut += 97) {
    EXPECT_FALSE(DecodeSplatv(good.data(), cut).ok()) << cut;
  }
  std::vector<uint8_t> bad = good;
  bad[0] = 0;
  EXPECT_EQ(DecodeSplatv(bad.data(), bad.size()).status().code(), StatusCode::kBadMagic);
  bad = good;
  bad[4] = 0xff, bad[5] = 0xff, bad[6] = 0xff, bad[7] = 0x7f;
  EXPECT_EQ(DecodeSplatv(bad.data(), bad.size()).status().code(), StatusCode::kTruncated);
  const std::string text = R"([{"type":"splat","size":64,"texwidth":4,"texheight":1}])";
  std::vector<uint8_t> forged = {0x4b, 0x67, 0, 0, uint8_t(text.size()), 0, 0, 0};
  forged.insert(forged.end(), text.begin(), text.end());
  forged.resize(forged.size() + 64, 0);
  EXPECT_EQ(DecodeSplatv(forged.data(), forged.size()).status().code(), StatusCode::kCorrupt);
}

TEST(SplatvExport, RefusesBadArguments) {
  Asset asset = MovingAsset(5);
  SplatvOptions options;
  options.samples = 2;
  EXPECT_EQ(EncodeSplatv(asset, options).status().code(), StatusCode::kInvalidArgument);
  Asset empty;
  EXPECT_EQ(EncodeSplatv(empty).status().code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace atex
