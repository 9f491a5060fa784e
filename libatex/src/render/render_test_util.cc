#include "render/render_test_util.h"

#include <algorithm>
#include <cmath>

#include "atex/detail/composite.h"
#include "atex/detail/projection.h"
#include "atex/detail/quaternion.h"
#include "atex/detail/sh.h"
#include "render/render_internal.h"

namespace atex::render_testing {
namespace {

using detail::Mat3;
using detail::Vec3;

double Uniform(std::mt19937& rng, double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); }

// Rodrigues: rotation by `angle` about the unit vector `axis`, row-major.
std::array<double, 9> AxisAngle(const std::array<double, 3>& axis, double angle) {
  const double c = std::cos(angle), s = std::sin(angle), t = 1 - c;
  const double x = axis[0], y = axis[1], z = axis[2];
  return {t * x * x + c,     t * x * y - s * z, t * x * z + s * y, t * x * y + s * z, t * y * y + c,
          t * y * z - s * x, t * x * z - s * y, t * y * z + s * x, t * z * z + c};
}

}  // namespace

Camera RandomCamera(int width, int height, std::mt19937& rng) {
  Camera camera;
  camera.width = width;
  camera.height = height;
  camera.fx = 0.92 * width;
  camera.fy = 0.88 * width;
  camera.cx = 0.5 * width + 0.3;
  camera.cy = 0.5 * height - 0.3;
  std::array<double, 3> axis{Uniform(rng, -1, 1), Uniform(rng, -1, 1), Uniform(rng, -1, 1)};
  const double len = std::sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
  for (double& a : axis) a /= len;
  const auto r = AxisAngle(axis, Uniform(rng, 0.0, 0.4));
  const std::array<double, 3> center{Uniform(rng, -0.5, 0.5), Uniform(rng, -0.5, 0.5), Uniform(rng, -0.5, 0.5)};
  auto& m = camera.world_to_camera;
  for (int row = 0; row < 3; ++row) {
    for (int col = 0; col < 3; ++col) m[row * 4 + col] = r[row * 3 + col];
    m[row * 4 + 3] = -(r[row * 3] * center[0] + r[row * 3 + 1] * center[1] + r[row * 3 + 2] * center[2]);
  }
  m[12] = m[13] = m[14] = 0;
  m[15] = 1;
  camera.name = "random test camera";
  return camera;
}

template <typename T>
BasicGaussians<T> RandomGaussians(const Camera& camera, const SceneOptions& options, std::mt19937& rng) {
  BasicGaussians<T> g;
  g.sh_degree = options.sh_degree;
  const int n = options.count + (options.extras ? 3 : 0);
  g.Resize(n);
  const auto& m = camera.world_to_camera;
  const auto center = camera.Center();
  // Camera-space point → world: Wᵀ t + centre.
  const auto to_world = [&](const std::array<double, 3>& t, T* out) {
    for (int k = 0; k < 3; ++k) out[k] = T(m[k] * t[0] + m[4 + k] * t[1] + m[8 + k] * t[2] + center[k]);
  };
  const int coeffs = g.sh_coeffs();
  for (int i = 0; i < n; ++i) {
    std::array<double, 3> t;
    double scale_lo = std::log(0.08), scale_hi = std::log(0.5);
    double logit_lo = options.opaque ? -1.0 : -1.5, logit_hi = options.opaque ? 6.0 : 1.5;
    if (i < options.count) {
      const double z = Uniform(rng, 2.0, 5.0);
      t = {Uniform(rng, -0.6, 0.6) * z, Uniform(rng, -0.55, 0.55) * z, z};
    } else if (i < options.count + 2) {
      // Beyond gsplat's Jacobian clamp (x/z > lim), large enough to reach into the image.
      const double z = 3.0;
      t = {(i == options.count ? 0.9 : -0.95) * z, Uniform(rng, -0.2, 0.2) * z, z};
      scale_lo = std::log(0.4);
      scale_hi = std::log(0.55);
      logit_lo = 0.0;
      logit_hi = 1.0;
    } else {
      t = {0.1, -0.2, -1.0};  // behind the camera
    }
    to_world(t, &g.positions[3 * i]);
    for (int k = 0; k < 3; ++k) g.log_scales[3 * i + k] = T(Uniform(rng, scale_lo, scale_hi));
    std::normal_distribution<double> normal(0.0, 1.0);
    double q[4], norm = 0;
    for (double& v : q) {
      v = normal(rng);
      norm += v * v;
    }
    const double length = Uniform(rng, 0.5, 2.0) / std::sqrt(norm);
    for (int k = 0; k < 4; ++k) g.rotations[4 * i + k] = T(q[k] * length);
    g.opacity_logits[i] = T(Uniform(rng, logit_lo, logit_hi));
    for (int k = 0; k < coeffs; ++k) {
      for (int ch = 0; ch < 3; ++ch) {
        g.sh[(size_t(i) * coeffs + k) * 3 + ch] = T(k == 0 ? Uniform(rng, -1.0, 1.2) : Uniform(rng, -0.4, 0.4));
      }
    }
  }
  return g;
}

template <typename T>
BasicTexturePool<T> RandomTextures(const BasicGaussians<T>& g, TextureKind kind, double texel_range,
                                   std::mt19937& rng) {
  static constexpr uint8_t kSizes[][2] = {{1, 1}, {1, 4}, {4, 1}, {2, 4}, {4, 2}, {1, 2}, {2, 1}, {2, 2}, {4, 4}};
  static constexpr uint8_t kAxes[][2] = {{0, 1}, {1, 0}, {0, 2}, {2, 0}, {1, 2}, {2, 1}};
  const size_t n = g.size();
  BasicTexturePool<T> pool;
  pool.heights.resize(n);
  pool.widths.resize(n);
  pool.axis_u.resize(n);
  pool.axis_v.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const bool uniform = kind == TextureKind::kUniform;
    pool.heights[i] = uniform ? 4 : kSizes[i % 9][0];
    pool.widths[i] = uniform ? 4 : kSizes[i % 9][1];
    pool.axis_u[i] = kAxes[i % 6][0];
    pool.axis_v[i] = kAxes[i % 6][1];
  }
  pool.RebuildOffsets();
  pool.texels.resize(pool.texel_count() * kTexelChannels);
  for (T& v : pool.texels) v = T(Uniform(rng, -texel_range, texel_range));
  return pool;
}

template <typename T>
std::vector<int64_t> PixelSignature(const Camera& camera, const BasicTexturePool<T>* textures,
                                    const BasicRenderOutput<T>& fwd) {
  const auto cam = detail::MakeCameraModel<T>(camera, 0.01);  // near plane unused per pixel
  const auto& st = fwd.state;
  std::vector<int64_t> sig;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const int t = (y / detail::kTileSize) * st.tiles_x + x / detail::kTileSize;
      const T px = T(x) + T(0.5), py = T(y) + T(0.5);
      const Vec3<T> ray = detail::PixelRayDirection(cam, px, py);
      T transmittance = T(1);
      for (uint64_t e = st.tile_ranges[t]; e < st.tile_ranges[t + 1]; ++e) {
        const auto s = render_internal::MakeSplatParams(fwd, textures, st.tile_gaussians[e]);
        const auto smp = detail::EvaluateSplat(s, px, py, ray);
        sig.push_back(smp.contributes);
        if (!smp.contributes) continue;
        sig.push_back(smp.alpha_clamped);
        if (textures != nullptr) {
          const auto tc = detail::ComputeTexCoord(*s.frame, ray);
          const auto taps = detail::MakeBilinearTaps(tc, s.tex_h, s.tex_w);
          bool replaced;
          detail::SafePlaneDenominator(detail::Dot(s.frame->normal, ray), &replaced);
          sig.insert(sig.end(), {tc.u_clamped, tc.v_clamped, taps.x.i0, taps.y.i0, replaced});
        }
        const T next = transmittance * (T(1) - smp.alpha);
        if (next < T(detail::kMinTransmittance)) {
          sig.push_back(-1);  // stopped here
          break;
        }
        transmittance = next;
      }
    }
  }
  return sig;
}

template <typename T>
std::vector<int64_t> RenderSignature(const Camera& camera, const BasicGaussians<T>& g,
                                     const BasicTexturePool<T>* textures, const RenderSettings& settings,
                                     const BasicRenderOutput<T>& fwd) {
  const auto cam = detail::MakeCameraModel<T>(camera, settings.near_plane);
  const auto& st = fwd.state;
  std::vector<int64_t> sig(fwd.radius.begin(), fwd.radius.end());
  sig.insert(sig.end(), st.tile_ranges.begin(), st.tile_ranges.end());
  sig.insert(sig.end(), st.tile_gaussians.begin(), st.tile_gaussians.end());
  sig.insert(sig.end(), st.contributor_end.begin(), st.contributor_end.end());
  const size_t coeffs = size_t(g.sh_coeffs());
  for (size_t i = 0; i < g.size(); ++i) {
    if (fwd.radius[i] <= 0) continue;
    const Vec3<T> mean = render_internal::Load3(g.positions, i);
    const auto jac = detail::ProjectionJacobian(cam, detail::WorldToCamera(cam, mean));
    bool clamped[3];
    detail::ShColor(st.sh_degree, &g.sh[i * coeffs * 3], mean - cam.center, clamped);
    sig.insert(sig.end(), {jac.clamped_x, jac.clamped_y, clamped[0], clamped[1], clamped[2]});
  }
  const auto pixels = PixelSignature(camera, textures, fwd);
  sig.insert(sig.end(), pixels.begin(), pixels.end());
  return sig;
}

template <typename T>
void NaiveRender(const Camera& camera, const BasicGaussians<T>& g, const BasicTexturePool<T>* textures,
                 const RenderSettings& settings, std::vector<T>* color, std::vector<T>* alpha) {
  const auto cam = detail::MakeCameraModel<T>(camera, settings.near_plane);
  const int sh_degree = std::min(settings.active_sh_degree, g.sh_degree);
  const size_t n = g.size(), coeffs = size_t(g.sh_coeffs());
  std::vector<detail::ProjectedGaussian<T>> projected(n);
  std::vector<detail::TextureFrame<T>> frames(n);
  std::vector<detail::SplatParams<T>> splats(n);
  for (size_t i = 0; i < n; ++i) {
    const Vec3<T> mean = render_internal::Load3(g.positions, i);
    const Vec3<T> log_scale = render_internal::Load3(g.log_scales, i);
    const Mat3<T> rotation = detail::QuaternionToRotation(render_internal::Load4(g.rotations, i));
    projected[i] = detail::ProjectGaussian(cam, mean, rotation, log_scale);
    auto& s = splats[i];
    s.mean2d = projected[i].mean2d;
    s.conic = projected[i].conic;
    s.opacity = detail::Sigmoid(g.opacity_logits[i]);
    bool clamped[3];
    s.color = detail::ShColor(sh_degree, &g.sh[i * coeffs * 3], mean - cam.center, clamped);
    s.frame = nullptr;
    if (textures != nullptr) {
      frames[i] = detail::MakeTextureFrame(rotation, mean, log_scale, cam.center, textures->axis_u[i],
                                           textures->axis_v[i]);
      s.frame = &frames[i];
      s.texels = textures->texels.data() + textures->offsets[i] * 4;
      s.tex_h = textures->heights[i];
      s.tex_w = textures->widths[i];
    }
  }
  color->assign(size_t(camera.width) * camera.height * 3, T(0));
  alpha->assign(size_t(camera.width) * camera.height, T(0));
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      std::vector<size_t> list;
      for (size_t i = 0; i < n; ++i) {
        if (projected[i].visible && projected[i].rect.contains(x / detail::kTileSize, y / detail::kTileSize)) {
          list.push_back(i);
        }
      }
      std::sort(list.begin(), list.end(), [&](size_t a, size_t b) {
        return projected[a].depth < projected[b].depth || (projected[a].depth == projected[b].depth && a < b);
      });
      const T px = T(x) + T(0.5), py = T(y) + T(0.5);
      const Vec3<T> ray = detail::PixelRayDirection(cam, px, py);
      T transmittance = T(1);
      T c[3] = {T(0), T(0), T(0)};
      for (size_t i : list) {
        const auto smp = detail::EvaluateSplat(splats[i], px, py, ray);
        if (!smp.contributes) continue;
        const T next = transmittance * (T(1) - smp.alpha);
        if (next < T(detail::kMinTransmittance)) break;
        for (int ch = 0; ch < 3; ++ch) c[ch] += smp.color[ch] * smp.alpha * transmittance;
        transmittance = next;
      }
      const size_t p = size_t(y) * camera.width + x;
      for (int ch = 0; ch < 3; ++ch) (*color)[3 * p + ch] = c[ch] + transmittance * T(settings.background[ch]);
      (*alpha)[p] = T(1) - transmittance;
    }
  }
}

#define ATEX_INSTANTIATE(T)                                                                                        \
  template BasicGaussians<T> RandomGaussians<T>(const Camera&, const SceneOptions&, std::mt19937&);              \
  template BasicTexturePool<T> RandomTextures(const BasicGaussians<T>&, TextureKind, double, std::mt19937&);     \
  template std::vector<int64_t> RenderSignature(const Camera&, const BasicGaussians<T>&, const BasicTexturePool<T>*, \
                                                const RenderSettings&, const BasicRenderOutput<T>&);            \
  template std::vector<int64_t> PixelSignature(const Camera&, const BasicTexturePool<T>*,                        \
                                               const BasicRenderOutput<T>&);                                     \
  template void NaiveRender(const Camera&, const BasicGaussians<T>&, const BasicTexturePool<T>*,                 \
                            const RenderSettings&, std::vector<T>*, std::vector<T>*);
ATEX_INSTANTIATE(float)
ATEX_INSTANTIATE(double)
#undef ATEX_INSTANTIATE

}  // namespace atex::render_testing
