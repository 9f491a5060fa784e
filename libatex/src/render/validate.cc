// Input checks of the rasteriser: everything that could make it crash, allocate
// from a forged size or produce NaN is rejected here with the element named.
#include <cmath>
#include <limits>

#include "atex/render.h"
#include "render/render_internal.h"

namespace atex {
namespace render_internal {
namespace {

template <typename T>
Status CheckFinite(const std::vector<T>& values, int per_element, const char* what) {
  for (size_t k = 0; k < values.size(); ++k) {
    if (!std::isfinite(values[k])) {
      return MakeError(StatusCode::kOutOfRange, what, " of element ", k / per_element, " (component ",
                       k % per_element, ") is not finite: ", values[k]);
    }
  }
  return Status::Ok();
}

}  // namespace

Status ValidateCamera(const Camera& camera) {
  const std::string name = camera.name.empty() ? std::string("camera") : "camera '" + camera.name + "'";
  if (camera.width <= 0 || camera.height <= 0) {
    return MakeError(StatusCode::kInvalidArgument, name, ": image size ", camera.width, "x", camera.height,
                     " is empty");
  }
  if (camera.width > kMaxImageSide || camera.height > kMaxImageSide ||
      uint64_t(camera.width) * uint64_t(camera.height) > kMaxPixels) {
    return MakeError(StatusCode::kLimitExceeded, name, ": image size ", camera.width, "x", camera.height,
                     " exceeds the reference rasteriser's limit (", kMaxImageSide, " per side, ", kMaxPixels,
                     " pixels)");
  }
  if (!(std::isfinite(camera.fx) && std::isfinite(camera.fy) && camera.fx > 0 && camera.fy > 0)) {
    return MakeError(StatusCode::kInvalidArgument, name, ": focal lengths fx=", camera.fx, " fy=", camera.fy,
                     " must be finite and positive");
  }
  if (!(std::isfinite(camera.cx) && std::isfinite(camera.cy))) {
    return MakeError(StatusCode::kInvalidArgument, name, ": principal point (", camera.cx, ", ", camera.cy,
                     ") is not finite");
  }
  const auto& m = camera.world_to_camera;
  for (int k = 0; k < 16; ++k) {
    if (!std::isfinite(m[k])) {
      return MakeError(StatusCode::kInvalidArgument, name, ": world_to_camera[", k, "] is not finite");
    }
  }
  // Rigid: rotation rows orthonormal (loose tolerance for transforms stored in float), last row (0, 0, 0, 1).
  constexpr double kTolerance = 1e-3;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      const double dot = m[r * 4] * m[c * 4] + m[r * 4 + 1] * m[c * 4 + 1] + m[r * 4 + 2] * m[c * 4 + 2];
      if (std::abs(dot - (r == c ? 1.0 : 0.0)) > kTolerance) {
        return MakeError(StatusCode::kInvalidArgument, name,
                         ": world_to_camera is not a rigid transform (rows ", r, " and ", c,
                         " of the rotation have dot product ", dot, ")");
      }
    }
  }
  const double det = m[0] * (m[5] * m[10] - m[6] * m[9]) - m[1] * (m[4] * m[10] - m[6] * m[8]) +
                     m[2] * (m[4] * m[9] - m[5] * m[8]);
  if (det < 0 || m[12] != 0 || m[13] != 0 || m[14] != 0 || m[15] != 1) {
    return MakeError(StatusCode::kInvalidArgument, name,
                     ": world_to_camera is not a rigid transform (reflection or last row not 0 0 0 1)");
  }
  return Status::Ok();
}

Status ValidateSettings(const RenderSettings& settings) {
  if (!(std::isfinite(settings.near_plane) && settings.near_plane > 0)) {
    return MakeError(StatusCode::kInvalidArgument, "render settings: near_plane ", settings.near_plane,
                     " must be finite and positive");
  }
  for (int c = 0; c < 3; ++c) {
    if (!std::isfinite(settings.background[c])) {
      return MakeError(StatusCode::kInvalidArgument, "render settings: background[", c, "] is not finite");
    }
  }
  if (settings.active_sh_degree < 0 || settings.active_sh_degree > kMaxShDegree) {
    return MakeError(StatusCode::kInvalidArgument, "render settings: active_sh_degree ", settings.active_sh_degree,
                     " is outside 0..", kMaxShDegree);
  }
  return Status::Ok();
}

template <typename T>
Status ValidateGaussians(const BasicGaussians<T>& g) {
  if (g.sh_degree < 0 || g.sh_degree > kMaxShDegree) {
    return MakeError(StatusCode::kInvalidArgument, "gaussians: sh_degree ", g.sh_degree, " is outside 0..",
                     kMaxShDegree);
  }
  const size_t n = g.size();
  if (n > size_t(std::numeric_limits<int32_t>::max())) {
    return MakeError(StatusCode::kLimitExceeded, "gaussians: ", n, " Gaussians exceed the rasteriser's limit");
  }
  const size_t k = static_cast<size_t>(g.sh_coeffs());
  struct Expected {
    const char* name;
    size_t actual, expected;
  };
  const Expected sizes[] = {{"positions", g.positions.size(), n * 3},
                            {"rotations", g.rotations.size(), n * 4},
                            {"log_scales", g.log_scales.size(), n * 3},
                            {"sh", g.sh.size(), n * k * 3}};
  for (const auto& s : sizes) {
    if (s.actual != s.expected) {
      return MakeError(StatusCode::kInvalidArgument, "gaussians: ", s.name, " has ", s.actual, " values, expected ",
                       s.expected, " for ", n, " Gaussians");
    }
  }
  ATEX_RETURN_IF_ERROR(CheckFinite(g.positions, 3, "gaussians: position"));
  ATEX_RETURN_IF_ERROR(CheckFinite(g.rotations, 4, "gaussians: rotation"));
  ATEX_RETURN_IF_ERROR(CheckFinite(g.log_scales, 3, "gaussians: log_scale"));
  ATEX_RETURN_IF_ERROR(CheckFinite(g.opacity_logits, 1, "gaussians: opacity_logit"));
  ATEX_RETURN_IF_ERROR(CheckFinite(g.sh, static_cast<int>(k * 3), "gaussians: sh"));
  for (size_t i = 0; i < n; ++i) {
    const T* q = &g.rotations[4 * i];
    const T norm2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    if (!(norm2 > T(0)) || !std::isfinite(norm2)) {
      return MakeError(StatusCode::kOutOfRange, "gaussians: rotation of element ", i,
                       " has no usable length (|q|^2 = ", norm2, ")");
    }
  }
  return Status::Ok();
}

}  // namespace render_internal

template <typename T>
Status ValidateTexturePool(const BasicTexturePool<T>& pool, size_t gaussian_count) {
  const size_t n = gaussian_count;
  if (pool.heights.size() != n || pool.widths.size() != n || pool.axis_u.size() != n || pool.axis_v.size() != n) {
    return MakeError(StatusCode::kInvalidArgument, "texture pool: per-Gaussian arrays have sizes heights=",
                     pool.heights.size(), " widths=", pool.widths.size(), " axis_u=", pool.axis_u.size(),
                     " axis_v=", pool.axis_v.size(), ", expected ", n);
  }
  if (pool.offsets.size() != n + 1 || pool.offsets[0] != 0) {
    return MakeError(StatusCode::kInvalidArgument, "texture pool: offsets has ", pool.offsets.size(),
                     " entries (first ", pool.offsets.empty() ? 0 : pool.offsets[0], "), expected ", n + 1,
                     " starting at 0");
  }
  for (size_t i = 0; i < n; ++i) {
    const int h = pool.heights[i], w = pool.widths[i];
    if ((h != 1 && h != 2 && h != 4) || (w != 1 && w != 2 && w != 4)) {
      return MakeError(StatusCode::kOutOfRange, "texture pool: element ", i, " has size ", h, "x", w,
                       " (each side must be 1, 2 or 4)");
    }
    const int p = pool.axis_u[i], q = pool.axis_v[i];
    if (p > 2 || q > 2 || p == q) {
      return MakeError(StatusCode::kOutOfRange, "texture pool: element ", i, " has axes (", p, ", ", q,
                       "); they must be distinct and in 0..2");
    }
    if (pool.offsets[i + 1] != pool.offsets[i] + uint64_t(h) * uint64_t(w)) {
      return MakeError(StatusCode::kInvalidArgument, "texture pool: offsets[", i + 1, "] = ", pool.offsets[i + 1],
                       " does not match offsets[", i, "] + h*w = ", pool.offsets[i] + uint64_t(h) * w);
    }
  }
  if (pool.texels.size() != pool.offsets[n] * kTexelChannels) {
    return MakeError(StatusCode::kInvalidArgument, "texture pool: texels has ", pool.texels.size(),
                     " values, expected ", pool.offsets[n] * kTexelChannels);
  }
  for (size_t k = 0; k < pool.texels.size(); ++k) {
    if (!std::isfinite(pool.texels[k])) {
      return MakeError(StatusCode::kOutOfRange, "texture pool: texel ", k / kTexelChannels, " channel ",
                       k % kTexelChannels, " is not finite");
    }
  }
  return Status::Ok();
}

template Status render_internal::ValidateGaussians(const BasicGaussians<float>&);
template Status render_internal::ValidateGaussians(const BasicGaussians<double>&);
template Status ValidateTexturePool(const BasicTexturePool<float>&, size_t);
template Status ValidateTexturePool(const BasicTexturePool<double>&, size_t);

}  // namespace atex
