// `atex view`'s writer: the page embeds a payload that decodes back to the keyframes we
// baked, compared with the deformation evaluated independently (DeformForward at the
// keyframe times) on a synthetic asset and on the bundled lego sample; the static/dynamic
// split, the Gaussian selection, the size cap, the opening camera and hostile pages.
#include <algorithm>
#include <cmath>
#include <string>

#include <gtest/gtest.h>

#include "atex/container.h"
#include "atex/converters/view.h"
#include "atex/deform.h"
#include "core/test_support.h"
#include "gltf/gltf_test_scene.h"
#include "splatv/half.h"

namespace atex {
namespace {

constexpr double kShC0 = 0.28209479177387814;

double Sigmoid(double x) { return 1.0 / (1.0 + std::exp(-x)); }

ViewPayload EncodeAndDecode(const Asset& asset, const ViewOptions& options, ViewReport* report = nullptr,
                            std::string* page = nullptr) {
  auto html = EncodeViewHtml(asset, options, report);
  EXPECT_TRUE(html.ok()) << html.status().ToString();
  if (!html.ok()) return {};
  auto payload = DecodeViewHtml(*html);
  EXPECT_TRUE(payload.ok()) << payload.status().ToString();
  if (page) *page = *html;
  return payload.ok() ? *payload : ViewPayload{};
}

// Every stored value against the deformation evaluated here, within its quantisation.
void ExpectKeyframesMatch(const Asset& asset, const ViewPayload& p) {
  ASSERT_EQ(p.count, asset.gaussians.size());
  const Gaussians& canonical = asset.gaussians;
  const size_t n = p.count, sh_stride = size_t(canonical.sh_coeffs()) * 3;
  double position_step[3];
  for (int c = 0; c < 3; ++c)
    position_step[c] = (double(p.position_hi[size_t(c)]) - p.position_lo[size_t(c)]) / 65535.0;
  std::vector<float> previous(n * 4, 0.0f);
  for (size_t k = 0; k < p.times.size(); ++k) {
    Gaussians g = canonical;
    if (asset.deformation) {
      ASSERT_TRUE(DeformForward(*asset.deformation, canonical, p.times[k], &g, nullptr).ok());
    }
    double worst_position = 0, worst_rotation = 0, worst_scale = 0, worst_colour = 0, worst_opacity = 0;
    for (size_t i = 0; i < n; ++i) {
      const auto pos = p.Position(k, i);
      for (int c = 0; c < 3; ++c) {
        worst_position = std::max(worst_position,
                                  std::abs(pos[size_t(c)] - double(g.positions[i * 3 + size_t(c)])) / position_step[c]);
      }
      // Unit quaternion, up to the sign the writer chose (aligned with the previous keyframe).
      const float* q = &g.rotations[i * 4];
      const double norm =
          std::sqrt(double(q[0]) * q[0] + double(q[1]) * q[1] + double(q[2]) * q[2] + double(q[3]) * q[3]);
      const auto r = p.Rotation(k, i);
      double dot = 0;
      for (int c = 0; c < 4; ++c) dot += r[size_t(c)] * q[c] / norm;
      const double sign = dot < 0 ? -1 : 1;
      for (int c = 0; c < 4; ++c)
        worst_rotation = std::max(worst_rotation, std::abs(r[size_t(c)] - sign * q[c] / norm));
      if (k > 0 && p.rotation_frames > 1) {
        double along = 0;  // consecutive keyframes blend the near pair: non-negative dot products
        for (int c = 0; c < 4; ++c) along += double(r[size_t(c)]) * previous[i * 4 + size_t(c)];
        EXPECT_GE(along, -1e-6) << "Gaussian " << i << " keyframe " << k;
      }
      for (int c = 0; c < 4; ++c) previous[i * 4 + size_t(c)] = r[size_t(c)];
      const auto ls = p.LogScale(k, i);
      for (int c = 0; c < 3; ++c) {
        const double truth = g.log_scales[i * 3 + size_t(c)];
        worst_scale = std::max(worst_scale, std::abs(ls[size_t(c)] - truth) / std::max(std::abs(truth), 1e-3));
      }
      // Colour: DC plus the texture's average; opacity times its average factor.
      double tex[3] = {0, 0, 0}, factor = 1;
      if (asset.textures) {
        const auto& pool = *asset.textures;
        const uint64_t a = pool.offsets[i], b = pool.offsets[i + 1];
        factor = 0;
        for (uint64_t t = a; t < b; ++t) {
          for (int c = 0; c < 3; ++c) tex[c] += 0.1 * std::tanh(pool.texels[t * 4 + size_t(c)]) / double(b - a);
          factor += std::exp(0.1 * std::tanh(pool.texels[t * 4 + 3])) / double(b - a);
        }
      }
      const auto co = p.ColourOpacity(k, i);
      for (int c = 0; c < 3; ++c) {
        const double truth = std::max(0.0, 0.5 + kShC0 * g.sh[i * sh_stride + size_t(c)]) + tex[c];
        worst_colour = std::max(worst_colour, std::abs(co[size_t(c)] - truth));
      }
      worst_opacity = std::max(worst_opacity, std::abs(co[3] - Sigmoid(g.opacity_logits[i]) * factor));
    }
    // Half a step of rounding, plus the float arithmetic of the dequantisation (as the shader's).
    EXPECT_LE(worst_position, 0.5 + 0.02) << "keyframe " << k << ": position error in quantisation steps";
    EXPECT_LE(worst_rotation, 0.5 / 127 + 1e-6) << "keyframe " << k;
    EXPECT_LE(worst_scale, std::ldexp(1.0, -11) + 1e-6) << "keyframe " << k << ": relative log-scale error";
    const double colour_step = (p.colour_range[1] - p.colour_range[0]) / 255.0;
    EXPECT_LE(worst_colour, 0.5 * colour_step + 1e-5) << "keyframe " << k;
    EXPECT_LE(worst_opacity, 0.5 * p.opacity_scale / 255.0 + 1e-5) << "keyframe " << k;
  }
}

TEST(View, PayloadDecodesToTheDeformedGaussiansAtEachKeyframe) {
  const Asset asset = testing::MakeTestAsset({.count = 300, .sh_degree = 1, .textures = true, .deformation = true});
  ViewOptions options;
  options.frames = 7;
  ViewReport report;
  const ViewPayload p = EncodeAndDecode(asset, options, &report);
  ASSERT_EQ(p.times.size(), 7u);
  for (size_t k = 0; k < 7; ++k) EXPECT_DOUBLE_EQ(p.times[k], double(k) / 6.0);
  // The test asset's heads: position, scale, rotation, opacity (no SH head).
  EXPECT_EQ(p.position_frames, 7);
  EXPECT_EQ(p.rotation_frames, 7);
  EXPECT_EQ(p.scale_frames, 7);
  EXPECT_EQ(p.colour_frames, 7);
  ExpectKeyframesMatch(asset, p);
  // The motion is real: the keyframes differ.
  double moved = 0;
  for (size_t i = 0; i < p.count; ++i)
    moved = std::max(moved, double(std::abs(p.Position(6, i)[0] - p.Position(0, i)[0])));
  EXPECT_GT(moved, 1e-3);
  EXPECT_EQ(report.times, p.times);
  EXPECT_EQ(report.kept, 300u);
  EXPECT_EQ(report.dynamic.size(), 4u);
  // SH of degree 1 and textures are approximated, and say so.
  ASSERT_EQ(report.warnings.size(), 3u);
  EXPECT_NE(report.warnings[0].find("DC term"), std::string::npos);
  EXPECT_EQ(p.header.at("approximations").size(), 3u);
}

TEST(View, CompressedAndPlainPagesHoldTheSameKeyframes) {
  const Asset asset = testing::MakeTestAsset({.count = 500, .sh_degree = 0, .textures = true, .deformation = true});
  ViewOptions options;
  options.frames = 6;
  ViewReport packed_report, plain_report;
  std::string packed_page, plain_page;
  const ViewPayload packed = EncodeAndDecode(asset, options, &packed_report, &packed_page);
  options.compress = false;
  const ViewPayload plain = EncodeAndDecode(asset, options, &plain_report, &plain_page);
  EXPECT_EQ(packed.positions, plain.positions);
  EXPECT_EQ(packed.rotations, plain.rotations);
  EXPECT_EQ(packed.log_scales, plain.log_scales);
  EXPECT_EQ(packed.colours, plain.colours);
  EXPECT_NE(packed_page.find("\"encoding\":\"delta-planes-deflate\""), std::string::npos);
  EXPECT_NE(plain_page.find("\"encoding\":\"raw\""), std::string::npos);
  EXPECT_EQ(plain_report.stored_bytes, plain_report.payload_bytes);
  EXPECT_EQ(packed_report.payload_bytes, plain_report.payload_bytes);
  EXPECT_LT(packed_report.stored_bytes, plain_report.stored_bytes);
  EXPECT_LT(packed_page.size(), plain_page.size());
}

TEST(View, ParametersOfDisabledHeadsAreStoredOnce) {
  Asset asset = testing::MakeTestAsset({.count = 64, .sh_degree = 0, .textures = false, .deformation = true});
  auto& field = *asset.deformation;
  for (int h : {kHeadScale, kHeadOpacity}) {
    field.config.heads[size_t(h)] = false;
    field.heads[size_t(h)] = {};
  }
  ASSERT_TRUE(ValidateAsset(asset).ok());
  ViewOptions options;
  options.frames = 4;
  const ViewPayload p = EncodeAndDecode(asset, options);
  EXPECT_EQ(p.position_frames, 4);
  EXPECT_EQ(p.rotation_frames, 4);
  EXPECT_EQ(p.scale_frames, 1);
  EXPECT_EQ(p.colour_frames, 1);
  ExpectKeyframesMatch(asset, p);
}

// Time-local Gaussians (model.h time_windows) fade in and out without an opacity head: their
// colours (opacity included) are stored per keyframe, and each keyframe's opacities are the
// deformed ones with the window applied.
TEST(View, TimeWindowsMakeOpacitiesPerKeyframe) {
  Asset asset = testing::MakeTestAsset({.count = 64, .sh_degree = 0, .textures = false, .deformation = true});
  auto& field = *asset.deformation;
  for (int h : {kHeadScale, kHeadOpacity}) {
    field.config.heads[size_t(h)] = false;
    field.heads[size_t(h)] = {};
  }
  asset.gaussians.time_windows.assign(2 * asset.gaussians.size(), 0.0f);
  for (size_t i = 0; i < asset.gaussians.size(); i += 2) asset.gaussians.time_windows[2 * i + 1] = 8.0f;  // centre 0
  ASSERT_TRUE(ValidateAsset(asset).ok());
  ViewOptions options;
  options.frames = 4;
  const ViewPayload p = EncodeAndDecode(asset, options);
  EXPECT_EQ(p.colour_frames, 4);
  ExpectKeyframesMatch(asset, p);
}

TEST(View, StaticAssetHasOneFrame) {
  const Asset asset = testing::MakeTestAsset({.count = 40, .sh_degree = 0, .textures = false, .deformation = false});
  ViewOptions options;
  options.frames = 9;  // ignored: nothing moves
  ViewReport report;
  const ViewPayload p = EncodeAndDecode(asset, options, &report);
  ASSERT_EQ(p.times.size(), 1u);
  EXPECT_EQ(p.position_frames, 1);
  EXPECT_TRUE(report.warnings.empty());
  ExpectKeyframesMatch(asset, p);
}

TEST(View, DefaultFramesFollowTheTimeGrid) {
  Asset asset = testing::MakeTestAsset({.count = 10, .sh_degree = 0, .textures = false, .deformation = true});
  EXPECT_EQ(DefaultViewFrames(asset), 2 * (4 - 1) + 1);  // base_resolution t = 4
  asset.deformation->config.grid.base_resolution[3] = 150;
  EXPECT_EQ(DefaultViewFrames(asset), 120);
  asset.deformation.reset();
  EXPECT_EQ(DefaultViewFrames(asset), 1);
}

TEST(View, MaxSplatsKeepsTheMostOpaqueLargest) {
  Asset asset = testing::MakeTestAsset({.count = 50, .sh_degree = 0, .textures = false, .deformation = false});
  // Gaussian 7: large and opaque; 3: tiny; 20: transparent.
  for (int c = 0; c < 3; ++c) asset.gaussians.log_scales[7 * 3 + size_t(c)] = 0.0f;
  asset.gaussians.opacity_logits[7] = 5.0f;
  for (int c = 0; c < 3; ++c) asset.gaussians.log_scales[3 * 3 + size_t(c)] = -12.0f;
  asset.gaussians.opacity_logits[20] = -20.0f;
  ViewOptions options;
  options.max_splats = 10;
  ViewReport report;
  const ViewPayload p = EncodeAndDecode(asset, options, &report);
  ASSERT_EQ(p.count, 10u);
  EXPECT_EQ(report.kept, 10u);
  EXPECT_EQ(report.gaussians, 50u);
  // Find Gaussian 7 among the kept ones by its position; 3 and 20 are gone.
  auto kept = [&](size_t source) {
    for (size_t i = 0; i < p.count; ++i) {
      const auto pos = p.Position(0, i);
      bool same = true;
      for (int c = 0; c < 3; ++c) {
        same = same && std::abs(pos[size_t(c)] - asset.gaussians.positions[source * 3 + size_t(c)]) < 1e-3;
      }
      if (same) return true;
    }
    return false;
  };
  EXPECT_TRUE(kept(7));
  EXPECT_FALSE(kept(3));
  EXPECT_FALSE(kept(20));
}

TEST(View, SizeCapDropsKeyframesThenRefuses) {
  const Asset asset = testing::MakeTestAsset({.count = 2000, .sh_degree = 0, .textures = false, .deformation = true});
  ViewOptions options;
  options.frames = 50;
  ViewReport full;
  auto big = EncodeViewHtml(asset, options, &full);
  ASSERT_TRUE(big.ok());
  ASSERT_EQ(full.times.size(), 50u);
  options.max_bytes = ViewTemplate().size() + 10 * 2000 * 16 * 4 / 3;  // about ten keyframes
  ViewReport capped;
  auto small = EncodeViewHtml(asset, options, &capped);
  ASSERT_TRUE(small.ok()) << small.status().ToString();
  EXPECT_LT(capped.times.size(), 50u);
  EXPECT_GE(capped.times.size(), 2u);
  EXPECT_LE(small->size(), options.max_bytes);
  EXPECT_EQ(capped.frames_requested, 50);
  ASSERT_FALSE(capped.notes.empty());
  options.max_bytes = ViewTemplate().size() + 1000;
  auto refused = EncodeViewHtml(asset, options);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), StatusCode::kBudgetTooSmall);
  // More keyframes than WebGL2 guarantees array-texture layers.
  ViewOptions too_many;
  too_many.frames = kViewMaxFrames + 1;
  EXPECT_EQ(EncodeViewHtml(asset, too_many).status().code(), StatusCode::kInvalidArgument);
}

TEST(View, DefaultCameraIsUprightAndLooksAtTheScene) {
  Asset asset = testing::MakeTestAsset({.count = 200, .sh_degree = 0, .textures = false, .deformation = false});
  for (UpAxis up : {UpAxis::kPosZ, UpAxis::kNegY, UpAxis::kPosY, UpAxis::kNegX}) {
    std::array<double, 3> target;
    const Camera cam = DefaultViewCamera(asset.gaussians, up, 640, 480, &target);
    const auto& m = cam.world_to_camera;
    // The camera's up (-y axis, in world coordinates: minus row 1) is the world's up, tilted
    // by the 20 degree elevation.
    std::array<double, 3> world_up{0, 0, 0};
    if (up == UpAxis::kPosZ) world_up = {0, 0, 1};
    if (up == UpAxis::kNegY) world_up = {0, -1, 0};
    if (up == UpAxis::kPosY) world_up = {0, 1, 0};
    if (up == UpAxis::kNegX) world_up = {-1, 0, 0};
    const double along = -(m[4] * world_up[0] + m[5] * world_up[1] + m[6] * world_up[2]);
    EXPECT_NEAR(along, std::cos(20.0 * M_PI / 180.0), 1e-9) << UpAxisName(up);
    // The target projects to the image centre, in front of the camera, and every robust
    // corner of the scene is in the picture.
    double u = 0, v = 0;
    ASSERT_TRUE(ProjectToImage(cam, target.data(), 0.2, &u, &v));
    EXPECT_NEAR(u, 320, 1e-6);
    EXPECT_NEAR(v, 240, 1e-6);
    size_t inside = 0;
    for (size_t i = 0; i < asset.gaussians.size(); ++i) {
      const double x[3] = {asset.gaussians.positions[i * 3], asset.gaussians.positions[i * 3 + 1],
                           asset.gaussians.positions[i * 3 + 2]};
      inside += ProjectToImage(cam, x, 0.2, &u, &v) ? 1 : 0;
    }
    EXPECT_GE(inside, asset.gaussians.size() * 9 / 10) << UpAxisName(up);
  }
  // The page records the asset's up axis (metadata.up) and this camera.
  asset.metadata.up = "+z";
  ViewReport report;
  const ViewPayload p = EncodeAndDecode(asset, {}, &report);
  EXPECT_EQ(p.header.at("up"), "+z");
  EXPECT_EQ(p.header.at("up_vector"), nlohmann::json::array({0.0, 0.0, 1.0}));
  EXPECT_EQ(p.header.at("camera").at("world_to_camera").get<std::vector<double>>(),
            std::vector<double>(report.camera.world_to_camera.begin(), report.camera.world_to_camera.end()));
}

TEST(View, GivenCameraIsKeptAndTheTitleEscaped) {
  const Asset asset = testing::MakeTestAsset({.count = 30, .sh_degree = 0, .textures = false, .deformation = false});
  ViewOptions options;
  Camera c;
  c.width = 100, c.height = 80, c.fx = 90, c.fy = 91, c.cx = 50, c.cy = 40;
  c.world_to_camera[11] = 6;  // 6 units in front
  options.camera = c;
  options.title = "a <b>&\"scene</script>";
  std::string page;
  ViewReport report;
  const ViewPayload p = EncodeAndDecode(asset, options, &report, &page);
  EXPECT_EQ(p.header.at("camera").at("fx"), 90.0);
  EXPECT_EQ(p.header.at("title"), options.title);  // JSON-escaped, not lost
  EXPECT_NE(page.find("<title>a &lt;b&gt;&amp;&quot;scene&lt;/script&gt;</title>"), std::string::npos);
  // Exactly the template's script elements: the title cannot close one.
  size_t scripts = 0;
  for (size_t at = page.find("</script>"); at != std::string::npos; at = page.find("</script>", at + 1)) ++scripts;
  EXPECT_EQ(scripts, 2u);
  EXPECT_EQ(page.find("/*ATEX_VIEW_DATA*/"), std::string::npos);
  // The orbit target is on the optical axis.
  EXPECT_NEAR(report.target[0], 0, 1e-9);
  EXPECT_NEAR(report.target[1], 0, 1e-9);
  ViewOptions bad;
  bad.camera = Camera{};
  EXPECT_EQ(EncodeViewHtml(asset, bad).status().code(), StatusCode::kInvalidArgument);
}

TEST(View, HostilePagesAreRefused) {
  const Asset asset = testing::MakeTestAsset({.count = 20, .sh_degree = 0, .textures = false, .deformation = true});
  ViewOptions options;
  options.frames = 3;
  auto html = EncodeViewHtml(asset, options);
  ASSERT_TRUE(html.ok());
  EXPECT_EQ(DecodeViewHtml("<html></html>").status().code(), StatusCode::kBadMagic);
  const size_t data = html->find("atex-view-data");
  ASSERT_NE(data, std::string::npos);
  EXPECT_EQ(DecodeViewHtml(html->substr(0, data + 100)).status().code(), StatusCode::kTruncated);
  std::string broken = *html;
  const size_t base64 = broken.find("\"data\":\"") + 8;
  broken[base64 + 5] = '!';
  EXPECT_EQ(DecodeViewHtml(broken).status().code(), StatusCode::kCorrupt);
  std::string wrong_count = *html;
  const size_t count = wrong_count.find("\"count\":20");
  ASSERT_NE(count, std::string::npos);
  wrong_count.replace(count, 10, "\"count\":21");
  EXPECT_EQ(DecodeViewHtml(wrong_count).status().code(), StatusCode::kCorrupt);
  std::string unknown = *html;
  const size_t encoding = unknown.find("delta-planes-deflate");
  ASSERT_NE(encoding, std::string::npos);
  unknown.replace(encoding, 5, "gamma");
  EXPECT_EQ(DecodeViewHtml(unknown).status().code(), StatusCode::kCorrupt);
  std::string not_json = *html;
  not_json.insert(data + 16, "{");
  EXPECT_EQ(DecodeViewHtml(not_json).status().code(), StatusCode::kCorrupt);
}

TEST(View, LegoSampleDecodesToItsDeformationAtTheKeyframes) {
  auto asset = ReadAssetFile((testing::SourceDir() / "samples" / "lego_adaptive_2MiB.atex").string());
  ASSERT_TRUE(asset.ok()) << asset.status().ToString();
  ViewOptions options;
  options.frames = 3;
  ViewReport report;
  const ViewPayload p = EncodeAndDecode(*asset, options, &report);
  ASSERT_EQ(p.times.size(), 3u);
  EXPECT_DOUBLE_EQ(p.times[1], 0.5 * (asset->metadata.time_min + asset->metadata.time_max));
  EXPECT_EQ(report.up, "+z");  // D-NeRF: Blender's Z-up world (metadata.up)
  ExpectKeyframesMatch(*asset, p);
  // The default keyframe count of this asset: its time grid has 13 nodes.
  EXPECT_EQ(DefaultViewFrames(*asset), 25);
}

}  // namespace
}  // namespace atex
