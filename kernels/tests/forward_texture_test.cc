// The forward rasteriser's rearranged texture sample (render/forward_texture.h) against the
// reference functions of atex/detail/texture.h, on the CPU: the camera-frame plane rows give
// the coordinates of ComputeTexCoord with the world ray, and the branch-free taps give
// SampleTexels' value at MakeBilinearTaps' taps, never reading outside the texture. Needs no GPU, so it runs in CI; the
// whole kernel is checked against the CPU engine by render_parity_test on a GPU.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "atex/detail/projection.h"
#include "atex/detail/quaternion.h"
#include "atex/detail/texture.h"
#include "render/forward_texture.h"

namespace atex::cuda::render {
namespace {

using detail::Mat3;
using detail::Vec3;
using detail::Vec4;

template <typename T>
Mat3<T> RandomRotation(std::mt19937& rng) {
  std::normal_distribution<double> normal;
  return detail::QuaternionToRotation(Vec4<T>{{T(normal(rng)), T(normal(rng)), T(normal(rng)), T(normal(rng))}});
}

// One random view of one random textured Gaussian in front of the camera, in float and in double.
struct ViewOfSplat {
  detail::CameraModel<float> cam;
  detail::TextureFrame<float> frame;
  detail::TextureFrame<double> exact;  // the same frame in double
  Mat3<double> cam_rotation;
  double fx, fy, cx, cy;
  double mean_px, mean_py, extent_px;  // the projected centre and the smaller in-plane scale, in pixels
};

ViewOfSplat RandomViewOfSplat(std::mt19937& rng) {
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  ViewOfSplat s;
  const Mat3<double> w = RandomRotation<double>(rng);
  const Vec3<double> center{{uniform(rng), uniform(rng), uniform(rng)}};
  s.cam_rotation = w;
  s.fx = 500 + 100 * uniform(rng);
  s.fy = 500 + 100 * uniform(rng);
  s.cx = 320 + 20 * uniform(rng);
  s.cy = 180 + 20 * uniform(rng);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) s.cam.rotation(r, c) = float(w(r, c));
    s.cam.center[r] = float(center[r]);
  }
  s.cam.fx = float(s.fx);
  s.cam.fy = float(s.fy);
  s.cam.cx = float(s.cx);
  s.cam.cy = float(s.cy);
  // A Gaussian 2-6 units in front of the camera (camera z along W's third row).
  const Vec3<double> forward{{w(2, 0), w(2, 1), w(2, 2)}};
  const Vec3<double> mean = center + (4.0 + 2.0 * uniform(rng)) * forward +
                            Vec3<double>{{0.5 * uniform(rng), 0.5 * uniform(rng), 0.5 * uniform(rng)}};
  const Mat3<double> rotation = RandomRotation<double>(rng);
  const Vec3<double> log_scale{{-2.0 + uniform(rng), -2.0 + uniform(rng), -4.0 + uniform(rng)}};
  const int axis_u = 0, axis_v = 1;
  s.exact = detail::MakeTextureFrame(rotation, mean, log_scale, center, axis_u, axis_v);
  Mat3<float> rotation_f;
  Vec3<float> mean_f, log_scale_f, center_f;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) rotation_f(r, c) = float(rotation(r, c));
    mean_f[r] = float(mean[r]);
    log_scale_f[r] = float(log_scale[r]);
    center_f[r] = float(center[r]);
  }
  s.frame = detail::MakeTextureFrame(rotation_f, mean_f, log_scale_f, center_f, axis_u, axis_v);
  const Vec3<double> t = w * (mean - center);
  s.mean_px = s.fx * t[0] / t[2] + s.cx;
  s.mean_py = s.fy * t[1] / t[2] + s.cy;
  s.extent_px = std::exp(std::min(log_scale[0], log_scale[1])) * s.fx / t[2];
  return s;
}

TEST(ForwardTexture, CameraFramePlaneGivesTheReferenceCoordinates) {
  std::mt19937 rng(6666);
  std::uniform_real_distribution<double> offset(-1.0, 1.0);
  constexpr double kEpsilon = 1.0 / (1 << 24);  // float's unit roundoff
  double worst_ratio = 0;
  int unclamped = 0;
  for (int scene = 0; scene < 200; ++scene) {
    const ViewOfSplat s = RandomViewOfSplat(rng);
    const ForwardPlane plane = MakeForwardPlane(s.cam.rotation, s.frame);
    for (int k = 0; k < 200; ++k) {
      const float px = float(s.mean_px + s.extent_px * offset(rng)), py = float(s.mean_py + s.extent_px * offset(rng));
      // Reference in float (the CPU engine's form) and the exact value in double.
      const detail::TexCoord<float> ref = detail::ComputeTexCoord(s.frame, detail::PixelRayDirection(s.cam, px, py));
      const Vec3<double> c{{(px - s.cx) / s.fx, (py - s.cy) / s.fy, 1.0}};
      const detail::TexCoord<double> exact =
          detail::ComputeTexCoord(s.exact, detail::TransposeTimes(s.cam_rotation, c));
      if (exact.u_clamped && exact.v_clamped) continue;  // both clamped to a corner: nothing to compare
      float u, v;
      ForwardTexCoord(plane, (px - s.cam.cx) / s.cam.fx, (py - s.cam.cy) / s.cam.fy, &u, &v);
      ASSERT_TRUE(u >= -1.0f && u <= 1.0f && v >= -1.0f && v <= 1.0f) << u << " " << v;
      if (!exact.u_clamped && !exact.v_clamped) ++unclamped;
      // u = λ (a_u·d)/s_u − o_u/s_u subtracts two terms of about |o_u|/s_u, so float rounding
      // gives either form an error of a few ulps of that size: allow 32 of them (or twice the
      // float reference's own error). A wrong row or sign errs by O(1).
      const Vec3<double> d = detail::TransposeTimes(s.cam_rotation, c);
      const double lambda = s.exact.offset_n / detail::Dot(s.exact.normal, d);
      const double scale_u = std::abs(lambda * detail::Dot(s.exact.axis_u, d) * s.exact.inv_scale_u) +
                             std::abs(s.exact.offset_u * s.exact.inv_scale_u) + 1;
      const double scale_v = std::abs(lambda * detail::Dot(s.exact.axis_v, d) * s.exact.inv_scale_v) +
                             std::abs(s.exact.offset_v * s.exact.inv_scale_v) + 1;
      for (auto [ours, theirs, truth, scale] :
           {std::tuple{u, ref.u, exact.u, scale_u}, std::tuple{v, ref.v, exact.v, scale_v}}) {
        const double e_ours = std::abs(ours - truth), e_ref = std::abs(theirs - truth);
        const double allowed = std::max(32 * kEpsilon * scale, 2 * e_ref);
        worst_ratio = std::max(worst_ratio, e_ours / allowed);
        EXPECT_LE(e_ours, allowed) << "scene " << scene << " pixel " << px << "," << py;
      }
    }
  }
  EXPECT_GT(unclamped, 10000) << "too few samples inside the texture to test anything";
  std::printf(
      "[forward texture] coordinates: worst error %.2f of the allowed; %d of 40000 samples inside the texture\n",
      worst_ratio, unclamped);
}

TEST(ForwardTexture, BranchFreeTapsSampleLikeTheReference) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> coordinate(-1.2f, 1.2f), value(-3.0f, 3.0f);
  const float special[] = {-1.0f, 1.0f, 0.0f, -0.5f, 0.5f, std::nextafter(1.0f, 0.0f),
                           std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()};
  for (int h : {1, 2, 4}) {
    for (int w : {1, 2, 4}) {
      // A pool with texels before and after this texture's, as in the packed pool. They are
      // NaN: a tap outside the texture poisons the sample even with a zero weight.
      const uint32_t first = 3;
      std::vector<float> pool(4 * (first + h * w + 16), std::numeric_limits<float>::quiet_NaN());
      for (int i = 0; i < 4 * h * w; ++i) pool[4 * first + i] = value(rng);
      const ForwardGrid grid = MakeForwardGrid(h, w, first);
      auto check = [&](float u_in, float v_in) {
        const float u = ClampToUnit(u_in), v = ClampToUnit(v_in);
        ASSERT_EQ(u, detail::ClampNanLow(u_in, -1.0f, 1.0f)) << u_in;
        ASSERT_EQ(v, detail::ClampNanLow(v_in, -1.0f, 1.0f)) << v_in;
        const detail::TexCoord<float> tc{u, v, false, false};
        const Vec4<float> want =
            detail::SampleTexels(pool.data() + 4 * first, w, detail::MakeBilinearTaps(tc, h, w));
        const Vec4<float> got = ForwardSample(pool.data(), grid, u, v);
        for (int ch = 0; ch < 4; ++ch) {
          EXPECT_NEAR(got[ch], want[ch], 2e-6f) << h << "x" << w << " at (" << u_in << ", " << v_in << ") ch " << ch;
        }
      };
      for (float a : special) {
        for (float b : special) check(a, b);
      }
      for (int k = 0; k < 2000; ++k) check(coordinate(rng), coordinate(rng));
    }
  }
}

}  // namespace
}  // namespace atex::cuda::render
