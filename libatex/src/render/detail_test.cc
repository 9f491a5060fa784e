// Each ATEX_HD forward function of atex/detail against closed forms, and its
// vector-Jacobian product against central finite differences (double), so that a
// wrong term is pinned to one function rather than to the whole renderer.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <random>
#include <vector>

#include "atex/detail/composite.h"
#include "atex/detail/projection.h"
#include "atex/detail/quaternion.h"
#include "atex/detail/sh.h"
#include "atex/detail/texture.h"

namespace atex::detail {
namespace {

using Vector = std::vector<double>;
using Function = std::function<Vector(const Vector&)>;
using Vjp = std::function<Vector(const Vector& x, const Vector& g_out)>;

// max_k |vjp(x, g)_k − ∂(g·f)/∂x_k| relative to the largest gradient entry.
double VjpError(const Function& f, const Vjp& vjp, const Vector& x, std::mt19937& rng) {
  std::uniform_real_distribution<double> weight(-1, 1);
  const Vector y = f(x);
  Vector g(y.size());
  for (double& v : g) v = weight(rng);
  const Vector analytic = vjp(x, g);
  EXPECT_EQ(analytic.size(), x.size());
  double max_error = 0, scale = 1e-12;
  for (size_t k = 0; k < x.size(); ++k) {
    const double h = 1e-6;
    Vector xp = x, xm = x;
    xp[k] += h;
    xm[k] -= h;
    const Vector yp = f(xp), ym = f(xm);
    double fd = 0;
    for (size_t j = 0; j < y.size(); ++j) fd += g[j] * (yp[j] - ym[j]) / (2 * h);
    max_error = std::max(max_error, std::abs(fd - analytic[k]));
    scale = std::max(scale, std::abs(fd));
  }
  return max_error / scale;
}

Vec3<double> V3(const Vector& x, size_t at) { return {{x[at], x[at + 1], x[at + 2]}}; }
Vec4<double> V4(const Vector& x, size_t at) { return {{x[at], x[at + 1], x[at + 2], x[at + 3]}}; }
Mat3<double> M3(const Vector& x, size_t at) {
  Mat3<double> m;
  for (int k = 0; k < 9; ++k) m(k / 3, k % 3) = x[at + k];
  return m;
}
void Put(Vector* out, const Vec3<double>& v) { out->insert(out->end(), v.v, v.v + 3); }
void Put(Vector* out, const Mat3<double>& m) {
  for (int k = 0; k < 9; ++k) out->push_back(m(k / 3, k % 3));
}
void Put(Vector* out, const TextureFrame<double>& f) {
  Put(out, f.axis_u);
  Put(out, f.axis_v);
  Put(out, f.normal);
  out->insert(out->end(), {f.offset_u, f.offset_v, f.offset_n, f.inv_scale_u, f.inv_scale_v});
}
TextureFrame<double> Frame(const Vector& x, size_t at) {
  TextureFrame<double> f;
  f.axis_u = V3(x, at);
  f.axis_v = V3(x, at + 3);
  f.normal = V3(x, at + 6);
  f.offset_u = x[at + 9];
  f.offset_v = x[at + 10];
  f.offset_n = x[at + 11];
  f.inv_scale_u = x[at + 12];
  f.inv_scale_v = x[at + 13];
  return f;
}
Vector Random(size_t n, double lo, double hi, std::mt19937& rng) {
  std::uniform_real_distribution<double> d(lo, hi);
  Vector v(n);
  for (double& x : v) x = d(rng);
  return v;
}

CameraModel<double> TestCamera() {
  Camera camera;
  camera.width = 64;
  camera.height = 48;
  camera.fx = 50;
  camera.fy = 45;
  camera.cx = 30;
  camera.cy = 25;
  return MakeCameraModel<double>(camera, 0.01);
}

TEST(DetailQuaternion, MatchesTheRotationAboutAnAxisAndIsScaleInvariant) {
  const double angle = 0.7;
  // 2.5 × the unit quaternion of a rotation by `angle` about z.
  const auto r = QuaternionToRotation(Vec4<double>{{2.5 * std::cos(angle / 2), 0, 0, 2.5 * std::sin(angle / 2)}});
  const double expected[3][3] = {
      {std::cos(angle), -std::sin(angle), 0}, {std::sin(angle), std::cos(angle), 0}, {0, 0, 1}};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) EXPECT_NEAR(r(i, j), expected[i][j], 1e-15);
  // About x by 90°: local y maps to world z (column 1 of R).
  const auto rx = QuaternionToRotation(Vec4<double>{{std::sqrt(0.5), std::sqrt(0.5), 0, 0}});
  EXPECT_NEAR(rx(2, 1), 1.0, 1e-15);
}

TEST(DetailQuaternion, Vjp) {
  std::mt19937 rng(1);
  for (int trial = 0; trial < 5; ++trial) {
    const Function f = [](const Vector& x) {
      Vector out;
      Put(&out, QuaternionToRotation(V4(x, 0)));
      return out;
    };
    const Vjp vjp = [](const Vector& x, const Vector& g) {
      const auto gq = QuaternionToRotationVjp(V4(x, 0), M3(g, 0));
      return Vector(gq.v, gq.v + 4);
    };
    EXPECT_LT(VjpError(f, vjp, Random(4, -1.5, 1.5, rng), rng), 1e-8);
  }
}

TEST(DetailProjection, CovarianceVjp) {
  std::mt19937 rng(2);
  const Function f = [](const Vector& x) {
    Vector out;
    Put(&out, CovarianceFromRotationScale(M3(x, 0), V3(x, 9)));
    return out;
  };
  const Vjp vjp = [](const Vector& x, const Vector& g) {
    Mat3<double> g_r = ZeroMat3<double>();
    Vec3<double> g_s{{0, 0, 0}};
    CovarianceFromRotationScaleVjp(M3(x, 0), V3(x, 9), M3(g, 0), &g_r, &g_s);
    Vector out;
    Put(&out, g_r);
    Put(&out, g_s);
    return out;
  };
  EXPECT_LT(VjpError(f, vjp, Random(12, -1, 1, rng), rng), 1e-8);
}

TEST(DetailProjection, ConicVjp) {
  std::mt19937 rng(3);
  const Function f = [](const Vector& x) {
    Vec3<double> conic{{0, 0, 0}};
    EXPECT_TRUE(InvertCovariance2d(V3(x, 0), &conic));
    return Vector(conic.v, conic.v + 3);
  };
  const Vjp vjp = [](const Vector& x, const Vector& g) {
    Vec3<double> conic{{0, 0, 0}};
    InvertCovariance2d(V3(x, 0), &conic);
    const auto gc = InvertCovariance2dVjp(conic, V3(g, 0));
    return Vector(gc.v, gc.v + 3);
  };
  EXPECT_LT(VjpError(f, vjp, {4.0, 1.3, 2.5}, rng), 1e-8);
  Vec3<double> conic{{7, 7, 7}};
  EXPECT_FALSE(InvertCovariance2d(Vec3<double>{{1, 2, 1}}, &conic));  // det < 0
  EXPECT_EQ(conic[0], 7);
}

// The whole per-Gaussian projection, with the rotation matrix as free input; one
// case inside the view and one beyond the Jacobian's clamp.
TEST(DetailProjection, ProjectGaussianVjp) {
  std::mt19937 rng(4);
  const auto cam = TestCamera();
  for (double x_over_z : {0.1, -0.3, 1.2, -1.4}) {
    const Vector mean{x_over_z * 3, -0.2, 3};
    Vector x = mean;
    const auto r = QuaternionToRotation(Vec4<double>{{0.9, 0.2, -0.3, 0.4}});
    Put(&x, r);
    Put(&x, Vec3<double>{{std::log(0.3), std::log(0.1), std::log(0.2)}});
    const Function f = [&](const Vector& in) {
      const auto p = ProjectGaussian(cam, V3(in, 0), M3(in, 3), V3(in, 12));
      EXPECT_TRUE(p.visible || std::abs(x_over_z) > 1);
      // Off-screen Gaussians have no rectangle; use the raw values through the detail steps.
      const auto t = WorldToCamera(cam, V3(in, 0));
      const auto cov2d =
          ProjectCovariance(cam, ProjectionJacobian(cam, t), CovarianceFromRotationScale(M3(in, 3), V3(in, 12)));
      Vec3<double> conic{{0, 0, 0}};
      InvertCovariance2d(cov2d, &conic);
      const auto m = ProjectPoint(cam, t);
      return Vector{m[0], m[1], conic[0], conic[1], conic[2]};
    };
    const Vjp vjp = [&](const Vector& in, const Vector& g) {
      Vec3<double> g_mean{{0, 0, 0}}, g_s{{0, 0, 0}};
      Mat3<double> g_r = ZeroMat3<double>();
      ProjectGaussianVjp(cam, V3(in, 0), M3(in, 3), V3(in, 12), Vec2<double>{{g[0], g[1]}}, V3(g, 2), &g_mean, &g_r,
                         &g_s);
      Vector out;
      Put(&out, g_mean);
      Put(&out, g_r);
      Put(&out, g_s);
      return out;
    };
    EXPECT_LT(VjpError(f, vjp, x, rng), 1e-7) << x_over_z;
  }
}

TEST(DetailProjection, TileRectangleAndRadius) {
  // mid = 5, det = 25 - 0 → max(0.1, 0) → λ = 5 + sqrt(0.1).
  EXPECT_NEAR(ProjectedExtent(Vec3<double>{{5, 0, 5}}), 3 * std::sqrt(5 + std::sqrt(0.1)), 1e-14);
  // Anisotropic: eigenvalues 9 and 1 → λ_max = 9.
  EXPECT_NEAR(ProjectedExtent(Vec3<double>{{9, 0, 1}}), 9.0, 1e-14);
  auto rect = ComputeTileRect(Vec2<double>{{20.0, 40.0}}, 5.0, 4, 3);
  EXPECT_EQ(rect.x0, 0);   // floor(15/16)
  EXPECT_EQ(rect.x1, 2);   // floor(25/16) + 1
  EXPECT_EQ(rect.y0, 2);   // floor(35/16)
  EXPECT_EQ(rect.y1, 3);   // floor(45/16) + 1 = 3, clamped to 3
  rect = ComputeTileRect(Vec2<double>{{-1e30, 5.0}}, 3.0, 4, 3);
  EXPECT_TRUE(rect.empty());
  rect = ComputeTileRect(Vec2<double>{{100.0, 5.0}}, 3.0, 4, 3);  // right of a 64-pixel image
  EXPECT_TRUE(rect.empty());
}

// Every pixel where a splat can pass the 1/255 alpha cut lies in a tile of its
// contribution rectangle (brute force over a 128×96 image), the cut rectangle lies in
// the 3σ one, and faint or elongated splats do lose tiles.
TEST(DetailProjection, ContributionTileRectKeepsEveryContributingPixel) {
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> unit(0, 1);
  const int width = 128, height = 96, tiles_x = 8, tiles_y = 6;
  int shrunk = 0, emptied = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const Vec2<double> mean{{-20 + 170 * unit(rng), -20 + 140 * unit(rng)}};
    const double sx = 0.5 + 30 * unit(rng) * unit(rng), sy = 0.5 + 30 * unit(rng) * unit(rng);
    const double rho = -0.95 + 1.9 * unit(rng);
    const Vec3<double> cov2d{{sx * sx + kCov2dBlur, rho * sx * sy, sy * sy + kCov2dBlur}};
    Vec3<double> conic;
    ASSERT_TRUE(InvertCovariance2d(cov2d, &conic));
    const double opacity = std::pow(10.0, -3.0 + 3.0 * unit(rng));  // 0.001 .. 1
    const double factor = trial % 2 ? kTextureAlphaFactorBound : 1.0;
    const TileRect rect = ComputeTileRect(mean, std::ceil(ProjectedExtent(cov2d)), tiles_x, tiles_y);
    const TileRect cut = ContributionTileRect(rect, mean, cov2d, opacity * factor, tiles_x, tiles_y);
    if (!cut.empty()) {
      EXPECT_TRUE(cut.x0 >= rect.x0 && cut.x1 <= rect.x1 && cut.y0 >= rect.y0 && cut.y1 <= rect.y1);
    }
    const int area = rect.empty() ? 0 : (rect.x1 - rect.x0) * (rect.y1 - rect.y0);
    const int cut_area = cut.empty() ? 0 : (cut.x1 - cut.x0) * (cut.y1 - cut.y0);
    shrunk += cut_area < area;
    emptied += area > 0 && cut_area == 0;
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) {
        const int tx = x / kTileSize, ty = y / kTileSize;
        if (!rect.contains(tx, ty)) continue;
        const double power = GaussianPower(conic, x + 0.5 - mean[0], y + 0.5 - mean[1]);
        const bool passes = power <= 0 && opacity * std::exp(power) * factor >= kMinSplatAlpha;
        if (passes) {
          ASSERT_TRUE(cut.contains(tx, ty)) << "trial " << trial << " pixel " << x << "," << y;
        }
      }
    }
  }
  EXPECT_GT(shrunk, 100);
  EXPECT_GT(emptied, 10);  // opacity × factor < 1/255: no tiles at all
}

TEST(DetailComposite, OneTexelSkipsCoordinatesWithTheSameSample) {
  // A 1×1 texture through the coordinate-free path (with and without the precomputed
  // ConstantTexel) gives exactly what the general bilinear path gives.
  const auto r = QuaternionToRotation(Vec4<double>{{0.9, 0.1, -0.2, 0.3}});
  const TextureFrame<double> frame = MakeTextureFrame(r, Vec3<double>{{0.1, 0.1, 3.0}},
                                                      Vec3<double>{{-0.5, -0.7, -1.0}}, Vec3<double>{{0, 0, 0}}, 0, 1);
  const double texel[4] = {0.7, -1.3, 0.2, 2.1};
  SplatParams<double> s;
  s.mean2d = {{10.2, 7.9}};
  s.conic = {{0.08, 0.02, 0.12}};
  s.opacity = 0.6;
  s.color = {{0.3, 0.5, 0.7}};
  s.frame = &frame;
  s.texels = texel;
  s.tex_h = s.tex_w = 1;
  const Vec3<double> ray{{0.03, 0.02, 1.0}};
  const SplatSample<double> fast = EvaluateSplat(s, 11.5, 8.5, ray);
  const ConstantTexel<double> constant = MakeConstantTexel(texel);
  s.constant = &constant;
  const SplatSample<double> precomputed = EvaluateSplat(s, 11.5, 8.5, ray);
  // The general path, step by step.
  const TexCoord<double> tc = ComputeTexCoord(frame, ray);
  const Vec4<double> sampled = SampleTexels(texel, 1, MakeBilinearTaps(tc, 1, 1));
  const double alpha = s.opacity * fast.falloff * TextureAlphaFactor(sampled[3]);
  ASSERT_TRUE(fast.contributes);
  for (const auto& smp : {fast, precomputed}) {
    EXPECT_EQ(smp.alpha, alpha);
    for (int ch = 0; ch < 3; ++ch) EXPECT_EQ(smp.color[ch], s.color[ch] + TextureColorResidual(sampled[ch]));
    for (int c = 0; c < 4; ++c) EXPECT_EQ(smp.texel[c], texel[c]);
  }
  // The VJP: all of the texel gradient on the one texel, none on the frame.
  auto grad = ZeroSplatGrad<double>();
  double g_texel[4] = {0, 0, 0, 0};
  EvaluateSplatVjp(s, ray, precomputed, Vec3<double>{{0.5, -0.25, 1.0}}, 0.75, &grad, g_texel);
  for (int c = 0; c < 4; ++c) EXPECT_NE(g_texel[c], 0.0) << c;
  EXPECT_EQ(grad.frame.offset_n, 0.0);
  EXPECT_EQ(grad.frame.inv_scale_u, 0.0);
}

TEST(DetailSh, DegreeZeroAndOneClosedForm) {
  const double sh[12] = {1.0, -2.0, 0.5, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9};
  bool clamped[3];
  const Vec3<double> dir{{0, 0, 2}};  // v = +z: Y1 = 0, Y2 = C1, Y3 = 0
  auto c = ShColor(0, sh, dir, clamped);
  EXPECT_NEAR(c[0], kShC0 * 1.0 + 0.5, 1e-15);
  EXPECT_EQ(c[1], 0.0);  // kShC0·(−2) + 0.5 < 0: clamped
  EXPECT_TRUE(clamped[1]);
  EXPECT_FALSE(clamped[0]);
  c = ShColor(1, sh, dir, clamped);
  EXPECT_NEAR(c[0], kShC0 * 1.0 + kShC1 * 0.4 + 0.5, 1e-15);
  EXPECT_NEAR(c[2], kShC0 * 0.5 + kShC1 * 0.6 + 0.5, 1e-15);
}

TEST(DetailSh, VjpAtEveryDegree) {
  std::mt19937 rng(5);
  for (int degree = 0; degree <= 3; ++degree) {
    const int k = (degree + 1) * (degree + 1);
    Vector x = Random(3 * k, -0.3, 0.3, rng);
    for (int ch = 0; ch < 3; ++ch) x[ch] = 1.0;  // keep every channel above the clamp
    const Vector dir = Random(3, -2, 2, rng);
    x.insert(x.end(), dir.begin(), dir.end());
    const Function f = [&](const Vector& in) {
      bool clamped[3];
      const auto c = ShColor(degree, in.data(), V3(in, 3 * k), clamped);
      return Vector(c.v, c.v + 3);
    };
    const Vjp vjp = [&](const Vector& in, const Vector& g) {
      bool clamped[3];
      ShColor(degree, in.data(), V3(in, 3 * k), clamped);
      Vector out(3 * k, 0.0);
      const auto g_dir = ShColorVjp(degree, in.data(), V3(in, 3 * k), clamped, V3(g, 0), out.data());
      Put(&out, g_dir);
      return out;
    };
    EXPECT_LT(VjpError(f, vjp, x, rng), 1e-8) << "degree " << degree;
  }
}

TEST(DetailTexture, FrameAndCoordinatesVjp) {
  std::mt19937 rng(6);
  const Vec3<double> center{{0.1, -0.2, 0.3}};
  const auto r = QuaternionToRotation(Vec4<double>{{0.8, -0.3, 0.5, 0.2}});
  Vector x;
  Put(&x, r);
  Put(&x, Vec3<double>{{0.2, 0.1, 3.0}});
  Put(&x, Vec3<double>{{std::log(0.5), std::log(0.4), std::log(0.3)}});
  for (int axis_u : {0, 1, 2}) {
    const int axis_v = (axis_u + 2) % 3;
    const Function f = [&](const Vector& in) {
      Vector out;
      Put(&out, MakeTextureFrame(M3(in, 0), V3(in, 9), V3(in, 12), center, axis_u, axis_v));
      return out;
    };
    const Vjp vjp = [&](const Vector& in, const Vector& g) {
      Mat3<double> g_r = ZeroMat3<double>();
      Vec3<double> g_mean{{0, 0, 0}}, g_s{{0, 0, 0}};
      MakeTextureFrameVjp(M3(in, 0), V3(in, 9), V3(in, 12), center, axis_u, axis_v, Frame(g, 0), &g_r, &g_mean, &g_s);
      Vector out;
      Put(&out, g_r);
      Put(&out, g_mean);
      Put(&out, g_s);
      return out;
    };
    EXPECT_LT(VjpError(f, vjp, x, rng), 1e-8);
  }
  // Texture coordinates of a ray, as functions of the 14 frame fields.
  Vector frame;
  Put(&frame, MakeTextureFrame(r, Vec3<double>{{0.2, 0.1, 3.0}}, Vec3<double>{{0.5, 0.2, 0.4}}, center, 0, 2));
  const Vec3<double> ray{{0.05, -0.02, 1.0}};
  const auto tc0 = ComputeTexCoord(Frame(frame, 0), ray);
  ASSERT_FALSE(tc0.u_clamped || tc0.v_clamped);
  const Function f = [&](const Vector& in) {
    const auto tc = ComputeTexCoord(Frame(in, 0), ray);
    return Vector{tc.u, tc.v};
  };
  const Vjp vjp = [&](const Vector& in, const Vector& g) {
    auto g_frame = ZeroTextureFrame<double>();
    ComputeTexCoordVjp(Frame(in, 0), ray, ComputeTexCoord(Frame(in, 0), ray), g[0], g[1], &g_frame);
    Vector out;
    Put(&out, g_frame);
    return out;
  };
  EXPECT_LT(VjpError(f, vjp, frame, rng), 1e-8);
}

TEST(DetailTexture, RayPlaneIntersectionClosedForm) {
  // Plane z = 4 facing the camera at the origin, u along x with scale 2, v along y with scale 0.5.
  Mat3<double> identity = ZeroMat3<double>();
  for (int k = 0; k < 3; ++k) identity(k, k) = 1;
  const auto frame = MakeTextureFrame(identity, Vec3<double>{{0.5, 0, 4}},
                                      Vec3<double>{{std::log(2.0), std::log(0.5), 0}}, Vec3<double>{{0, 0, 0}}, 0, 1);
  const auto tc = ComputeTexCoord(frame, Vec3<double>{{0.25, 0.05, 1.0}});  // hits (1, 0.2, 4)
  EXPECT_NEAR(tc.u, (1.0 - 0.5) / 2, 1e-15);
  EXPECT_NEAR(tc.v, 0.2 / 0.5, 1e-15);
  const auto far = ComputeTexCoord(frame, Vec3<double>{{2.0, 0.0, 1.0}});  // x = 8: clamped
  EXPECT_TRUE(far.u_clamped);
  EXPECT_EQ(far.u, 1.0);
  // An edge-on plane: the ray is parallel; finite, clamped coordinates.
  const auto edge = ComputeTexCoord(frame, Vec3<double>{{1.0, 0.0, 0.0}});
  EXPECT_TRUE(std::isfinite(edge.u) && std::isfinite(edge.v));
  bool replaced;
  EXPECT_EQ(SafePlaneDenominator(0.0, &replaced), kMinPlaneDenominator);
  EXPECT_TRUE(replaced);
  EXPECT_EQ(SafePlaneDenominator(-1e-12, &replaced), -kMinPlaneDenominator);
}

TEST(DetailTexture, BilinearSampleVjp) {
  std::mt19937 rng(7);
  for (auto [h, w] : {std::pair{1, 1}, {1, 4}, {4, 1}, {2, 4}, {4, 4}}) {
    const size_t n = size_t(h) * w * 4;
    Vector x = Random(n, -1, 1, rng);
    x.push_back(0.37);   // u (off the knots)
    x.push_back(-0.21);  // v
    const Function f = [&](const Vector& in) {
      TexCoord<double> tc{in[n], in[n + 1], false, false};
      const auto s = SampleTexels(in.data(), w, MakeBilinearTaps(tc, h, w));
      return Vector(s.v, s.v + 4);
    };
    const Vjp vjp = [&](const Vector& in, const Vector& g) {
      TexCoord<double> tc{in[n], in[n + 1], false, false};
      Vector out(n, 0.0);
      double g_u, g_v;
      SampleTexelsVjp(in.data(), h, w, MakeBilinearTaps(tc, h, w), V4(g, 0), out.data(), &g_u, &g_v);
      out.push_back(g_u);
      out.push_back(g_v);
      return out;
    };
    EXPECT_LT(VjpError(f, vjp, x, rng), 1e-8) << h << "x" << w;
  }
  // Corner-aligned: u = −1 is texel column 0, u = +1 the last column.
  const double texels[8] = {1, 2, 3, 4, 5, 6, 7, 8};  // 1x2
  EXPECT_EQ(SampleTexels(texels, 2, MakeBilinearTaps(TexCoord<double>{-1, 0, false, false}, 1, 2))[0], 1);
  EXPECT_EQ(SampleTexels(texels, 2, MakeBilinearTaps(TexCoord<double>{1, 0, false, false}, 1, 2))[0], 5);
  EXPECT_EQ(SampleTexels(texels, 2, MakeBilinearTaps(TexCoord<double>{0, 0, false, false}, 1, 2))[3], 6);
}

// One splat at one pixel: (c̃, α̃) as a function of everything the rasteriser reads.
TEST(DetailComposite, EvaluateSplatVjp) {
  std::mt19937 rng(8);
  const int h = 2, w = 4;
  const size_t nt = size_t(h) * w * 4;
  Vector x{10.2, 7.9,         // mean2d
           0.08, 0.02, 0.12,  // conic
           0.6,               // opacity
           0.3, 0.5, 0.7};    // colour
  Vector frame;
  const auto r = QuaternionToRotation(Vec4<double>{{0.9, 0.1, -0.2, 0.3}});
  Put(&frame, MakeTextureFrame(r, Vec3<double>{{0.1, 0.1, 3.0}}, Vec3<double>{{-0.5, -0.7, -1.0}},
                               Vec3<double>{{0, 0, 0}}, 0, 1));
  x.insert(x.end(), frame.begin(), frame.end());
  const Vector texels = Random(nt, -1, 1, rng);
  x.insert(x.end(), texels.begin(), texels.end());
  const double px = 11.5, py = 8.5;
  const Vec3<double> ray{{0.03, 0.02, 1.0}};
  const auto params = [&](const Vector& in, TextureFrame<double>* f) {
    SplatParams<double> s;
    s.mean2d = {{in[0], in[1]}};
    s.conic = V3(in, 2);
    s.opacity = in[5];
    s.color = V3(in, 6);
    *f = Frame(in, 9);
    s.frame = f;
    s.texels = in.data() + 23;
    s.tex_h = h;
    s.tex_w = w;
    return s;
  };
  const Function f = [&](const Vector& in) {
    TextureFrame<double> fr;
    const auto smp = EvaluateSplat(params(in, &fr), px, py, ray);
    EXPECT_TRUE(smp.contributes && !smp.alpha_clamped && !smp.tc.u_clamped && !smp.tc.v_clamped);
    return Vector{smp.color[0], smp.color[1], smp.color[2], smp.alpha};
  };
  const Vjp vjp = [&](const Vector& in, const Vector& g) {
    TextureFrame<double> fr;
    const auto s = params(in, &fr);
    const auto smp = EvaluateSplat(s, px, py, ray);
    auto grad = ZeroSplatGrad<double>();
    Vector g_texels(nt, 0.0);
    EvaluateSplatVjp(s, ray, smp, V3(g, 0), g[3], &grad, g_texels.data());
    Vector out{grad.mean2d[0], grad.mean2d[1]};
    Put(&out, grad.conic);
    out.push_back(grad.opacity);
    Put(&out, grad.color);
    Put(&out, grad.frame);
    out.insert(out.end(), g_texels.begin(), g_texels.end());
    return out;
  };
  EXPECT_LT(VjpError(f, vjp, x, rng), 1e-7);
}

}  // namespace
}  // namespace atex::detail
