#include "atex/train/texture_growth.h"

#include <algorithm>
#include <numeric>

namespace atex::train {

GrowthEvidence ComputeGrowthEvidence(const TextureStats& stats, const GrowthAblations& ablations) {
  GrowthEvidence evidence;
  const int bins = stats.bins;
  const size_t n = bins > 0 ? stats.demand_sum.size() / bins : 0;
  evidence.score.assign(n, 0.0f);
  evidence.scale_u.assign(n, 0.0f);
  evidence.scale_v.assign(n, 0.0f);
  for (size_t i = 0; i < n; ++i) {
    double sum = 0, peak = -1;
    int nonempty = 0, peak_bin = -1;
    for (int b = 0; b < bins; ++b) {
      const size_t k = i * bins + b;
      const float count = stats.visible_count[k];
      if (count <= 0) continue;  // only visible occurrences are evidence
      // Visibility normalisation: the mean demand of the bin; the ablation uses the raw sum.
      const double q = ablations.visibility_normalization ? stats.demand_sum[k] / count : stats.demand_sum[k];
      sum += q;
      ++nonempty;
      if (q > peak) {
        peak = q;
        peak_bin = b;
      }
    }
    if (nonempty == 0) continue;
    const double mean = sum / nonempty;
    evidence.score[i] = static_cast<float>(ablations.temporal_peak ? 0.5 * mean + 0.5 * peak : mean);
    const size_t k = i * bins + peak_bin;
    evidence.scale_u[i] = stats.scale_u_sum[k] / stats.visible_count[k];
    evidence.scale_v[i] = stats.scale_v_sum[k] / stats.visible_count[k];
  }
  return evidence;
}

StatusOr<TextureResize> PlanTextureGrowth(const TexturePool& layout, const GrowthEvidence& evidence,
                                          const Stage2Config& config, uint64_t texel_budget, GrowthReport* report) {
  const size_t n = layout.size();
  if (evidence.score.size() != n) {
    return MakeError(StatusCode::kInvalidArgument, "growth evidence has ", evidence.score.size(), " scores for ", n,
                     " textures");
  }
  TextureResize resize{layout.heights, layout.widths};
  resize.rescale_moments = config.rescale_grown_moments;
  GrowthReport local;
  uint64_t total = 0;
  for (size_t i = 0; i < n; ++i) total += uint64_t{layout.heights[i]} * layout.widths[i];
  local.texels_before = total;
  local.texel_budget = texel_budget;

  std::vector<uint32_t> order;
  for (size_t i = 0; i < n; ++i) {
    const bool full = layout.heights[i] >= kMaxTextureSide && layout.widths[i] >= kMaxTextureSide;
    if (!full && evidence.score[i] > config.growth_threshold) order.push_back(static_cast<uint32_t>(i));
  }
  local.candidates = order.size();
  std::stable_sort(order.begin(), order.end(),
                   [&](uint32_t a, uint32_t b) { return evidence.score[a] > evidence.score[b]; });

  for (uint32_t i : order) {
    const int h = layout.heights[i], w = layout.widths[i];
    const double su = evidence.scale_u[i], sv = evidence.scale_v[i];
    int new_h = 2 * h, new_w = 2 * w;  // isotropic footprint: both axes
    if (config.ablations.anisotropic) {
      if (sv > 0 && su / sv > config.anisotropy_ratio && sv < config.anisotropy_max_scale) {
        new_h = h;  // long along u: more texels along u (the width)
      } else if (su > 0 && sv / su > config.anisotropy_ratio && su < config.anisotropy_max_scale) {
        new_w = w;
      }
    }
    new_h = std::min(new_h, kMaxTextureSide);
    new_w = std::min(new_w, kMaxTextureSide);
    if (new_h == h && new_w == w) continue;  // the proposed axis is already at its cap
    const uint64_t grown_total = total - uint64_t(h) * w + uint64_t(new_h) * new_w;
    if (grown_total > texel_budget) {
      ++local.rejected_budget;
      continue;
    }
    total = grown_total;
    resize.heights[i] = static_cast<uint8_t>(new_h);
    resize.widths[i] = static_cast<uint8_t>(new_w);
    ++local.grown;
    if (new_h != h && new_w != w) {
      ++local.grown_both;
    } else if (new_w != w) {
      ++local.grown_u_only;
    } else {
      ++local.grown_v_only;
    }
  }
  local.texels_after = total;
  if (report) *report = local;
  return resize;
}

}  // namespace atex::train
