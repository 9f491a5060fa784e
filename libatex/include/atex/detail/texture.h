// Per-Gaussian texture planes (docs/conventions.md §5, paper eqs. 1–2): the
// texture frame of a deformed Gaussian, the ray–plane intersection giving the
// texture coordinates (u, v) of a pixel ray, corner-aligned bilinear sampling of
// the packed texels, the texel activations, and corner-aligned resampling for
// texture growth — each with its vector-Jacobian product.
//
// Texels of one Gaussian are [h][w][4] (rows along v, columns along u, raw RGBA
// innermost); callers pass a pointer to the Gaussian's first texel.
#pragma once

#include <type_traits>

#include "atex/detail/math.h"
#include "atex/detail/vec.h"
#include "atex/hd.h"

namespace atex::detail {

inline constexpr double kMinPlaneDenominator = 1e-10;  // |nᵀd| below this becomes ±1e-10 (§5.2)
inline constexpr double kTextureColorScale = 0.1;      // colour residual 0.1 tanh(r)
inline constexpr double kTextureAlphaScale = 0.1;      // opacity factor exp(0.1 tanh(a))

// What a pixel ray needs of one Gaussian's texture plane. Built once per
// Gaussian and view; everything per pixel is three dot products with the ray.
template <typename T>
struct TextureFrame {
  Vec3<T> axis_u;   // R' e_p: local axis p (spans u) in world coordinates
  Vec3<T> axis_v;   // R' e_q
  Vec3<T> normal;   // R' e_n, n = 3 − p − q
  T offset_u;       // axis_u · (μ' − o)
  T offset_v;       // axis_v · (μ' − o)
  T offset_n;       // normal · (μ' − o)
  T inv_scale_u;    // 1 / s'_p = exp(−log_scale[p])
  T inv_scale_v;    // 1 / s'_q
};

template <typename T>
ATEX_HD TextureFrame<T> ZeroTextureFrame() {
  TextureFrame<T> f;
  f.axis_u = f.axis_v = f.normal = {{T(0), T(0), T(0)}};
  f.offset_u = f.offset_v = f.offset_n = f.inv_scale_u = f.inv_scale_v = T(0);
  return f;
}

// `axis_u`, `axis_v`: the plane's canonical axes p ≠ q in {0, 1, 2}.
template <typename T>
ATEX_HD TextureFrame<T> MakeTextureFrame(const Mat3<T>& rotation, const Vec3<T>& mean, const Vec3<T>& log_scale,
                                         const Vec3<T>& camera_center, int axis_u, int axis_v) {
  const int axis_n = 3 - axis_u - axis_v;
  const Vec3<T> rel = mean - camera_center;
  TextureFrame<T> f;
  f.axis_u = Column(rotation, axis_u);
  f.axis_v = Column(rotation, axis_v);
  f.normal = Column(rotation, axis_n);
  f.offset_u = Dot(f.axis_u, rel);
  f.offset_v = Dot(f.axis_v, rel);
  f.offset_n = Dot(f.normal, rel);
  f.inv_scale_u = Exp(-log_scale[axis_u]);
  f.inv_scale_v = Exp(-log_scale[axis_v]);
  return f;
}

// Accumulates dL/dR', dL/dμ' and dL/dlog_scale' from the gradient of every frame field.
template <typename T>
ATEX_HD void MakeTextureFrameVjp(const Mat3<T>& rotation, const Vec3<T>& mean, const Vec3<T>& log_scale,
                                 const Vec3<T>& camera_center, int axis_u, int axis_v, const TextureFrame<T>& g,
                                 Mat3<T>* g_rotation, Vec3<T>* g_mean, Vec3<T>* g_log_scale) {
  const int axis_n = 3 - axis_u - axis_v;
  const Vec3<T> rel = mean - camera_center;
  AddToColumn(*g_rotation, axis_u, g.axis_u + g.offset_u * rel);
  AddToColumn(*g_rotation, axis_v, g.axis_v + g.offset_v * rel);
  AddToColumn(*g_rotation, axis_n, g.normal + g.offset_n * rel);
  *g_mean += g.offset_u * Column(rotation, axis_u);
  *g_mean += g.offset_v * Column(rotation, axis_v);
  *g_mean += g.offset_n * Column(rotation, axis_n);
  (*g_log_scale)[axis_u] += -g.inv_scale_u * Exp(-log_scale[axis_u]);
  (*g_log_scale)[axis_v] += -g.inv_scale_v * Exp(-log_scale[axis_v]);
}

// nᵀd with |nᵀd| < 1e-10 replaced by ±1e-10 (sign kept, +0 → +): edge-on planes give
// a finite λ and clamped coordinates. `replaced` reports the substitution.
template <typename T>
ATEX_HD T SafePlaneDenominator(T denominator, bool* replaced) {
  *replaced = Abs(denominator) < T(kMinPlaneDenominator);
  if (!*replaced) return denominator;
  return denominator < T(0) ? -T(kMinPlaneDenominator) : T(kMinPlaneDenominator);
}

template <typename T>
struct TexCoord {
  T u, v;          // clamped to [−1, 1]
  bool u_clamped;  // the unclamped value was outside [−1, 1] (or NaN): no gradient
  bool v_clamped;
};

// Ray o + λd through a pixel against the plane through μ' with normal n:
// λ = nᵀ(μ' − o)/nᵀd, ℓ = R'ᵀ(o + λd − μ'), u = ℓ[p]/s'_p, v = ℓ[q]/s'_q, each clamped.
template <typename T>
ATEX_HD TexCoord<T> ComputeTexCoord(const TextureFrame<T>& f, const Vec3<T>& ray) {
  bool replaced;
  const T denominator = SafePlaneDenominator(Dot(f.normal, ray), &replaced);
  const T lambda = f.offset_n / denominator;
  const T u = (lambda * Dot(f.axis_u, ray) - f.offset_u) * f.inv_scale_u;
  const T v = (lambda * Dot(f.axis_v, ray) - f.offset_v) * f.inv_scale_v;
  TexCoord<T> tc;
  tc.u_clamped = !(u >= T(-1) && u <= T(1));
  tc.v_clamped = !(v >= T(-1) && v <= T(1));
  tc.u = ClampNanLow(u, T(-1), T(1));
  tc.v = ClampNanLow(v, T(-1), T(1));
  return tc;
}

// Accumulates into `g_frame` the gradient of the frame fields given dL/du and dL/dv
// of the clamped coordinates (zero where clamped).
template <typename T>
ATEX_HD void ComputeTexCoordVjp(const TextureFrame<T>& f, const Vec3<T>& ray, const TexCoord<T>& tc, T g_u, T g_v,
                                TextureFrame<T>* g_frame) {
  if (tc.u_clamped) g_u = T(0);
  if (tc.v_clamped) g_v = T(0);
  if (g_u == T(0) && g_v == T(0)) return;
  bool replaced;
  const T denominator = SafePlaneDenominator(Dot(f.normal, ray), &replaced);
  const T lambda = f.offset_n / denominator;
  const T du = Dot(f.axis_u, ray), dv = Dot(f.axis_v, ray);
  const T lu = lambda * du - f.offset_u;  // ℓ[p]
  const T lv = lambda * dv - f.offset_v;  // ℓ[q]
  const T g_lu = g_u * f.inv_scale_u;
  const T g_lv = g_v * f.inv_scale_v;
  g_frame->inv_scale_u += g_u * lu;
  g_frame->inv_scale_v += g_v * lv;
  g_frame->axis_u += (g_lu * lambda) * ray;
  g_frame->axis_v += (g_lv * lambda) * ray;
  g_frame->offset_u += -g_lu;
  g_frame->offset_v += -g_lv;
  const T g_lambda = g_lu * du + g_lv * dv;
  g_frame->offset_n += g_lambda / denominator;
  if (!replaced) g_frame->normal += (-g_lambda * lambda / denominator) * ray;
}

// ---- corner-aligned bilinear sampling --------------------------------------------
// One axis: continuous index g in [0, size − 1] → knots i0 ≤ i1 and the weight of i1.
template <typename T>
struct TexelTap {
  int i0, i1;
  T frac;
};

// i0 = min(floor(g), size − 1), i1 = min(i0 + 1, size − 1), frac = g − i0 (§5.2).
template <typename T>
ATEX_HD TexelTap<T> MakeTexelTap(T g, int size) {
  TexelTap<T> tap;
  const T last = T(size - 1);
  tap.i0 = static_cast<int>(Min(Floor(ClampNanLow(g, T(0), last)), last));
  tap.i1 = tap.i0 + 1 < size ? tap.i0 + 1 : size - 1;
  tap.frac = g - T(tap.i0);
  return tap;
}

// Continuous texel index of a clamped coordinate c in [−1, 1]: (c + 1)/2 · (size − 1).
template <typename T>
ATEX_HD T TexelGridCoordinate(T c, int size) {
  return (c + T(1)) * T(0.5) * T(size - 1);
}

template <typename T>
struct BilinearTaps {
  TexelTap<T> x;  // along u (width)
  TexelTap<T> y;  // along v (height)
};

template <typename T>
ATEX_HD BilinearTaps<T> MakeBilinearTaps(const TexCoord<T>& tc, int height, int width) {
  return {MakeTexelTap(TexelGridCoordinate(tc.u, width), width),
          MakeTexelTap(TexelGridCoordinate(tc.v, height), height)};
}

// One texel's raw RGBA. In device code (float) a single 16-byte read-only load, so
// `texel` must be 16-byte aligned there and not written by the running kernel: texel rows
// start at multiples of 4 floats of a cudaMalloc'd pool, and rasterisers only read them.
template <typename T>
ATEX_HD Vec4<T> LoadTexel(const T* texel /* [4] */) {
#ifdef __CUDA_ARCH__
  if constexpr (std::is_same_v<T, float>) {
    const float4 v = __ldg(reinterpret_cast<const float4*>(texel));
    return {{v.x, v.y, v.z, v.w}};
  }
#endif
  return {{texel[0], texel[1], texel[2], texel[3]}};
}

// Bilinear RGBA over texels[y][x][4] (row stride `width`).
template <typename T>
ATEX_HD Vec4<T> SampleTexels(const T* texels /* [h][w][4] */, int width, const BilinearTaps<T>& taps) {
  const T fx = taps.x.frac, fy = taps.y.frac;
  const T w00 = (T(1) - fx) * (T(1) - fy), w01 = fx * (T(1) - fy), w10 = (T(1) - fx) * fy, w11 = fx * fy;
  const Vec4<T> t00 = LoadTexel(texels + (taps.y.i0 * width + taps.x.i0) * 4);
  const Vec4<T> t01 = LoadTexel(texels + (taps.y.i0 * width + taps.x.i1) * 4);
  const Vec4<T> t10 = LoadTexel(texels + (taps.y.i1 * width + taps.x.i0) * 4);
  const Vec4<T> t11 = LoadTexel(texels + (taps.y.i1 * width + taps.x.i1) * 4);
  Vec4<T> out;
  for (int c = 0; c < 4; ++c) out[c] = w00 * t00[c] + w01 * t01[c] + w10 * t10[c] + w11 * t11[c];
  return out;
}

// Accumulates dL/dtexels and returns dL/du, dL/dv (of the clamped coordinates) in *g_u, *g_v.
template <typename T>
ATEX_HD void SampleTexelsVjp(const T* texels /* [h][w][4] */, int height, int width, const BilinearTaps<T>& taps,
                             const Vec4<T>& g_rgba, T* g_texels /* [h][w][4], accumulated */, T* g_u, T* g_v) {
  const T fx = taps.x.frac, fy = taps.y.frac;
  const T w00 = (T(1) - fx) * (T(1) - fy), w01 = fx * (T(1) - fy), w10 = (T(1) - fx) * fy, w11 = fx * fy;
  const int i00 = (taps.y.i0 * width + taps.x.i0) * 4, i01 = (taps.y.i0 * width + taps.x.i1) * 4;
  const int i10 = (taps.y.i1 * width + taps.x.i0) * 4, i11 = (taps.y.i1 * width + taps.x.i1) * 4;
  T g_fx = T(0), g_fy = T(0);
  for (int c = 0; c < 4; ++c) {
    g_texels[i00 + c] += w00 * g_rgba[c];
    g_texels[i01 + c] += w01 * g_rgba[c];
    g_texels[i10 + c] += w10 * g_rgba[c];
    g_texels[i11 + c] += w11 * g_rgba[c];
    g_fx += g_rgba[c] * ((T(1) - fy) * (texels[i01 + c] - texels[i00 + c]) + fy * (texels[i11 + c] - texels[i10 + c]));
    g_fy += g_rgba[c] * ((T(1) - fx) * (texels[i10 + c] - texels[i00 + c]) + fx * (texels[i11 + c] - texels[i01 + c]));
  }
  *g_u = g_fx * T(0.5) * T(width - 1);
  *g_v = g_fy * T(0.5) * T(height - 1);
}

// ---- activations (§5.3, §5.5) --------------------------------------------------
// Colour residual 0.1 tanh(r).
template <typename T>
ATEX_HD T TextureColorResidual(T r) {
  return T(kTextureColorScale) * Tanh(r);
}
template <typename T>
ATEX_HD T TextureColorResidualVjp(T r, T g) {
  const T th = Tanh(r);
  return g * T(kTextureColorScale) * (T(1) - th * th);
}
// Opacity factor exp(0.1 tanh(a)), in [e^−0.1, e^0.1].
template <typename T>
ATEX_HD T TextureAlphaFactor(T a) {
  return Exp(T(kTextureAlphaScale) * Tanh(a));
}
template <typename T>
ATEX_HD T TextureAlphaFactorVjp(T a, T g) {
  const T th = Tanh(a);
  return g * Exp(T(kTextureAlphaScale) * th) * T(kTextureAlphaScale) * (T(1) - th * th);
}
// An upper bound of TextureAlphaFactor that is safe under rounding (e^0.1 = 1.105170918…),
// for the exact early-out "α G · bound < 1/255 ⇒ α̃ < 1/255" before sampling a texture.
inline constexpr double kTextureAlphaFactorBound = 1.1052;

// ---- growth (§5 "Growth preserves the image") -----------------------------------
// Resamples one Gaussian's [h][w][channels] texels onto a new_h × new_w corner-aligned
// grid: new knot (y', x') sits at old continuous index (y'(h−1)/(new_h−1), x'(w−1)/(new_w−1))
// (the centre (h−1)/2 when the new side is 1) and takes the old bilinear field there.
// Growing (new ≥ old per side) reproduces the old piecewise-linear field exactly, so
// rendering is unchanged up to rounding; shrinking is a plain resample.
template <typename T>
ATEX_HD void UpsampleTexture(const T* src /* [h][w][channels] */, int height, int width,
                             T* dst /* [new_h][new_w][channels] */, int new_height, int new_width, int channels) {
  for (int y = 0; y < new_height; ++y) {
    const T gy = new_height > 1 ? T(y) * T(height - 1) / T(new_height - 1) : T(0.5) * T(height - 1);
    const TexelTap<T> ty = MakeTexelTap(gy, height);
    for (int x = 0; x < new_width; ++x) {
      const T gx = new_width > 1 ? T(x) * T(width - 1) / T(new_width - 1) : T(0.5) * T(width - 1);
      const TexelTap<T> tx = MakeTexelTap(gx, width);
      const T w00 = (T(1) - tx.frac) * (T(1) - ty.frac), w01 = tx.frac * (T(1) - ty.frac);
      const T w10 = (T(1) - tx.frac) * ty.frac, w11 = tx.frac * ty.frac;
      for (int c = 0; c < channels; ++c) {
        dst[(y * new_width + x) * channels + c] =
            w00 * src[(ty.i0 * width + tx.i0) * channels + c] + w01 * src[(ty.i0 * width + tx.i1) * channels + c] +
            w10 * src[(ty.i1 * width + tx.i0) * channels + c] + w11 * src[(ty.i1 * width + tx.i1) * channels + c];
      }
    }
  }
}

// Stage2Config::rescale_grown_moments: the factor a = old texels / new texels by which a
// grown texture's interpolated Adam moments are multiplied (m by a, v by a²). When a texture's
// gradient is spread evenly over it, one new texel receives a of what one old texel received.
template <typename T>
ATEX_HD T GrownMomentShare(int height, int width, int new_height, int new_width) {
  return T(height * width) / T(new_height * new_width);
}

}  // namespace atex::detail
