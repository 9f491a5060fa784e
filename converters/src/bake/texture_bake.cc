// Textured Gaussians -> plain Gaussians (atex/converters/texture_bake.h).
//
// Design. A texture lives on the plane of the Gaussian's two largest axes, in coordinates
// (u, v) measured in standard deviations and clamped to [−1, 1] (conventions §5). Seen face-on,
// the textured Gaussian is one layer with opacity O(u, v) = min(0.99, α·g(u, v)·F(u, v)),
// g = exp(−(u² + v²)/2), F = exp(0.1·tanh(a)), and colour c_SH + Δc(u, v), Δc = 0.1·tanh(r).
//
// Why 2 children per textured axis (not one per texel): the texture's effect is bounded (±0.1 in
// colour, ±10 % in opacity) and sits inside ±1σ, where a 2-knot side is linear and a 4-knot side
// is mostly its linear part plus a small bump; two children per axis carry the linear part (the
// texture's first moment, the largest share of its energy), so a 4x4 texture costs 4 Gaussians,
// not 16. A 1xN texture splits along its one textured axis only (2 children).
//
// Closed form (moment match): children at ±d along each split axis, standard deviation
// sqrt(1 − d²) there, so their equal-weight mixture has the parent's mean and covariance; each
// child's opacity starts at the parent's mass share, α·F(child centre)/(n·s_u·s_v). A few
// (d, width) candidates around it are fitted and the best kept (see BakeTextures).
// Fit (deterministic, fixed steps): on a grid over [−3, 3]², Gauss-Newton on the children's
// opacities a_k ∈ [1e-6, 0.99] so that their composite 1 − Π(1 − a_k·b_k) matches O; then the
// colours c_k (added to the DC term) by linear least squares of Σ w_k·c_k, w_k = a_k·b_k/Σ a_j·b_j
// (the share of each child in the layer, ignoring the order of nearly coplanar children),
// against Δc, weighted by O, with a small ridge toward the parent's colour. The normal axis,
// rotation, higher SH bands and time windows are the parent's.
#include "atex/converters/texture_bake.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <new>
#include <utility>
#include <vector>

#include "atex/detail/quaternion.h"
#include "atex/detail/texture.h"
#include "atex/render.h"

namespace atex {
namespace {

constexpr double kShC0 = 0.28209479177387814;
constexpr double kMaxAlpha = 0.99;  // the renderer's clamp (§5 step 3)
constexpr double kMinAlpha = 1e-6;
constexpr double kGridExtent = 3.0;  // fit over ±3 standard deviations
constexpr int kMaxChildren = 4;
// A texture whose colour and opacity factor vary less than half an 8-bit level over its texels
// is constant for any 8-bit display: it is folded like a 1x1 texture instead of split.
constexpr double kConstantTolerance = 0.5 / 255;
// Split only when the children's fit error is below this share of folding's: the face-on fit
// models the renderer only roughly (one layer, no projection), and an opaque parent's children
// (sub-additive compositing) rendered worse than folding in the tests while fitting about as well.
constexpr double kSplitGain = 0.8;

double Logit(double a) { return std::log(a / (1 - a)); }
double Sigmoid(double x) { return 1 / (1 + std::exp(-x)); }

// The activated texture (Δc, F) at clamped plane coordinates (u, v) of Gaussian `i`.
struct TexelValue {
  std::array<double, 3> colour;  // 0.1·tanh(r)
  double factor;                 // exp(0.1·tanh(a))
};

TexelValue SampleActivated(const TexturePool& t, size_t i, double u, double v) {
  detail::TexCoord<float> tc;
  tc.u = float(std::clamp(u, -1.0, 1.0));
  tc.v = float(std::clamp(v, -1.0, 1.0));
  tc.u_clamped = tc.v_clamped = false;
  const int h = t.heights[i], w = t.widths[i];
  const detail::Vec4<float> raw =
      detail::SampleTexels(&t.texels[t.offsets[i] * kTexelChannels], w, detail::MakeBilinearTaps(tc, h, w));
  TexelValue out;
  for (int c = 0; c < 3; ++c) out.colour[size_t(c)] = detail::kTextureColorScale * std::tanh(double(raw[c]));
  out.factor = std::exp(detail::kTextureAlphaScale * std::tanh(double(raw[3])));
  return out;
}

bool NearlyConstant(const TexturePool& t, size_t i) {
  const size_t count = size_t(t.heights[i]) * t.widths[i];
  const float* texels = &t.texels[t.offsets[i] * kTexelChannels];
  for (int c = 0; c < 4; ++c) {
    const double scale = c < 3 ? detail::kTextureColorScale : detail::kTextureAlphaScale;
    double lo = 1e30, hi = -1e30;
    for (size_t k = 0; k < count; ++k) {
      const double value = scale * std::tanh(double(texels[k * 4 + size_t(c)]));
      lo = std::min(lo, value), hi = std::max(hi, value);
    }
    // exp(x) of x in [−0.1, 0.1] changes by at most 1.11·Δx: compare the factor's spread too.
    if ((hi - lo) * (c < 3 ? 1.0 : 1.11) > kConstantTolerance) return false;
  }
  return true;
}

// Solves the n×n system a·x = b (n ≤ 4) by Gaussian elimination with partial pivoting; a
// singular pivot leaves that unknown at 0.
void SolveSmall(std::array<std::array<double, kMaxChildren>, kMaxChildren> a, std::array<double, kMaxChildren> b,
                int n, std::array<double, kMaxChildren>* x) {
  for (int col = 0; col < n; ++col) {
    int pivot = col;
    for (int r = col + 1; r < n; ++r)
      if (std::abs(a[size_t(r)][size_t(col)]) > std::abs(a[size_t(pivot)][size_t(col)])) pivot = r;
    std::swap(a[size_t(col)], a[size_t(pivot)]);
    std::swap(b[size_t(col)], b[size_t(pivot)]);
    const double p = a[size_t(col)][size_t(col)];
    if (std::abs(p) < 1e-300) continue;
    for (int r = col + 1; r < n; ++r) {
      const double f = a[size_t(r)][size_t(col)] / p;
      for (int k = col; k < n; ++k) a[size_t(r)][size_t(k)] -= f * a[size_t(col)][size_t(k)];
      b[size_t(r)] -= f * b[size_t(col)];
    }
  }
  for (int r = n - 1; r >= 0; --r) {
    double s = b[size_t(r)];
    for (int k = r + 1; k < n; ++k) s -= a[size_t(r)][size_t(k)] * (*x)[size_t(k)];
    const double p = a[size_t(r)][size_t(r)];
    (*x)[size_t(r)] = std::abs(p) < 1e-300 ? 0.0 : s / p;
  }
}

// Squared error of a layer at one point, in image units: the premultiplied texture colour
// (opacity × colour offset, per channel) and the opacity times 0.5, the mean contrast assumed
// between the Gaussian's colour and what lies behind it (unknown here).
double LayerError(double alpha, const std::array<double, 3>& premultiplied, double want_alpha,
                  const std::array<double, 3>& want_premultiplied) {
  double e = 3 * 0.25 * (alpha - want_alpha) * (alpha - want_alpha);
  for (int c = 0; c < 3; ++c) {
    const double d = premultiplied[size_t(c)] - want_premultiplied[size_t(c)];
    e += d * d;
  }
  return e;
}

struct Child {
  double u = 0, v = 0;            // centre in parent standard deviations
  double alpha = 0;               // opacity
  std::array<double, 3> dc{};     // colour added to the parent's (before the SH constant)
};

// The textured Gaussian seen face-on, on the fit grid over [−3, 3]² (plane standard deviations);
// shared by every candidate geometry.
struct Profile {
  size_t m = 0;                          // grid points
  std::vector<double> u, v;              // [m] coordinates
  std::vector<double> target;            // [m] O = min(0.99, α·g·F)
  std::vector<double> colour;            // [m][3] Δc = 0.1·tanh(r)
  double fold_se = 0;     // Σ LayerError of folding the centre texel into the parent
  double unbaked_se = 0;  // Σ LayerError of the parent without its texture
};

Profile SampleProfile(const TexturePool& t, size_t i, double alpha, int grid) {
  Profile p;
  p.m = size_t(grid) * size_t(grid);
  p.u.resize(p.m), p.v.resize(p.m), p.target.resize(p.m), p.colour.resize(p.m * 3);
  const TexelValue centre = SampleActivated(t, i, 0, 0);
  for (int y = 0; y < grid; ++y) {
    for (int x = 0; x < grid; ++x) {
      const size_t s = size_t(y) * size_t(grid) + size_t(x);
      const double u = -kGridExtent + 2 * kGridExtent * x / (grid - 1);
      const double v = -kGridExtent + 2 * kGridExtent * y / (grid - 1);
      p.u[s] = u, p.v[s] = v;
      const TexelValue tv = SampleActivated(t, i, u, v);
      const double parent = alpha * std::exp(-0.5 * (u * u + v * v));
      p.target[s] = std::min(kMaxAlpha, parent * tv.factor);
      const double folded = std::min(kMaxAlpha, parent * centre.factor);
      std::array<double, 3> folded_colour, wanted, none{};
      for (int c = 0; c < 3; ++c) {
        p.colour[s * 3 + size_t(c)] = tv.colour[size_t(c)];
        folded_colour[size_t(c)] = folded * centre.colour[size_t(c)];
        wanted[size_t(c)] = p.target[s] * tv.colour[size_t(c)];
      }
      p.fold_se += LayerError(folded, folded_colour, p.target[s], wanted);
      p.unbaked_se += LayerError(std::min(kMaxAlpha, parent), none, p.target[s], wanted);
    }
  }
  return p;
}

struct Fit {
  std::array<Child, kMaxChildren> children;
  int count = 0;
  double scale_u = 1, scale_v = 1;  // child / parent standard deviation
  std::vector<double> base;         // [m][count] each child's unit footprint b_k on the grid
  double se = 0;                    // Σ LayerError of the result
};

using Small = std::array<std::array<double, kMaxChildren>, kMaxChildren>;

// Gauss-Newton (Levenberg-damped) on the children's opacities: their composite 1 − Π(1 − a_k·b_k)
// against the target profile, a_k kept in [kMinAlpha, kMaxAlpha].
void FitOpacities(const Profile& p, int iterations, Fit* fit) {
  const int n = fit->count;
  const auto b = [&](size_t s, int k) { return fit->base[s * size_t(n) + size_t(k)]; };
  for (int it = 0; it < iterations; ++it) {
    Small jtj{};
    std::array<double, kMaxChildren> jtr{};
    for (size_t s = 0; s < p.m; ++s) {
      std::array<double, kMaxChildren> keep{};  // 1 − a_k·b_k
      double all = 1;
      for (int k = 0; k < n; ++k) {
        keep[size_t(k)] = 1 - fit->children[size_t(k)].alpha * b(s, k);
        all *= keep[size_t(k)];
      }
      const double residual = (1 - all) - p.target[s];
      std::array<double, kMaxChildren> jac{};
      for (int k = 0; k < n; ++k) {
        double others = 1;
        for (int j = 0; j < n; ++j)
          if (j != k) others *= keep[size_t(j)];
        jac[size_t(k)] = b(s, k) * others;
      }
      for (int k = 0; k < n; ++k) {
        jtr[size_t(k)] += jac[size_t(k)] * residual;
        for (int j = 0; j < n; ++j) jtj[size_t(k)][size_t(j)] += jac[size_t(k)] * jac[size_t(j)];
      }
    }
    for (int k = 0; k < n; ++k) jtj[size_t(k)][size_t(k)] *= 1 + 1e-3;
    std::array<double, kMaxChildren> step{};
    SolveSmall(jtj, jtr, n, &step);
    for (int k = 0; k < n; ++k) {
      Child& c = fit->children[size_t(k)];
      c.alpha = std::clamp(c.alpha - step[size_t(k)], kMinAlpha, kMaxAlpha);
    }
  }
}

// Colours: least squares of the premultiplied layer colour, Σ_k Ô·w_k·c_k against O·Δc (Ô the
// children's composite opacity, w_k = a_k·b_k/Σ a_j·b_j their shares), with a small ridge toward
// the parent's colour; then the result's error.
void FitColours(const Profile& p, Fit* fit) {
  const int n = fit->count;
  std::vector<double> shown_alpha(p.m), basis(p.m * size_t(n));
  Small normal{};
  std::array<std::array<double, kMaxChildren>, 3> rhs{};
  for (size_t s = 0; s < p.m; ++s) {
    double sum = 0, all = 1;
    for (int k = 0; k < n; ++k) {
      const double ab = fit->children[size_t(k)].alpha * fit->base[s * size_t(n) + size_t(k)];
      sum += ab, all *= 1 - ab;
    }
    shown_alpha[s] = 1 - all;
    for (int k = 0; k < n; ++k) {
      const double ab = fit->children[size_t(k)].alpha * fit->base[s * size_t(n) + size_t(k)];
      basis[s * size_t(n) + size_t(k)] = shown_alpha[s] * (sum > 0 ? ab / sum : 1.0 / n);
    }
    for (int k = 0; k < n; ++k) {
      const double bk = basis[s * size_t(n) + size_t(k)];
      for (int j = 0; j < n; ++j) normal[size_t(k)][size_t(j)] += bk * basis[s * size_t(n) + size_t(j)];
      for (int c = 0; c < 3; ++c) rhs[size_t(c)][size_t(k)] += bk * p.target[s] * p.colour[s * 3 + size_t(c)];
    }
  }
  double trace = 0;
  for (int k = 0; k < n; ++k) trace += normal[size_t(k)][size_t(k)];
  for (int k = 0; k < n; ++k) normal[size_t(k)][size_t(k)] += 1e-3 * trace / n + 1e-300;
  for (int c = 0; c < 3; ++c) {
    std::array<double, kMaxChildren> x{};
    SolveSmall(normal, rhs[size_t(c)], n, &x);
    for (int k = 0; k < n; ++k) fit->children[size_t(k)].dc[size_t(c)] = std::clamp(x[size_t(k)], -0.5, 0.5);
  }
  fit->se = 0;
  for (size_t s = 0; s < p.m; ++s) {
    std::array<double, 3> premultiplied{}, wanted;
    for (int c = 0; c < 3; ++c) {
      for (int k = 0; k < n; ++k)
        premultiplied[size_t(c)] += basis[s * size_t(n) + size_t(k)] * fit->children[size_t(k)].dc[size_t(c)];
      wanted[size_t(c)] = p.target[s] * p.colour[s * 3 + size_t(c)];
    }
    fit->se += LayerError(shown_alpha[s], premultiplied, p.target[s], wanted);
  }
}

// Fits the children of textured Gaussian `i` (opacity `alpha`) as described at the top.
// `d`: the children's offset; `narrow`: their standard deviation along a split axis relative to
// the moment-matching sqrt(1 − d²).
Fit FitChildren(const Profile& p, const TexturePool& t, size_t i, double alpha, int iterations, double d,
                double narrow) {
  Fit fit;
  const int nu = t.widths[i] > 1 ? 2 : 1, nv = t.heights[i] > 1 ? 2 : 1;
  fit.scale_u = nu == 2 ? narrow * std::sqrt(1 - d * d) : 1.0;
  fit.scale_v = nv == 2 ? narrow * std::sqrt(1 - d * d) : 1.0;
  fit.count = nu * nv;
  for (int y = 0; y < nv; ++y) {
    for (int x = 0; x < nu; ++x) {
      Child& c = fit.children[size_t(y * nu + x)];
      c.u = nu == 2 ? (x == 0 ? -d : d) : 0.0;
      c.v = nv == 2 ? (y == 0 ? -d : d) : 0.0;
      // Closed form: the parent's mass share at the texture value of the child's centre.
      const double share = alpha * SampleActivated(t, i, c.u, c.v).factor / (fit.count * fit.scale_u * fit.scale_v);
      c.alpha = std::clamp(share, kMinAlpha, kMaxAlpha);
    }
  }
  const size_t n = size_t(fit.count);
  fit.base.resize(p.m * n);
  for (size_t s = 0; s < p.m; ++s) {
    for (size_t k = 0; k < n; ++k) {
      const double du = (p.u[s] - fit.children[k].u) / fit.scale_u, dv = (p.v[s] - fit.children[k].v) / fit.scale_v;
      fit.base[s * n + k] = std::exp(-0.5 * (du * du + dv * dv));
    }
  }
  FitOpacities(p, iterations, &fit);
  FitColours(p, &fit);
  return fit;
}

Status CheckInputs(const Gaussians& g, const TexturePool& t, const TextureBakeOptions& options) {
  const size_t n = g.size();
  if (options.fit_iterations < 0 || options.fit_iterations > 1000)
    return MakeError(StatusCode::kInvalidArgument, "texture bake: fit_iterations ", options.fit_iterations,
                     " is not in [0, 1000]");
  if (options.grid < 5 || options.grid > 1000)
    return MakeError(StatusCode::kInvalidArgument, "texture bake: grid ", options.grid, " is not in [5, 1000]");
  if (g.positions.size() != 3 * n || g.rotations.size() != 4 * n || g.log_scales.size() != 3 * n ||
      g.sh.size() != n * size_t(g.sh_coeffs()) * 3 || (g.has_time_windows() && g.time_windows.size() != 2 * n))
    return MakeError(StatusCode::kInvalidArgument, "texture bake: the Gaussians' arrays disagree with ", n,
                     " Gaussians");
  ATEX_RETURN_IF_ERROR(ValidateTexturePool(t, n));
  for (size_t i = 0; i < n; ++i) {
    bool finite = std::isfinite(g.opacity_logits[i]);
    for (int k = 0; k < 3; ++k) finite = finite && std::isfinite(g.positions[i * 3 + size_t(k)]);
    for (int k = 0; k < 3; ++k) finite = finite && !std::isnan(g.log_scales[i * 3 + size_t(k)]) &&
                                         g.log_scales[i * 3 + size_t(k)] < 1e30f;
    for (int k = 0; k < 4; ++k) finite = finite && std::isfinite(g.rotations[i * 4 + size_t(k)]);
    if (!finite)
      return MakeError(StatusCode::kOutOfRange, "texture bake: element ", i,
                       " has a non-finite position, rotation, log-scale or opacity logit");
  }
  for (size_t k = 0; k < t.texels.size(); ++k) {
    if (!std::isfinite(t.texels[k]))
      return MakeError(StatusCode::kOutOfRange, "texture bake: texel value ", k, " (texel ", k / 4,
                       ") is not finite");
  }
  return Status::Ok();
}

// Appends Gaussian `i` of `g` to `out` with its centre moved by `offset`, log-scales raised by
// `log_scale_delta` and the given opacity logit and DC offset.
void AppendChild(const Gaussians& g, size_t i, const std::array<double, 3>& offset,
                 const std::array<double, 3>& log_scale_delta, float logit, const std::array<double, 3>& dc,
                 Gaussians* out) {
  for (int k = 0; k < 3; ++k)
    out->positions.push_back(float(double(g.positions[i * 3 + size_t(k)]) + offset[size_t(k)]));
  for (int k = 0; k < 4; ++k) out->rotations.push_back(g.rotations[i * 4 + size_t(k)]);
  for (int k = 0; k < 3; ++k)
    out->log_scales.push_back(float(double(g.log_scales[i * 3 + size_t(k)]) + log_scale_delta[size_t(k)]));
  out->opacity_logits.push_back(logit);
  const size_t coeffs = size_t(g.sh_coeffs()) * 3;
  for (size_t k = 0; k < coeffs; ++k) {
    double value = g.sh[i * coeffs + k];
    if (k < 3 && dc[k] != 0) value += dc[k] / kShC0;
    out->sh.push_back(float(value));
  }
  if (g.has_time_windows()) {
    out->time_windows.push_back(g.time_windows[i * 2]);
    out->time_windows.push_back(g.time_windows[i * 2 + 1]);
  }
}

}  // namespace

StatusOr<Gaussians> BakeTextures(const Gaussians& g, const TexturePool& t, const TextureBakeOptions& options,
                                 TextureBakeReport* report) {
  ATEX_RETURN_IF_ERROR(CheckInputs(g, t, options));
  TextureBakeReport r;
  r.input_gaussians = g.size();
  double fit_se = 0, unbaked_se = 0;
  size_t samples = 0;
  try {
    Gaussians out;
    out.sh_degree = g.sh_degree;
    const size_t n = g.size();
    for (size_t i = 0; i < n; ++i) {
      const double alpha = Sigmoid(g.opacity_logits[i]);
      const bool split = (t.heights[i] > 1 || t.widths[i] > 1) && !NearlyConstant(t, i);
      if (!split) {
        // 1x1 (or constant): the texel's colour and opacity factor fold in exactly.
        const TexelValue tv = SampleActivated(t, i, 0, 0);
        const float logit = tv.factor == 1.0 ? g.opacity_logits[i]
                                             : float(Logit(std::clamp(alpha * tv.factor, kMinAlpha, kMaxAlpha)));
        AppendChild(g, i, {0, 0, 0}, {0, 0, 0}, logit, tv.colour, &out);
        ++r.folded;
        continue;
      }
      // The children's geometry: the best of a few candidates (offset d, width relative to the
      // moment match) by the fit's error. Overlapping children composite sub-additively
      // (1 − Π(1 − a·b)), so an opaque parent is matched best by children narrower than the
      // moment match; a faint one by the moment match itself. When no candidate beats folding
      // the centre texel into the parent (a texture too faint or too fine for 2 children per
      // axis), the parent is folded (kSplitGain): baking never makes the fit worse than one Gaussian.
      const Profile profile = SampleProfile(t, i, alpha, options.grid);
      Fit fit;
      bool have = false;
      for (double d : {0.35, 0.5, 0.65}) {
        for (double narrow : {0.55, 0.75, 1.0}) {
          Fit candidate = FitChildren(profile, t, i, alpha, options.fit_iterations, d, narrow);
          if (!have || candidate.se < fit.se) fit = std::move(candidate), have = true;
        }
      }
      samples += profile.m;
      unbaked_se += profile.unbaked_se;
      if (!(fit.se < kSplitGain * profile.fold_se)) {
        const TexelValue tv = SampleActivated(t, i, 0, 0);
        AppendChild(g, i, {0, 0, 0}, {0, 0, 0}, float(Logit(std::clamp(alpha * tv.factor, kMinAlpha, kMaxAlpha))),
                    tv.colour, &out);
        ++r.folded;
        ++r.fold_better;
        fit_se += profile.fold_se;
        continue;
      }
      const float* q = &g.rotations[i * 4];
      const double qn =
          std::sqrt(double(q[0]) * q[0] + double(q[1]) * q[1] + double(q[2]) * q[2] + double(q[3]) * q[3]);
      const detail::Mat3<double> rot =
          qn > 0 ? detail::QuaternionToRotation(detail::Vec4<double>{{q[0], q[1], q[2], q[3]}})
                 : detail::Mat3<double>{{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};
      const int p = t.axis_u[i], a = t.axis_v[i];
      const double sp = std::exp(double(g.log_scales[i * 3 + size_t(p)]));
      const double sq = std::exp(double(g.log_scales[i * 3 + size_t(a)]));
      std::array<double, 3> log_delta{0, 0, 0};
      log_delta[size_t(p)] = std::log(fit.scale_u);
      log_delta[size_t(a)] = std::log(fit.scale_v);
      for (int k = 0; k < fit.count; ++k) {
        const Child& c = fit.children[size_t(k)];
        std::array<double, 3> offset;
        for (int row = 0; row < 3; ++row) offset[size_t(row)] = rot(row, p) * c.u * sp + rot(row, a) * c.v * sq;
        AppendChild(g, i, offset, log_delta, float(Logit(c.alpha)), c.dc, &out);
      }
      ++r.split;
      fit_se += fit.se;
    }
    r.output_gaussians = out.size();
    if (samples > 0) {
      r.fit_rms = std::sqrt(fit_se / double(samples));
      r.unbaked_rms = std::sqrt(unbaked_se / double(samples));
    }
    if (report != nullptr) *report = r;
    return out;
  } catch (const std::bad_alloc&) {
    return MakeError(StatusCode::kLimitExceeded, "texture bake: out of memory for ", g.size(), " Gaussians");
  }
}

}  // namespace atex
