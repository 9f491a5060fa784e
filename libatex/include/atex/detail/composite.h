// What one Gaussian does to one pixel (docs/conventions.md §5, paper eq. 3):
// the projected falloff, the texture sample, the clamped alpha and the colour,
// plus the front-to-back blending step — each with its vector-Jacobian
// product. The CPU engine and the CUDA kernels differ only in how they loop over
// pixels and Gaussians; both call these.
#pragma once

#include "atex/detail/math.h"
#include "atex/detail/texture.h"
#include "atex/detail/vec.h"
#include "atex/hd.h"

namespace atex::detail {

inline constexpr double kMaxSplatAlpha = 0.99;          // α̃ = min(0.99, ...)
inline constexpr double kMinSplatAlpha = 1.0 / 255.0;   // skip if α̃ < 1/255
inline constexpr double kMinTransmittance = 1e-4;       // stop before adding i if T(1 − α̃) < 1e-4

// power = −½(A Δx² + C Δy²) − B Δx Δy, Δ = p − m, conic = (A, B, C).
template <typename T>
ATEX_HD T GaussianPower(const Vec3<T>& conic, T dx, T dy) {
  return T(-0.5) * (conic[0] * dx * dx + conic[2] * dy * dy) - conic[1] * dx * dy;
}
// Accumulates dL/dconic and dL/dm (m = projected centre, so ∂Δ/∂m = −1).
template <typename T>
ATEX_HD void GaussianPowerVjp(const Vec3<T>& conic, T dx, T dy, T g_power, Vec3<T>* g_conic, Vec2<T>* g_mean2d) {
  (*g_conic)[0] += T(-0.5) * dx * dx * g_power;
  (*g_conic)[1] += -dx * dy * g_power;
  (*g_conic)[2] += T(-0.5) * dy * dy * g_power;
  (*g_mean2d)[0] += (conic[0] * dx + conic[1] * dy) * g_power;
  (*g_mean2d)[1] += (conic[1] * dx + conic[2] * dy) * g_power;
}

// The alpha cut of a sample: α̃ = min(0.99, α), kept when !(α̃ < 1/255) (a NaN is kept).
template <typename T>
ATEX_HD T ClampSplatAlpha(T alpha) {
  return alpha > T(kMaxSplatAlpha) ? T(kMaxSplatAlpha) : alpha;
}
template <typename T>
ATEX_HD bool SplatAlphaKept(T clamped_alpha) {
  return !(clamped_alpha < T(kMinSplatAlpha));
}
// Exact early-out before sampling a texture: the texture factor is at most e^0.1 <
// kTextureAlphaFactorBound, so a textured sample of α·G = `base` below this is cut whatever
// its texels.
template <typename T>
ATEX_HD bool TexturedSampleIsCut(T base) {
  return base * T(kTextureAlphaFactorBound) < T(kMinSplatAlpha);
}

// A 1×1 texture is the same texel wherever a ray meets its plane, so its sample needs
// no texture coordinates and its activations are the same at every pixel: a rasteriser
// may compute them once per splat and view (most adaptive textures stay 1×1).
template <typename T>
struct ConstantTexel {
  Vec4<T> raw;             // the texel (raw RGBA)
  Vec3<T> color_residual;  // TextureColorResidual(raw[c])
  T alpha_factor;          // TextureAlphaFactor(raw[3])
};

template <typename T>
ATEX_HD ConstantTexel<T> MakeConstantTexel(const T* texel /* [4] */) {
  ConstantTexel<T> c;
  c.raw = LoadTexel(texel);
  for (int ch = 0; ch < 3; ++ch) c.color_residual[ch] = TextureColorResidual(c.raw[ch]);
  c.alpha_factor = TextureAlphaFactor(c.raw[3]);
  return c;
}

// One Gaussian as the rasteriser sees it (per view).
template <typename T>
struct SplatParams {
  Vec2<T> mean2d;               // pixels
  Vec3<T> conic;                // (A, B, C)
  T opacity;                    // sigmoid(logit)
  Vec3<T> color;                // c_SH (already clamped at 0)
  const TextureFrame<T>* frame; // null: no texture (r = 0, a = 0)
  const T* texels;              // [tex_h][tex_w][4] of this Gaussian (when frame is set)
  int tex_h, tex_w;
  // Optional, 1×1 textures only: MakeConstantTexel(texels), computed once by the caller.
  // The results are the same with or without it.
  const ConstantTexel<T>* constant = nullptr;
};

// The contribution of one splat at one pixel, with what its VJP needs.
template <typename T>
struct SplatSample {
  bool contributes;    // false: skipped (power > 0 or α̃ < 1/255); nothing else is meaningful then
  T dx, dy;            // Δ = p − m
  T falloff;           // G = exp(power)
  T alpha;             // α̃
  bool alpha_clamped;  // α̃ = 0.99 by the min (no gradient)
  Vec3<T> color;       // c_SH + 0.1 tanh(r)
  TexCoord<T> tc;      // texture state (textured splats that reached the sample)
  BilinearTaps<T> taps;
  Vec4<T> texel;       // sampled raw RGBA
};

// Pixel centre (px, py) with ray direction `ray` (PixelRayDirection).
// The untextured path computes α̃ = α·G and c_SH exactly as the textured path does
// with r = a = 0 (tanh 0 = 0, exp 0 = 1), so zero texels render bit-identically.
template <typename T>
ATEX_HD SplatSample<T> EvaluateSplat(const SplatParams<T>& s, T px, T py, const Vec3<T>& ray) {
  SplatSample<T> out;
  out.contributes = false;
  out.dx = px - s.mean2d[0];
  out.dy = py - s.mean2d[1];
  const T power = GaussianPower(s.conic, out.dx, out.dy);
  if (power > T(0)) return out;
  out.falloff = Exp(power);
  const T base = s.opacity * out.falloff;
  T alpha = base;
  out.color = s.color;
  if (s.frame != nullptr) {
    if (TexturedSampleIsCut(base)) return out;
    if (s.tex_h == 1 && s.tex_w == 1) {
      // The taps of a 1×1 grid are (0, 0) with zero fractions whatever (u, v), and the
      // coordinates get no gradient (the four taps are one texel): skip the ray–plane step.
      out.tc = {T(0), T(0), true, true};
      out.taps = {{0, 0, T(0)}, {0, 0, T(0)}};
      out.texel = s.constant != nullptr ? s.constant->raw : LoadTexel(s.texels);
    } else {
      out.tc = ComputeTexCoord(*s.frame, ray);
      out.taps = MakeBilinearTaps(out.tc, s.tex_h, s.tex_w);
      out.texel = SampleTexels(s.texels, s.tex_w, out.taps);
    }
    // s.constant holds exactly these activations of its texel, computed once per splat.
    alpha = base * (s.constant != nullptr ? s.constant->alpha_factor : TextureAlphaFactor(out.texel[3]));
    for (int ch = 0; ch < 3; ++ch) {
      out.color[ch] += s.constant != nullptr ? s.constant->color_residual[ch] : TextureColorResidual(out.texel[ch]);
    }
  }
  out.alpha_clamped = alpha > T(kMaxSplatAlpha);
  out.alpha = ClampSplatAlpha(alpha);
  out.contributes = SplatAlphaKept(out.alpha);
  return out;
}

// Per-Gaussian gradient of the rasteriser's inputs (SplatParams' differentiable fields).
template <typename T>
struct SplatGrad {
  Vec2<T> mean2d;
  Vec3<T> conic;
  T opacity;
  Vec3<T> color;            // dL/dc_SH (before the SH clamp's mask)
  TextureFrame<T> frame;    // zero for untextured splats
};

template <typename T>
ATEX_HD SplatGrad<T> ZeroSplatGrad() {
  SplatGrad<T> g;
  g.mean2d = {{T(0), T(0)}};
  g.conic = {{T(0), T(0), T(0)}};
  g.opacity = T(0);
  g.color = {{T(0), T(0), T(0)}};
  g.frame = ZeroTextureFrame<T>();
  return g;
}

// Given dL/dc̃ (`g_color`) and dL/dα̃ (`g_alpha`) of a contributing sample, accumulates
// into `g` and into the Gaussian's texel gradient `g_texels` ([tex_h][tex_w][4]).
template <typename T>
ATEX_HD void EvaluateSplatVjp(const SplatParams<T>& s, const Vec3<T>& ray, const SplatSample<T>& smp,
                              const Vec3<T>& g_color, T g_alpha, SplatGrad<T>* g, T* g_texels) {
  g->color += g_color;
  const bool textured = s.frame != nullptr;
  const T factor =
      !textured ? T(1) : (s.constant != nullptr ? s.constant->alpha_factor : TextureAlphaFactor(smp.texel[3]));
  Vec4<T> g_rgba{{T(0), T(0), T(0), T(0)}};
  if (textured) {
    for (int ch = 0; ch < 3; ++ch) g_rgba[ch] = TextureColorResidualVjp(smp.texel[ch], g_color[ch]);
  }
  if (!smp.alpha_clamped) {
    const T base = s.opacity * smp.falloff;
    g->opacity += g_alpha * smp.falloff * factor;
    const T g_falloff = g_alpha * s.opacity * factor;
    GaussianPowerVjp(s.conic, smp.dx, smp.dy, g_falloff * smp.falloff, &g->conic, &g->mean2d);
    if (textured) g_rgba[3] = TextureAlphaFactorVjp(smp.texel[3], g_alpha * base);
  }
  if (textured) {
    T g_u, g_v;
    SampleTexelsVjp(s.texels, s.tex_h, s.tex_w, smp.taps, g_rgba, g_texels, &g_u, &g_v);
    ComputeTexCoordVjp(*s.frame, ray, smp.tc, g_u, g_v, &g->frame);
  }
}

// ---- front-to-back blending --------------------------------------------------------
// Forward (per pixel, splats in depth order, skipping non-contributing samples):
//   T_next = T (1 − α̃); if T_next < 1e-4 stop before adding the splat;
//   C += c̃ α̃ T; T = T_next.   Finally Î = C + T_final b, alpha = 1 − T_final.
//
// Backward, back to front from the last contributor, with T_i recovered by
// division (T_i = T_{i+1}/(1 − α̃_i), 1 − α̃ ≥ 0.01) and
// back_i = Σ_{j>i} c̃_j α̃_j T_j + T_final b:
//   dL/dc̃_i = α̃_i T_i g_C
//   dL/dα̃_i = Σ_ch g_C (c̃_i T_i − back_i/(1 − α̃_i)) + g_A T_final/(1 − α̃_i)
// Returns dL/dα̃_i and sets *g_color = dL/dc̃_i.
template <typename T>
ATEX_HD T BlendStepVjp(T alpha, const Vec3<T>& color, T transmittance_before, const Vec3<T>& back,
                       T final_transmittance, const Vec3<T>& g_pixel, T g_pixel_alpha, Vec3<T>* g_color) {
  const T inv_one_minus = T(1) / (T(1) - alpha);
  const T weight = alpha * transmittance_before;
  T g_alpha = g_pixel_alpha * final_transmittance * inv_one_minus;
  for (int ch = 0; ch < 3; ++ch) {
    (*g_color)[ch] = weight * g_pixel[ch];
    g_alpha += g_pixel[ch] * (color[ch] * transmittance_before - back[ch] * inv_one_minus);
  }
  return g_alpha;
}

}  // namespace atex::detail
