// Forward checks of the rasteriser against results derived independently of its
// code: closed-form footprints, an Eigen implementation of the EWA projection, a
// naive all-pairs renderer, and invariants (empty scene, occlusion, importance).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <optional>
#include <random>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "atex/render.h"
#include "render/render_test_util.h"

namespace atex {
namespace {

constexpr double kC0 = 0.28209479177387814;

Camera AxisCamera(int width, int height, double f, double cx, double cy) {
  Camera camera;
  camera.width = width;
  camera.height = height;
  camera.fx = camera.fy = f;
  camera.cx = cx;
  camera.cy = cy;
  return camera;  // identity pose: world = camera frame
}

// One Gaussian with DC colour `rgb` (SH degree 0).
template <typename T>
BasicGaussians<T> OneGaussian(std::array<double, 3> position, std::array<double, 3> scales, std::array<double, 4> q,
                              double opacity, std::array<double, 3> rgb) {
  BasicGaussians<T> g;
  g.sh_degree = 0;
  g.Resize(1);
  for (int k = 0; k < 3; ++k) {
    g.positions[k] = T(position[k]);
    g.log_scales[k] = T(std::log(scales[k]));
    g.sh[k] = T((rgb[k] - 0.5) / kC0);
  }
  for (int k = 0; k < 4; ++k) g.rotations[k] = T(q[k]);
  g.opacity_logits[0] = T(std::log(opacity / (1 - opacity)));
  return g;
}

void Append(BasicGaussians<double>* dst, const BasicGaussians<double>& src) {
  dst->sh_degree = src.sh_degree;
  dst->positions.insert(dst->positions.end(), src.positions.begin(), src.positions.end());
  dst->rotations.insert(dst->rotations.end(), src.rotations.begin(), src.rotations.end());
  dst->log_scales.insert(dst->log_scales.end(), src.log_scales.begin(), src.log_scales.end());
  dst->opacity_logits.insert(dst->opacity_logits.end(), src.opacity_logits.begin(), src.opacity_logits.end());
  dst->sh.insert(dst->sh.end(), src.sh.begin(), src.sh.end());
}

TEST(RenderForward, IsotropicGaussianFacingTheCameraHasTheClosedFormFootprint) {
  const double f = 30, z = 4, s = 0.5, opacity = 0.7;
  const Camera camera = AxisCamera(40, 30, f, 20.3, 14.6);
  // Any rotation: the Gaussian is isotropic.
  const auto g = OneGaussian<double>({0, 0, z}, {s, s, s}, {0.3, -0.5, 0.8, 0.1}, opacity, {0.8, 0.4, 0.2});
  RenderSettings settings;
  settings.background = {0.1f, 0.2f, 0.3f};
  auto out = RenderForward<double>(camera, g, nullptr, settings);
  ASSERT_TRUE(out.ok()) << out.status().ToString();
  // Σ₂ = (f s/z)² I + 0.3 I at the optical axis (the Jacobian's third column vanishes there).
  const double var = (f * s / z) * (f * s / z) + 0.3;
  EXPECT_NEAR(out->mean2d[0], 20.3, 1e-12);
  EXPECT_NEAR(out->mean2d[1], 14.6, 1e-12);
  EXPECT_NEAR(out->depth[0], z, 1e-12);
  EXPECT_EQ(out->radius[0], static_cast<int>(std::ceil(3 * std::sqrt(var + std::sqrt(0.1)))));
  const double rgb[3] = {0.8, 0.4, 0.2};
  double max_error = 0, alpha_sum = 0;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const double dx = x + 0.5 - 20.3, dy = y + 0.5 - 14.6;
      double a = opacity * std::exp(-(dx * dx + dy * dy) / (2 * var));
      if (a < 1.0 / 255) a = 0;
      const size_t p = size_t(y) * camera.width + x;
      for (int c = 0; c < 3; ++c) {
        max_error =
            std::max(max_error, std::abs(out->color[3 * p + c] - (rgb[c] * a + (1 - a) * settings.background[c])));
      }
      max_error = std::max(max_error, std::abs(out->alpha[p] - a));
      alpha_sum += a;
    }
  }
  EXPECT_LT(max_error, 1e-6);
  // With one Gaussian the blending weight is α̃ itself: importance = Σ alpha.
  EXPECT_NEAR(out->importance[0], alpha_sum, 1e-5);
}

TEST(RenderForward, ProjectionMatchesAnIndependentEigenEwa) {
  std::mt19937 rng(5);
  const Camera camera = render_testing::RandomCamera(64, 48, rng);
  render_testing::SceneOptions options;
  options.count = 40;
  const auto g = render_testing::RandomGaussians<double>(camera, options, rng);
  auto out = RenderForward<double>(camera, g, nullptr, RenderSettings{});
  ASSERT_TRUE(out.ok()) << out.status().ToString();
  Eigen::Matrix4d w2c;
  for (int k = 0; k < 16; ++k) w2c(k / 4, k % 4) = camera.world_to_camera[k];
  const Eigen::Matrix3d W = w2c.topLeftCorner<3, 3>();
  int checked = 0;
  for (size_t i = 0; i < g.size(); ++i) {
    const Eigen::Vector3d mu(g.positions[3 * i], g.positions[3 * i + 1], g.positions[3 * i + 2]);
    const Eigen::Vector3d t = W * mu + w2c.topRightCorner<3, 1>();
    if (t.z() <= 0.01) {
      EXPECT_EQ(out->radius[i], 0);
      continue;
    }
    const Eigen::Quaterniond q(g.rotations[4 * i], g.rotations[4 * i + 1], g.rotations[4 * i + 2],
                               g.rotations[4 * i + 3]);
    const Eigen::Matrix3d R = q.normalized().toRotationMatrix();
    const Eigen::Vector3d s(std::exp(g.log_scales[3 * i]), std::exp(g.log_scales[3 * i + 1]),
                            std::exp(g.log_scales[3 * i + 2]));
    const Eigen::Matrix3d cov = R * s.cwiseAbs2().asDiagonal() * R.transpose();
    // gsplat's clamp of x/z and y/z.
    const double tan_x = 0.5 * camera.width / camera.fx, tan_y = 0.5 * camera.height / camera.fy;
    const double lim_xp = (camera.width - camera.cx) / camera.fx + 0.3 * tan_x,
                 lim_xn = camera.cx / camera.fx + 0.3 * tan_x;
    const double lim_yp = (camera.height - camera.cy) / camera.fy + 0.3 * tan_y,
                 lim_yn = camera.cy / camera.fy + 0.3 * tan_y;
    const double tx = t.z() * std::clamp(t.x() / t.z(), -lim_xn, lim_xp);
    const double ty = t.z() * std::clamp(t.y() / t.z(), -lim_yn, lim_yp);
    Eigen::Matrix<double, 2, 3> J;
    J << camera.fx / t.z(), 0, -camera.fx * tx / (t.z() * t.z()), 0, camera.fy / t.z(),
        -camera.fy * ty / (t.z() * t.z());
    const Eigen::Matrix2d cov2 = J * W * cov * W.transpose() * J.transpose() + 0.3 * Eigen::Matrix2d::Identity();
    const Eigen::Matrix2d conic = cov2.inverse();
    const double mx = camera.fx * t.x() / t.z() + camera.cx, my = camera.fy * t.y() / t.z() + camera.cy;
    EXPECT_NEAR(out->mean2d[2 * i], mx, 1e-9);
    EXPECT_NEAR(out->mean2d[2 * i + 1], my, 1e-9);
    EXPECT_NEAR(out->depth[i], t.z(), 1e-12);
    const double mid = 0.5 * cov2.trace();
    const double radius = std::ceil(3 * std::sqrt(mid + std::sqrt(std::max(0.1, mid * mid - cov2.determinant()))));
    const int tiles_x = (camera.width + 15) / 16, tiles_y = (camera.height + 15) / 16;
    const int x0 = std::clamp<int>(std::floor((mx - radius) / 16), 0, tiles_x);
    const int x1 = std::clamp<int>(std::floor((mx + radius) / 16) + 1, 0, tiles_x);
    const int y0 = std::clamp<int>(std::floor((my - radius) / 16), 0, tiles_y);
    const int y1 = std::clamp<int>(std::floor((my + radius) / 16) + 1, 0, tiles_y);
    EXPECT_EQ(out->radius[i], x0 < x1 && y0 < y1 ? int(radius) : 0) << i;
    if (out->radius[i] > 0) {
      const double* c = &out->state.conic[3 * i];
      EXPECT_NEAR(c[0], conic(0, 0), 1e-9 * std::abs(conic(0, 0)) + 1e-12);
      EXPECT_NEAR(c[1], conic(0, 1), 1e-9 * std::abs(conic(0, 0)) + 1e-12);
      EXPECT_NEAR(c[2], conic(1, 1), 1e-9 * std::abs(conic(1, 1)) + 1e-12);
      ++checked;
    }
  }
  EXPECT_GT(checked, 30);
}

TEST(RenderForward, EmptySceneIsTheBackground) {
  const Camera camera = AxisCamera(33, 17, 20, 16, 8);
  BasicGaussians<float> g;
  g.sh_degree = 2;
  RenderSettings settings;
  settings.background = {0.25f, 0.5f, 1.0f};
  auto out = RenderForward<float>(camera, g, nullptr, settings);
  ASSERT_TRUE(out.ok()) << out.status().ToString();
  ASSERT_EQ(out->color.size(), size_t(33 * 17 * 3));
  for (size_t p = 0; p < size_t(33 * 17); ++p) {
    for (int c = 0; c < 3; ++c) EXPECT_EQ(out->color[3 * p + c], settings.background[c]);
    EXPECT_EQ(out->alpha[p], 0.0f);
  }
  BasicRenderGradients<float> grads;
  std::vector<float> ones(out->color.size(), 1.0f);
  EXPECT_TRUE(RenderBackward<float>(camera, g, nullptr, settings, *out, ones.data(), nullptr, &grads).ok());
  EXPECT_TRUE(grads.mean2d.empty());
}

TEST(RenderForward, GaussianBehindTheCameraIsInvisible) {
  const Camera camera = AxisCamera(32, 32, 20, 16, 16);
  for (double z : {-2.0, 0.0, 0.005}) {  // behind, at the centre, in front of the camera but before the near plane
    const auto g = OneGaussian<double>({0, 0, z}, {1, 1, 1}, {1, 0, 0, 0}, 0.9, {1, 1, 1});
    auto out = RenderForward<double>(camera, g, nullptr, RenderSettings{});
    ASSERT_TRUE(out.ok()) << out.status().ToString();
    EXPECT_EQ(out->radius[0], 0) << z;
    EXPECT_EQ(out->importance[0], 0.0);
    for (double a : out->alpha) EXPECT_EQ(a, 0.0);
  }
}

// The default near plane is the 3DGS rasterizer's 0.2 (kDefaultNearPlane): a Gaussian 0.15
// in front of the camera is culled, one at 0.25 is drawn (with 0.01, held-out Panoptic cameras
// lose 10 dB: BENCHMARKS.md stage 1).
TEST(RenderForward, DefaultNearPlaneIsTheRasterizersCull) {
  EXPECT_EQ(RenderSettings{}.near_plane, 0.2f);
  const Camera camera = AxisCamera(32, 32, 20, 16, 16);
  for (double z : {0.15, 0.25}) {
    const auto g = OneGaussian<double>({0, 0, z}, {0.01, 0.01, 0.01}, {1, 0, 0, 0}, 0.9, {1, 1, 1});
    auto out = RenderForward<double>(camera, g, nullptr, RenderSettings{});
    ASSERT_TRUE(out.ok()) << out.status().ToString();
    EXPECT_EQ(out->radius[0] > 0, z > 0.2) << z;
  }
}

TEST(RenderForward, FrontOpaqueGaussianHidesTheBackOne) {
  const Camera camera = AxisCamera(32, 32, 20, 16, 16);
  // Index order opposite to depth order: compositing must follow depth.
  BasicGaussians<double> g = OneGaussian<double>({0, 0, 6}, {2, 2, 2}, {1, 0, 0, 0}, 0.999, {0, 1, 0});  // back, green
  Append(&g, OneGaussian<double>({0, 0, 3}, {1, 1, 1}, {1, 0, 0, 0}, 0.999, {1, 0, 0}));             // front, red
  auto out = RenderForward<double>(camera, g, nullptr, RenderSettings{});
  ASSERT_TRUE(out.ok()) << out.status().ToString();
  const size_t centre = 16 * 32 + 16;
  // α̃ clamps at 0.99: red 0.99, then green gets 0.99 of the remaining 0.01.
  EXPECT_NEAR(out->color[3 * centre], 0.99, 1e-3);
  EXPECT_NEAR(out->color[3 * centre + 1], 0.01 * 0.99, 1e-3);
  EXPECT_LT(out->importance[0], out->importance[1]);
  // Swapping the depths swaps the result.
  std::swap(g.positions[2], g.positions[5]);
  auto swapped = RenderForward<double>(camera, g, nullptr, RenderSettings{});
  ASSERT_TRUE(swapped.ok());
  EXPECT_GT(swapped->color[3 * centre + 1], 0.95);
  EXPECT_LT(swapped->color[3 * centre], 0.05);
}

TEST(RenderForward, ZeroTexelsRenderExactlyLikeNoTexture) {
  std::mt19937 rng(7);
  const Camera camera = render_testing::RandomCamera(50, 40, rng);
  render_testing::SceneOptions options;
  options.count = 60;
  const auto g = render_testing::RandomGaussians<float>(camera, options, rng);
  for (auto kind : {render_testing::TextureKind::kUniform, render_testing::TextureKind::kAdaptiveMixed}) {
    auto pool = render_testing::RandomTextures(g, kind, 1.0, rng);
    std::fill(pool.texels.begin(), pool.texels.end(), 0.0f);
    RenderSettings settings;
    settings.background = {0.2f, 0.3f, 0.4f};
    auto plain = RenderForward<float>(camera, g, nullptr, settings);
    auto textured = RenderForward<float>(camera, g, &pool, settings);
    ASSERT_TRUE(plain.ok() && textured.ok());
    EXPECT_EQ(plain->color, textured->color);
    EXPECT_EQ(plain->alpha, textured->alpha);
    EXPECT_EQ(plain->importance, textured->importance);
  }
}

// A 1×2 texture with red on its +u texel, on a Gaussian facing the camera whose u
// axis is the camera's x axis: the closed form of conventions §5 pixel by pixel.
TEST(RenderForward, KnownTexturePatternMatchesTheClosedForm) {
  const double f = 30, z = 4, sx = 0.8, sy = 0.4, opacity = 0.6, red = 2.0, alpha_texel = 1.5;
  const double cx = 20.2, cy = 15.3;
  const Camera camera = AxisCamera(40, 32, f, cx, cy);
  const auto g = OneGaussian<double>({0, 0, z}, {sx, sy, 0.1}, {1, 0, 0, 0}, opacity, {0.3, 0.3, 0.3});
  BasicTexturePool<double> pool;
  pool.heights = {1};
  pool.widths = {2};
  pool.axis_u = {0};
  pool.axis_v = {1};
  pool.RebuildOffsets();
  pool.texels = {0, 0, 0, alpha_texel, red, 0, 0, alpha_texel};  // texel (0,0) at u = −1, (0,1) at u = +1
  auto out = RenderForward(camera, g, &pool, RenderSettings{});
  ASSERT_TRUE(out.ok()) << out.status().ToString();
  const double var_x = (f * sx / z) * (f * sx / z) + 0.3, var_y = (f * sy / z) * (f * sy / z) + 0.3;
  const double factor = std::exp(0.1 * std::tanh(alpha_texel));
  double max_error = 0;
  int right_brighter = 0, pairs = 0;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const double dx = x + 0.5 - cx, dy = y + 0.5 - cy;
      double a = std::min(0.99, opacity * std::exp(-0.5 * (dx * dx / var_x + dy * dy / var_y)) * factor);
      if (a < 1.0 / 255) a = 0;
      // The ray through the pixel meets the plane z = 4 at x = z dx / f: u = x / sx.
      const double u = std::clamp(z * dx / f / sx, -1.0, 1.0);
      const double r = (u + 1) / 2 * red;
      const size_t p = size_t(y) * camera.width + x;
      max_error = std::max(max_error, std::abs(out->color[3 * p] - (0.3 + 0.1 * std::tanh(r)) * a));
      max_error = std::max(max_error, std::abs(out->color[3 * p + 1] - 0.3 * a));
      max_error = std::max(max_error, std::abs(out->alpha[p] - a));
    }
  }
  EXPECT_LT(max_error, 1e-9);
  // Qualitatively: red is stronger right of the centre (+u) than at the mirrored pixel.
  for (int y = 10; y < 20; ++y) {
    for (int k = 1; k < 10; ++k) {
      const int right = 20 + k, left = 20 - k;  // mirrored about x = 20.5 ≈ cx
      const size_t pr = size_t(y) * camera.width + right, pl = size_t(y) * camera.width + left;
      if (out->alpha[pr] < 0.05) continue;
      ++pairs;
      right_brighter += out->color[3 * pr] / out->alpha[pr] > out->color[3 * pl] / out->alpha[pl];
    }
  }
  EXPECT_GT(pairs, 20);
  EXPECT_EQ(right_brighter, pairs);
}

TEST(RenderForward, TiledRendererMatchesNaiveAllPairsRenderer) {
  std::mt19937 rng(9);
  for (auto kind : {render_testing::TextureKind::kNone, render_testing::TextureKind::kUniform,
                    render_testing::TextureKind::kAdaptiveMixed}) {
    const Camera camera = render_testing::RandomCamera(70, 53, rng);
    render_testing::SceneOptions options;
    options.count = 150;
    options.opaque = kind == render_testing::TextureKind::kUniform;
    const auto g = render_testing::RandomGaussians<double>(camera, options, rng);
    std::optional<BasicTexturePool<double>> pool;
    if (kind != render_testing::TextureKind::kNone) pool = render_testing::RandomTextures(g, kind, 1.5, rng);
    const BasicTexturePool<double>* tex = pool ? &*pool : nullptr;
    RenderSettings settings;
    settings.background = {0.5f, 0.1f, 0.9f};
    auto out = RenderForward(camera, g, tex, settings);
    ASSERT_TRUE(out.ok()) << out.status().ToString();
    std::vector<double> color, alpha;
    render_testing::NaiveRender(camera, g, tex, settings, &color, &alpha);
    double max_diff = 0;
    for (size_t k = 0; k < color.size(); ++k) max_diff = std::max(max_diff, std::abs(color[k] - out->color[k]));
    for (size_t k = 0; k < alpha.size(); ++k) max_diff = std::max(max_diff, std::abs(alpha[k] - out->alpha[k]));
    EXPECT_LT(max_diff, 1e-12);
    // Σ_i w_i = 1 − T_final per pixel, so the importances sum to the alpha image's sum.
    double importance = 0, alpha_sum = 0;
    for (double v : out->importance) importance += v;
    for (double v : out->alpha) alpha_sum += v;
    EXPECT_NEAR(importance, alpha_sum, 1e-9 * alpha_sum);
  }
}

#ifdef _OPENMP
TEST(RenderForward, ResultsAreBitIdenticalForAnyThreadCount) {
  std::mt19937 rng(10);
  const Camera camera = render_testing::RandomCamera(96, 80, rng);
  render_testing::SceneOptions options;
  options.count = 3000;  // above the per-Gaussian parallel threshold
  const auto g = render_testing::RandomGaussians<float>(camera, options, rng);
  const auto pool = render_testing::RandomTextures(g, render_testing::TextureKind::kAdaptiveMixed, 1.0, rng);
  std::vector<float> grad_color(size_t(camera.width) * camera.height * 3),
      grad_alpha(size_t(camera.width) * camera.height);
  std::uniform_real_distribution<float> weight(-1, 1);
  for (float& v : grad_color) v = weight(rng);
  for (float& v : grad_alpha) v = weight(rng);
  const int saved = omp_get_max_threads();
  std::vector<RenderOutput> outputs;
  std::vector<RenderGradients> grads;
  for (int threads : {1, 2, 3}) {
    omp_set_num_threads(threads);
    auto out = RenderForward(camera, g, &pool, RenderSettings{});
    ASSERT_TRUE(out.ok());
    RenderGradients grad;
    ASSERT_TRUE(
        RenderBackward(camera, g, &pool, RenderSettings{}, *out, grad_color.data(), grad_alpha.data(), &grad).ok());
    outputs.push_back(std::move(*out));
    grads.push_back(std::move(grad));
  }
  omp_set_num_threads(saved);
  for (size_t k = 1; k < outputs.size(); ++k) {
    EXPECT_EQ(outputs[k].color, outputs[0].color);
    EXPECT_EQ(outputs[k].importance, outputs[0].importance);
    EXPECT_EQ(grads[k].gaussians.positions, grads[0].gaussians.positions);
    EXPECT_EQ(grads[k].gaussians.rotations, grads[0].gaussians.rotations);
    EXPECT_EQ(grads[k].gaussians.sh, grads[0].gaussians.sh);
    EXPECT_EQ(grads[k].texels, grads[0].texels);
    EXPECT_EQ(grads[k].mean2d, grads[0].mean2d);
  }
}
#endif

TEST(RenderForward, FloatAgreesWithDouble) {
  std::mt19937 rng(12);
  const Camera camera = render_testing::RandomCamera(48, 40, rng);
  render_testing::SceneOptions options;
  options.count = 80;
  std::mt19937 rng_copy = rng;
  const auto gd = render_testing::RandomGaussians<double>(camera, options, rng);
  const auto gf = render_testing::RandomGaussians<float>(camera, options, rng_copy);
  const auto pd = render_testing::RandomTextures(gd, render_testing::TextureKind::kAdaptiveMixed, 1.0, rng);
  const auto pf = render_testing::RandomTextures(gf, render_testing::TextureKind::kAdaptiveMixed, 1.0, rng_copy);
  auto od = RenderForward(camera, gd, &pd, RenderSettings{});
  auto of = RenderForward(camera, gf, &pf, RenderSettings{});
  ASSERT_TRUE(od.ok() && of.ok());
  double max_diff = 0;
  for (size_t k = 0; k < od->color.size(); ++k)
    max_diff = std::max(max_diff, std::abs(od->color[k] - double(of->color[k])));
  EXPECT_LT(max_diff, 1e-4);
}

TEST(RenderForward, HugeButFiniteValuesDoNotBreakTheRenderer) {
  const Camera camera = AxisCamera(32, 32, 20, 16, 16);
  BasicGaussians<float> g = OneGaussian<float>({0, 0, 3}, {1, 1, 1}, {1, 0, 0, 0}, 0.9, {1, 1, 1});
  for (const auto& [pos, log_scale] : std::vector<std::pair<std::array<float, 3>, float>>{{{1e30f, 0, 3}, 0.0f},
                                                                                          {{0, 0, 3}, 80.0f},
                                                                                          {{0, 0, 3}, -80.0f},
                                                                                          {{0, 0, 1e-6f + 0.01f}, 5.0f},
                                                                                          {{0, 0, 1e35f}, 0.0f}}) {
    for (int k = 0; k < 3; ++k) {
      g.positions[k] = pos[k];
      g.log_scales[k] = log_scale;
    }
    auto pool = AttachTextures(g, TextureMode::kUniform);
    ASSERT_TRUE(pool.ok());
    std::fill(pool->texels.begin(), pool->texels.end(), 0.5f);
    auto out = RenderForward(camera, g, &*pool, RenderSettings{});
    ASSERT_TRUE(out.ok()) << out.status().ToString();
    for (float v : out->color) ASSERT_TRUE(std::isfinite(v));
    std::vector<float> grad(out->color.size(), 1.0f);
    RenderGradients grads;
    ASSERT_TRUE(RenderBackward(camera, g, &*pool, RenderSettings{}, *out, grad.data(), nullptr, &grads).ok());
  }
}

}  // namespace
}  // namespace atex
