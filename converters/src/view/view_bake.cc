// The keyframe bake of `atex view`: deform the kept Gaussians at each keyframe time with
// libatex's CPU deformation, turn colours and opacities into what the page draws (DC
// colour, textures averaged), and quantise (the layout of atex/converters/view.h).
#include "view/view_bake.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "atex/deform.h"
#include "splatv/half.h"

namespace atex::view {
namespace {

constexpr double kShC0 = 0.28209479177387814;

double Sigmoid(double x) { return 1.0 / (1.0 + std::exp(-x)); }

// The Gaussians `kept` of `g` (every SH coefficient, so that a dSH head still applies).
Gaussians Subset(const Gaussians& g, const std::vector<uint32_t>& kept) {
  Gaussians out;
  out.sh_degree = g.sh_degree;
  out.Resize(kept.size());
  const size_t k = size_t(g.sh_coeffs()) * 3;
  for (size_t j = 0; j < kept.size(); ++j) {
    const size_t i = kept[j];
    std::copy_n(&g.positions[i * 3], 3, &out.positions[j * 3]);
    std::copy_n(&g.rotations[i * 4], 4, &out.rotations[j * 4]);
    std::copy_n(&g.log_scales[i * 3], 3, &out.log_scales[j * 3]);
    out.opacity_logits[j] = g.opacity_logits[i];
    std::copy_n(&g.sh[i * k], k, &out.sh[j * k]);
  }
  if (g.has_time_windows()) {
    out.time_windows.resize(kept.size() * 2);
    for (size_t j = 0; j < kept.size(); ++j) std::copy_n(&g.time_windows[kept[j] * 2], 2, &out.time_windows[j * 2]);
  }
  return out;
}

// Per kept Gaussian: the texture's average colour term 0.1 * mean tanh(rgb) and opacity
// factor mean exp(0.1 * tanh(a)) (conventions §5 steps 3 and 5, averaged over the plane).
void TextureAverages(const Asset& asset, const std::vector<uint32_t>& kept, std::vector<float>* colour,
                     std::vector<float>* opacity_factor) {
  colour->assign(kept.size() * 3, 0.0f);
  opacity_factor->assign(kept.size(), 1.0f);
  if (!asset.textures) return;
  const TexturePool& pool = *asset.textures;
  for (size_t j = 0; j < kept.size(); ++j) {
    const size_t i = kept[j];
    const uint64_t first = pool.offsets[i], last = pool.offsets[i + 1];
    if (last == first) continue;
    double sum[4] = {0, 0, 0, 0};
    for (uint64_t t = first; t < last; ++t) {
      const float* texel = &pool.texels[t * kTexelChannels];
      for (int c = 0; c < 3; ++c) sum[c] += 0.1 * std::tanh(double(texel[c]));
      sum[3] += std::exp(0.1 * std::tanh(double(texel[3])));
    }
    const double n = double(last - first);
    for (int c = 0; c < 3; ++c) (*colour)[j * 3 + size_t(c)] = float(sum[c] / n);
    (*opacity_factor)[j] = float(sum[3] / n);
  }
}

uint16_t QuantiseUnorm16(double v, double lo, double hi) {
  const double u = hi > lo ? (v - lo) / (hi - lo) : 0.0;
  return uint16_t(std::lround(std::clamp(u, 0.0, 1.0) * 65535.0));
}

uint8_t QuantiseUnorm8(double u) { return uint8_t(std::lround(std::clamp(u, 0.0, 1.0) * 255.0)); }

}  // namespace

std::vector<uint32_t> KeptGaussians(const Gaussians& g, size_t max_splats) {
  std::vector<uint32_t> kept(g.size());
  std::iota(kept.begin(), kept.end(), 0u);
  if (max_splats == 0 || max_splats >= g.size()) return kept;
  std::vector<double> score(g.size());
  for (size_t i = 0; i < g.size(); ++i) {
    const double log_volume = double(g.log_scales[i * 3]) + g.log_scales[i * 3 + 1] + g.log_scales[i * 3 + 2];
    score[i] = std::log(std::max(Sigmoid(g.opacity_logits[i]), 1e-30)) + log_volume;  // log of the product
  }
  std::stable_sort(kept.begin(), kept.end(), [&](uint32_t a, uint32_t b) { return score[a] > score[b]; });
  kept.resize(max_splats);
  std::sort(kept.begin(), kept.end());
  return kept;
}

Dynamic DynamicArrays(const Asset& asset) {
  Dynamic d;
  if (!asset.deformation) return d;
  const auto& heads = asset.deformation->config.heads;
  d.positions = heads[kHeadPosition];
  d.rotations = heads[kHeadRotation];
  d.scales = heads[kHeadScale];
  // Time-local Gaussians change their opacity with time even without an opacity head.
  d.colours = heads[kHeadOpacity] || heads[kHeadSH] || asset.gaussians.has_time_windows();
  return d;
}

uint64_t PayloadBytes(const Dynamic& d, size_t count, int frames) {
  const uint64_t f = uint64_t(std::max(frames, 1)), n = count;
  auto frames_of = [&](bool dynamic) { return dynamic ? f : 1; };
  return n *
         (6 * frames_of(d.positions) + 4 * frames_of(d.rotations) + 6 * frames_of(d.scales) + 4 * frames_of(d.colours));
}

StatusOr<ViewPayload> BakeKeyframes(const Asset& asset, const std::vector<uint32_t>& kept,
                                    const std::vector<double>& times, const ViewOptions& options,
                                    Gaussians* first_frame) {
  const size_t n = kept.size();
  const int frames = int(times.size());
  const Dynamic dyn = times.size() > 1 ? DynamicArrays(asset) : Dynamic{};
  ViewPayload p;
  p.count = n;
  p.times = times;
  p.position_frames = dyn.positions ? frames : 1;
  p.rotation_frames = dyn.rotations ? frames : 1;
  p.scale_frames = dyn.scales ? frames : 1;
  p.colour_frames = dyn.colours ? frames : 1;
  p.rotations.resize(size_t(p.rotation_frames) * n * 4);
  p.log_scales.resize(size_t(p.scale_frames) * n * 3);
  std::vector<float> colour(size_t(p.colour_frames) * n * 4);  // rgb, opacity before quantisation
  std::vector<float> positions(size_t(p.position_frames) * n * 3);

  std::vector<float> texture_colour, opacity_factor;
  TextureAverages(asset, kept, &texture_colour, &opacity_factor);
  const Gaussians canonical = Subset(asset.gaussians, kept);
  const size_t sh_stride = size_t(canonical.sh_coeffs()) * 3;
  std::vector<float> previous_q(n * 4, 0.0f);  // sign alignment of rotations between keyframes
  Gaussians deformed;
  Asset subset_asset;  // only for a caller's DeformFn, which takes an asset
  if (options.deform && asset.deformation) {
    subset_asset.gaussians = canonical;
    subset_asset.deformation = asset.deformation;
    subset_asset.metadata = asset.metadata;
  }
  for (int k = 0; k < frames; ++k) {
    const Gaussians* g = &canonical;
    if (asset.deformation) {
      if (options.deform) {
        ATEX_RETURN_IF_ERROR(options.deform(subset_asset, times[size_t(k)], &deformed));
      } else {
        ATEX_RETURN_IF_ERROR(DeformForward(*asset.deformation, canonical, times[size_t(k)], &deformed, nullptr));
      }
      if (deformed.size() != n || deformed.sh_coeffs() != canonical.sh_coeffs()) {
        return MakeError(StatusCode::kInternal, "view: the deformation changed the Gaussian count or SH degree");
      }
      g = &deformed;
    }
    if (k == 0 && first_frame) *first_frame = *g;
    const size_t kk = size_t(k);
    if (kk < size_t(p.position_frames)) std::copy(g->positions.begin(), g->positions.end(), &positions[kk * n * 3]);
    if (kk < size_t(p.rotation_frames)) {
      for (size_t i = 0; i < n; ++i) {
        const float* q = &g->rotations[i * 4];
        double norm = std::sqrt(double(q[0]) * q[0] + double(q[1]) * q[1] + double(q[2]) * q[2] + double(q[3]) * q[3]);
        double u[4] = {1, 0, 0, 0};
        if (norm > 1e-12)
          for (int c = 0; c < 4; ++c) u[c] = q[c] / norm;
        float* prev = &previous_q[i * 4];
        const double dot = u[0] * prev[0] + u[1] * prev[1] + u[2] * prev[2] + u[3] * prev[3];
        const double sign = dot < 0 ? -1.0 : 1.0;  // q and -q are one rotation: blend the near pair
        for (int c = 0; c < 4; ++c) {
          prev[c] = float(sign * u[c]);
          p.rotations[(kk * n + i) * 4 + size_t(c)] = int8_t(std::lround(std::clamp(sign * u[c], -1.0, 1.0) * 127.0));
        }
      }
    }
    if (kk < size_t(p.scale_frames)) {
      for (size_t i = 0; i < n * 3; ++i) {
        p.log_scales[kk * n * 3 + i] = splatv::FloatToHalf(std::clamp(g->log_scales[i], -60.0f, 60.0f));
      }
    }
    if (kk < size_t(p.colour_frames)) {
      for (size_t i = 0; i < n; ++i) {
        float* out = &colour[(kk * n + i) * 4];
        for (int c = 0; c < 3; ++c) {
          const double sh = std::max(0.0, 0.5 + kShC0 * g->sh[i * sh_stride + size_t(c)]);  // 3DGS's clamp
          out[c] = float(sh + texture_colour[i * 3 + size_t(c)]);
        }
        out[3] = float(Sigmoid(g->opacity_logits[i]) * opacity_factor[i]);
      }
    }
    if (options.progress && !options.progress(double(k + 1) / frames)) {
      return MakeError(StatusCode::kCancelled, "view: cancelled while baking keyframe ", k);
    }
  }

  // Quantisation ranges over every keyframe.
  for (int c = 0; c < 3; ++c) {
    p.position_lo[size_t(c)] = std::numeric_limits<float>::infinity();
    p.position_hi[size_t(c)] = -std::numeric_limits<float>::infinity();
  }
  for (size_t i = 0; i < positions.size(); ++i) {
    p.position_lo[i % 3] = std::min(p.position_lo[i % 3], positions[i]);
    p.position_hi[i % 3] = std::max(p.position_hi[i % 3], positions[i]);
  }
  for (int c = 0; c < 3; ++c) {
    if (!(p.position_hi[size_t(c)] > p.position_lo[size_t(c)]))
      p.position_hi[size_t(c)] = p.position_lo[size_t(c)] + 1e-6f;
  }
  p.positions.resize(positions.size());
  for (size_t i = 0; i < positions.size(); ++i) {
    p.positions[i] = QuantiseUnorm16(positions[i], p.position_lo[i % 3], p.position_hi[i % 3]);
  }
  float colour_lo = 0, colour_hi = 1, opacity_max = 1;
  for (size_t i = 0; i < colour.size(); ++i) {
    if (i % 4 == 3) {
      opacity_max = std::max(opacity_max, colour[i]);
    } else {
      colour_lo = std::min(colour_lo, colour[i]);
      colour_hi = std::max(colour_hi, colour[i]);
    }
  }
  p.colour_range = {std::max(colour_lo, -1.0f), std::min(colour_hi, 3.0f)};
  p.opacity_scale = opacity_max;
  p.colours.resize(colour.size());
  const double span = double(p.colour_range[1]) - p.colour_range[0];
  for (size_t i = 0; i < colour.size(); ++i) {
    p.colours[i] = i % 4 == 3 ? QuantiseUnorm8(colour[i] / p.opacity_scale)
                              : QuantiseUnorm8((colour[i] - p.colour_range[0]) / span);
  }
  return p;
}

}  // namespace atex::view
