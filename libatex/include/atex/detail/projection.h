// Per-Gaussian EWA projection (docs/conventions.md §1, §2, §4) and the
// vector-Jacobian product of every step: world → camera, pinhole projection of
// the centre, gsplat's clamped Jacobian, Σ = R diag(s²) Rᵀ, the projected 2-D
// covariance with the 0.3 px² low-pass blur, the conic, the 3σ radius and the
// 16×16 tile rectangle.
//
// Symmetric 2×2 matrices (2-D covariance, conic) are Vec3 (xx, xy, yy); their
// gradients are with respect to those three numbers (the off-diagonal counted
// once), which is how a rasteriser that uses B once in
// power = −½(A Δx² + C Δy²) − B Δx Δy wants them.
#pragma once

#include "atex/camera.h"
#include "atex/detail/math.h"
#include "atex/detail/vec.h"
#include "atex/hd.h"

namespace atex::detail {

inline constexpr int kTileSize = 16;          // pixels per tile side (conventions §4.5)
inline constexpr double kCov2dBlur = 0.3;     // low-pass added to the 2-D covariance (§4.3)
inline constexpr double kMinRadiusDiscriminant = 0.1;  // max(0.1, mid² − det) in λ_max (§4.4)
inline constexpr double kSigmaExtent = 3.0;   // radius = ceil(3 sqrt(λ_max))
inline constexpr double kFovClampMargin = 0.3;  // lim = edge/f + 0.3 tan (§4.2)
inline constexpr int kMaxRadiusPixels = 1 << 30;  // reported radius saturates here (no int overflow)

// Camera quantities in the engine's precision.
template <typename T>
struct CameraModel {
  Mat3<T> rotation;     // W: world → camera rotation
  Vec3<T> translation;  // T: world → camera translation
  Vec3<T> center;       // o = −Wᵀ T, camera centre in world coordinates
  T fx, fy, cx, cy;     // pixels
  T lim_x_pos, lim_x_neg, lim_y_pos, lim_y_neg;  // gsplat's asymmetric clamp of x/z and y/z (§4.2)
  T near_plane;
  int width, height;    // pixels
  int tiles_x, tiles_y; // ceil(width / 16), ceil(height / 16)
};

// Host-only: converts a Camera (double) to the engine's precision. The clamp limits
// and the centre are computed in double and rounded once, so that every engine that
// calls this gets the same numbers.
template <typename T>
inline CameraModel<T> MakeCameraModel(const Camera& camera, double near_plane) {
  CameraModel<T> cam;
  const auto& m = camera.world_to_camera;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) cam.rotation(r, c) = static_cast<T>(m[r * 4 + c]);
    cam.translation[r] = static_cast<T>(m[r * 4 + 3]);
  }
  const auto center = camera.Center();
  for (int k = 0; k < 3; ++k) cam.center[k] = static_cast<T>(center[k]);
  cam.fx = static_cast<T>(camera.fx);
  cam.fy = static_cast<T>(camera.fy);
  cam.cx = static_cast<T>(camera.cx);
  cam.cy = static_cast<T>(camera.cy);
  const double tan_x = 0.5 * camera.width / camera.fx;
  const double tan_y = 0.5 * camera.height / camera.fy;
  cam.lim_x_pos = static_cast<T>((camera.width - camera.cx) / camera.fx + kFovClampMargin * tan_x);
  cam.lim_x_neg = static_cast<T>(camera.cx / camera.fx + kFovClampMargin * tan_x);
  cam.lim_y_pos = static_cast<T>((camera.height - camera.cy) / camera.fy + kFovClampMargin * tan_y);
  cam.lim_y_neg = static_cast<T>(camera.cy / camera.fy + kFovClampMargin * tan_y);
  cam.near_plane = static_cast<T>(near_plane);
  cam.width = camera.width;
  cam.height = camera.height;
  cam.tiles_x = (camera.width + kTileSize - 1) / kTileSize;
  cam.tiles_y = (camera.height + kTileSize - 1) / kTileSize;
  return cam;
}

// Direction of the ray through image point (px, py) (a pixel centre is (i + 0.5, j + 0.5)):
// d = Wᵀ ((px − cx)/fx, (py − cy)/fy, 1), unnormalised (§1).
template <typename T>
ATEX_HD Vec3<T> PixelRayDirection(const CameraModel<T>& cam, T px, T py) {
  const Vec3<T> c{{(px - cam.cx) / cam.fx, (py - cam.cy) / cam.fy, T(1)}};
  return TransposeTimes(cam.rotation, c);
}

// ---- world → camera ----------------------------------------------------------
template <typename T>
ATEX_HD Vec3<T> WorldToCamera(const CameraModel<T>& cam, const Vec3<T>& mean) {
  return cam.rotation * mean + cam.translation;
}
// g_mean = Wᵀ g_t.
template <typename T>
ATEX_HD Vec3<T> WorldToCameraVjp(const CameraModel<T>& cam, const Vec3<T>& g_t) {
  return TransposeTimes(cam.rotation, g_t);
}

// ---- projected centre m = (fx x/z + cx, fy y/z + cy) --------------------------
template <typename T>
ATEX_HD Vec2<T> ProjectPoint(const CameraModel<T>& cam, const Vec3<T>& t) {
  const T rz = T(1) / t[2];
  return {{cam.fx * t[0] * rz + cam.cx, cam.fy * t[1] * rz + cam.cy}};
}
template <typename T>
ATEX_HD Vec3<T> ProjectPointVjp(const CameraModel<T>& cam, const Vec3<T>& t, const Vec2<T>& g_m) {
  const T rz = T(1) / t[2];
  return {{cam.fx * rz * g_m[0], cam.fy * rz * g_m[1], -(cam.fx * t[0] * g_m[0] + cam.fy * t[1] * g_m[1]) * rz * rz}};
}

// ---- Jacobian with gsplat's clamp (§4.2) -------------------------------------
template <typename T>
struct EwaJacobian {
  Mat23<T> j;        // [[fx/z, 0, −fx x'/z²], [0, fy/z, −fy y'/z²]]
  T tx, ty;          // x' = z clamp(x/z, −lim⁻, lim⁺), y' likewise
  bool clamped_x;    // x/z was outside [−lim_x⁻, lim_x⁺]
  bool clamped_y;
};

template <typename T>
ATEX_HD EwaJacobian<T> ProjectionJacobian(const CameraModel<T>& cam, const Vec3<T>& t) {
  EwaJacobian<T> out;
  const T rz = T(1) / t[2];
  const T ratio_x = t[0] * rz, ratio_y = t[1] * rz;
  out.clamped_x = !(ratio_x <= cam.lim_x_pos && ratio_x >= -cam.lim_x_neg);
  out.clamped_y = !(ratio_y <= cam.lim_y_pos && ratio_y >= -cam.lim_y_neg);
  out.tx = t[2] * Min(cam.lim_x_pos, Max(-cam.lim_x_neg, ratio_x));
  out.ty = t[2] * Min(cam.lim_y_pos, Max(-cam.lim_y_neg, ratio_y));
  out.j(0, 0) = cam.fx * rz;
  out.j(0, 1) = T(0);
  out.j(0, 2) = -cam.fx * out.tx * rz * rz;
  out.j(1, 0) = T(0);
  out.j(1, 1) = cam.fy * rz;
  out.j(1, 2) = -cam.fy * out.ty * rz * rz;
  return out;
}

// dL/dt from dL/dJ. Where the ratio is clamped, x' = z·c with c constant: the ratio
// passes no gradient but x' still scales with z (the exact derivative of §4.2).
template <typename T>
ATEX_HD Vec3<T> ProjectionJacobianVjp(const CameraModel<T>& cam, const Vec3<T>& t, const EwaJacobian<T>& jac,
                                      const Mat23<T>& g_j) {
  const T rz = T(1) / t[2];
  const T rz2 = rz * rz, rz3 = rz2 * rz;
  Vec3<T> g_t{{T(0), T(0), -cam.fx * rz2 * g_j(0, 0) - cam.fy * rz2 * g_j(1, 1)}};
  if (!jac.clamped_x) {
    g_t[0] += -cam.fx * rz2 * g_j(0, 2);
    g_t[2] += T(2) * cam.fx * jac.tx * rz3 * g_j(0, 2);
  } else {
    g_t[2] += cam.fx * jac.tx * rz3 * g_j(0, 2);
  }
  if (!jac.clamped_y) {
    g_t[1] += -cam.fy * rz2 * g_j(1, 2);
    g_t[2] += T(2) * cam.fy * jac.ty * rz3 * g_j(1, 2);
  } else {
    g_t[2] += cam.fy * jac.ty * rz3 * g_j(1, 2);
  }
  return g_t;
}

// ---- 3-D covariance Σ = M Mᵀ, M = R diag(exp(log_scale)) (§2) -----------------
template <typename T>
ATEX_HD Mat3<T> CovarianceFromRotationScale(const Mat3<T>& r, const Vec3<T>& log_scale) {
  const T s[3] = {Exp(log_scale[0]), Exp(log_scale[1]), Exp(log_scale[2])};
  Mat3<T> m;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) m(i, j) = r(i, j) * s[j];
  return m * Transpose(m);
}

// Accumulates dL/dR and dL/dlog_scale from dL/dΣ (all nine entries): dL/dM = (G + Gᵀ) M.
template <typename T>
ATEX_HD void CovarianceFromRotationScaleVjp(const Mat3<T>& r, const Vec3<T>& log_scale, const Mat3<T>& g_cov,
                                            Mat3<T>* g_r, Vec3<T>* g_log_scale) {
  const T s[3] = {Exp(log_scale[0]), Exp(log_scale[1]), Exp(log_scale[2])};
  Mat3<T> m, g_sym;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      m(i, j) = r(i, j) * s[j];
      g_sym(i, j) = g_cov(i, j) + g_cov(j, i);
    }
  const Mat3<T> g_m = g_sym * m;
  for (int j = 0; j < 3; ++j) {
    T g_s = T(0);
    for (int i = 0; i < 3; ++i) {
      (*g_r)(i, j) += g_m(i, j) * s[j];
      g_s += g_m(i, j) * r(i, j);
    }
    (*g_log_scale)[j] += g_s * s[j];
  }
}

// ---- 2-D covariance Σ₂ = J W Σ Wᵀ Jᵀ + 0.3 I (§4.3), as (xx, xy, yy) ---------
template <typename T>
ATEX_HD Vec3<T> ProjectCovariance(const CameraModel<T>& cam, const EwaJacobian<T>& jac, const Mat3<T>& cov) {
  const Mat3<T> cov_cam = cam.rotation * cov * Transpose(cam.rotation);
  T jc[2][3];  // J Σ_cam
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c)
      jc[r][c] = jac.j(r, 0) * cov_cam(0, c) + jac.j(r, 1) * cov_cam(1, c) + jac.j(r, 2) * cov_cam(2, c);
  T out[2][2];
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 2; ++c) out[r][c] = jc[r][0] * jac.j(c, 0) + jc[r][1] * jac.j(c, 1) + jc[r][2] * jac.j(c, 2);
  return {{out[0][0] + T(kCov2dBlur), out[0][1], out[1][1] + T(kCov2dBlur)}};
}

// From dL/d(xx, xy, yy) gives dL/dJ (returned) and accumulates dL/dΣ (world).
template <typename T>
ATEX_HD Mat23<T> ProjectCovarianceVjp(const CameraModel<T>& cam, const EwaJacobian<T>& jac, const Mat3<T>& cov,
                                      const Vec3<T>& g_cov2d, Mat3<T>* g_cov) {
  const Mat3<T> cov_cam = cam.rotation * cov * Transpose(cam.rotation);
  // Full symmetric gradient of the 2×2 matrix (the off-diagonal value appears twice).
  const T g2[2][2] = {{g_cov2d[0], T(0.5) * g_cov2d[1]}, {T(0.5) * g_cov2d[1], g_cov2d[2]}};
  T gj[2][3];  // G J
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c) gj[r][c] = g2[r][0] * jac.j(0, c) + g2[r][1] * jac.j(1, c);
  // dL/dΣ_cam = Jᵀ G J
  Mat3<T> g_cov_cam;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) g_cov_cam(r, c) = jac.j(0, r) * gj[0][c] + jac.j(1, r) * gj[1][c];
  *g_cov += Transpose(cam.rotation) * g_cov_cam * cam.rotation;
  // dL/dJ = (G + Gᵀ) J Σ_cam = 2 G J Σ_cam
  Mat23<T> g_j;
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c)
      g_j(r, c) = T(2) * (gj[r][0] * cov_cam(0, c) + gj[r][1] * cov_cam(1, c) + gj[r][2] * cov_cam(2, c));
  return g_j;
}

// ---- conic = Σ₂⁻¹ as (A, B, C) ------------------------------------------------
// False (conic untouched) when det Σ₂ ≤ 0 or is not a number: not visible (§4.3).
template <typename T>
ATEX_HD bool InvertCovariance2d(const Vec3<T>& cov2d, Vec3<T>* conic) {
  const T det = cov2d[0] * cov2d[2] - cov2d[1] * cov2d[1];
  if (!(det > T(0))) return false;
  const T inv_det = T(1) / det;
  *conic = {{cov2d[2] * inv_det, -cov2d[1] * inv_det, cov2d[0] * inv_det}};
  return true;
}

// dL/dΣ₂ = −K G K with K the conic matrix and G its full symmetric gradient;
// returned as dL/d(xx, xy, yy).
template <typename T>
ATEX_HD Vec3<T> InvertCovariance2dVjp(const Vec3<T>& conic, const Vec3<T>& g_conic) {
  const T k[2][2] = {{conic[0], conic[1]}, {conic[1], conic[2]}};
  const T g[2][2] = {{g_conic[0], T(0.5) * g_conic[1]}, {T(0.5) * g_conic[1], g_conic[2]}};
  T kg[2][2], out[2][2];
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 2; ++c) kg[r][c] = k[r][0] * g[0][c] + k[r][1] * g[1][c];
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 2; ++c) out[r][c] = -(kg[r][0] * k[0][c] + kg[r][1] * k[1][c]);
  return {{out[0][0], out[0][1] + out[1][0], out[1][1]}};
}

// ---- radius and tiles (§4.4, §4.5) ---------------------------------------------
// 3 sqrt(λ_max) with λ_max = mid + sqrt(max(0.1, mid² − det)); the radius is its ceiling.
template <typename T>
ATEX_HD T ProjectedExtent(const Vec3<T>& cov2d) {
  const T mid = T(0.5) * (cov2d[0] + cov2d[2]);
  const T det = cov2d[0] * cov2d[2] - cov2d[1] * cov2d[1];
  const T lambda_max = mid + Sqrt(Max(T(kMinRadiusDiscriminant), mid * mid - det));
  return T(kSigmaExtent) * Sqrt(lambda_max);
}

// Half-open tile rectangle [x0, x1) × [y0, y1).
struct TileRect {
  int x0, y0, x1, y1;
  ATEX_HD bool empty() const { return x0 >= x1 || y0 >= y1; }
  ATEX_HD bool contains(int tx, int ty) const { return tx >= x0 && tx < x1 && ty >= y0 && ty < y1; }
};

// The tiles of the box m ± (half_x, half_y):
// [clamp(floor((m.x − half_x)/16), 0, TX), clamp(floor((m.x + half_x)/16) + 1, 0, TX)) in x,
// likewise y. Clamped in floating point before the conversion, so far-away centres cannot overflow.
template <typename T>
ATEX_HD TileRect TileRectOfBox(const Vec2<T>& mean2d, T half_x, T half_y, int tiles_x, int tiles_y) {
  const T inv_tile = T(1) / T(kTileSize);
  const T tx = T(tiles_x), ty = T(tiles_y);
  TileRect rect;
  rect.x0 = static_cast<int>(ClampNanLow(Floor((mean2d[0] - half_x) * inv_tile), T(0), tx));
  rect.x1 = static_cast<int>(ClampNanLow(Floor((mean2d[0] + half_x) * inv_tile) + T(1), T(0), tx));
  rect.y0 = static_cast<int>(ClampNanLow(Floor((mean2d[1] - half_y) * inv_tile), T(0), ty));
  rect.y1 = static_cast<int>(ClampNanLow(Floor((mean2d[1] + half_y) * inv_tile) + T(1), T(0), ty));
  return rect;
}

// The 3σ tile rectangle (conventions §4 step 5): the box m ± r.
template <typename T>
ATEX_HD TileRect ComputeTileRect(const Vec2<T>& mean2d, T radius, int tiles_x, int tiles_y) {
  return TileRectOfBox(mean2d, radius, radius, tiles_x, tiles_y);
}

// The tiles a splat can reach (conventions §4 step 7). A sample passes the 1/255 alpha
// cut only where opacity · G · (texture factor) ≥ 1/255, i.e. inside the ellipse
// ½ dᵀΣ₂⁻¹d ≤ L with L = ln(255 · max_alpha), max_alpha = opacity × the largest texture
// factor (1 untextured). That ellipse's bounding box has half-sides sqrt(2 L Σ₂xx) and
// sqrt(2 L Σ₂yy) (with slack for rounding). `rect` (the 3σ rectangle) is cut to the
// box: the tiles removed hold no pixel the splat could change, so images and gradients are
// the same, while faint and elongated splats enter fewer tile lists (gsplat does likewise).
// Empty when max_alpha < 1/255 (the splat cannot pass the cut anywhere).
template <typename T>
ATEX_HD TileRect ContributionTileRect(const TileRect& rect, const Vec2<T>& mean2d, const Vec3<T>& cov2d, T max_alpha,
                                      int tiles_x, int tiles_y) {
  const T ratio = max_alpha * T(255);
  if (!(ratio >= T(1))) return {rect.x0, rect.y0, rect.x0, rect.y0};
  const T two_l = T(2) * Log(ratio);
  // 0.1 % and one pixel of slack cover float rounding in the per-pixel test.
  const T half_x = Sqrt(two_l * Max(cov2d[0], T(0))) * T(1.001) + T(1);
  const T half_y = Sqrt(two_l * Max(cov2d[2], T(0))) * T(1.001) + T(1);
  const TileRect box = TileRectOfBox(mean2d, half_x, half_y, tiles_x, tiles_y);
  const TileRect out{Max(box.x0, rect.x0), Max(box.y0, rect.y0), Min(box.x1, rect.x1), Min(box.y1, rect.y1)};
  if (out.empty()) return {rect.x0, rect.y0, rect.x0, rect.y0};
  return out;
}

// ---- the whole per-Gaussian projection ------------------------------------------
template <typename T>
struct ProjectedGaussian {
  bool visible;      // t.z > near, det Σ₂ > 0, everything finite, tile rectangle non-empty
  Vec2<T> mean2d;    // pixels (valid when t.z > near)
  Vec3<T> conic;     // (A, B, C) of Σ₂⁻¹ (valid when visible)
  T depth;           // camera-space z
  int radius;        // ceil(3 sqrt(λ_max)) when visible, else 0
  TileRect rect;     // empty when not visible
  Vec3<T> cov2d;     // Σ₂ (xx, xy, yy) with the blur (valid when visible)
};

// `rotation` = R(q̂) of the (deformed) Gaussian, shared with the texture frame.
template <typename T>
ATEX_HD ProjectedGaussian<T> ProjectGaussian(const CameraModel<T>& cam, const Vec3<T>& mean,
                                             const Mat3<T>& rotation, const Vec3<T>& log_scale) {
  ProjectedGaussian<T> out;
  out.visible = false;
  out.mean2d = {{T(0), T(0)}};
  out.conic = {{T(0), T(0), T(0)}};
  out.radius = 0;
  out.rect = {0, 0, 0, 0};
  out.cov2d = {{T(0), T(0), T(0)}};
  const Vec3<T> t = WorldToCamera(cam, mean);
  out.depth = t[2];
  if (!(t[2] > cam.near_plane)) return out;
  out.mean2d = ProjectPoint(cam, t);
  const EwaJacobian<T> jac = ProjectionJacobian(cam, t);
  const Mat3<T> cov = CovarianceFromRotationScale(rotation, log_scale);
  const Vec3<T> cov2d = ProjectCovariance(cam, jac, cov);
  Vec3<T> conic;
  if (!InvertCovariance2d(cov2d, &conic)) return out;
  const T extent = ProjectedExtent(cov2d);
  if (!IsFinite(extent) || !IsFinite(out.mean2d[0]) || !IsFinite(out.mean2d[1]) || !IsFinite(conic[0]) ||
      !IsFinite(conic[1]) || !IsFinite(conic[2])) {
    return out;
  }
  const T radius = Ceil(extent);
  const TileRect rect = ComputeTileRect(out.mean2d, radius, cam.tiles_x, cam.tiles_y);
  if (rect.empty()) return out;
  out.visible = true;
  out.conic = conic;
  out.cov2d = cov2d;
  out.rect = rect;
  out.radius = static_cast<int>(Min(radius, T(kMaxRadiusPixels)));
  return out;
}

// Accumulates dL/dμ, dL/dR and dL/dlog_scale from dL/dmean2d and dL/dconic of a
// visible Gaussian (recomputes the forward intermediates).
template <typename T>
ATEX_HD void ProjectGaussianVjp(const CameraModel<T>& cam, const Vec3<T>& mean, const Mat3<T>& rotation,
                                const Vec3<T>& log_scale, const Vec2<T>& g_mean2d, const Vec3<T>& g_conic,
                                Vec3<T>* g_mean, Mat3<T>* g_rotation, Vec3<T>* g_log_scale) {
  const Vec3<T> t = WorldToCamera(cam, mean);
  const EwaJacobian<T> jac = ProjectionJacobian(cam, t);
  const Mat3<T> cov = CovarianceFromRotationScale(rotation, log_scale);
  const Vec3<T> cov2d = ProjectCovariance(cam, jac, cov);
  Vec3<T> conic{{T(0), T(0), T(0)}};
  InvertCovariance2d(cov2d, &conic);
  const Vec3<T> g_cov2d = InvertCovariance2dVjp(conic, g_conic);
  Mat3<T> g_cov = ZeroMat3<T>();
  const Mat23<T> g_j = ProjectCovarianceVjp(cam, jac, cov, g_cov2d, &g_cov);
  const Vec3<T> g_t = ProjectPointVjp(cam, t, g_mean2d) + ProjectionJacobianVjp(cam, t, jac, g_j);
  *g_mean += WorldToCameraVjp(cam, g_t);
  CovarianceFromRotationScaleVjp(rotation, log_scale, g_cov, g_rotation, g_log_scale);
}

}  // namespace atex::detail
