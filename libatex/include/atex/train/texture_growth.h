// AdaTex4D's anisotropic texture growth decision (paper §2, "Visibility-normalized
// dynamic evidence" and "Anisotropic texture growth"), made on the host.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "atex/model.h"
#include "atex/status.h"
#include "atex/train/backend.h"
#include "atex/train/config.h"

namespace atex::train {

// Score g_i and the peak bin's mean in-plane scales for every Gaussian.
struct GrowthEvidence {
  std::vector<float> score;    // [N] g = ½ mean_b q_b + ½ max_b q_b (ablations change this)
  std::vector<float> scale_u;  // [N] mean deformed scale along axis_u in the highest-demand bin (0 if unseen)
  std::vector<float> scale_v;  // [N]
};
GrowthEvidence ComputeGrowthEvidence(const TextureStats& stats, const GrowthAblations& ablations);

struct GrowthReport {
  size_t candidates = 0;         // g above the threshold and not already 4x4
  size_t grown = 0;
  size_t grown_u_only = 0, grown_v_only = 0, grown_both = 0;
  size_t rejected_budget = 0;    // proposals refused because of the texel budget
  uint64_t texels_before = 0, texels_after = 0, texel_budget = 0;
};

// Candidates with g > threshold in descending score (ties: lower index) each propose
// (h, 2w) if s_u/s_v > ratio and s_v < max_scale; (2h, w) if s_v/s_u > ratio and
// s_u < max_scale; else (2h, 2w) (always (2h, 2w) without the anisotropic cue); each
// side capped at 4. A proposal is accepted only if the total texel count stays within
// `texel_budget`; a refused proposal does not stop later, smaller ones. The resize carries
// config.rescale_grown_moments for the backend.
StatusOr<TextureResize> PlanTextureGrowth(const TexturePool& layout, const GrowthEvidence& evidence,
                                          const Stage2Config& config, uint64_t texel_budget, GrowthReport* report);

}  // namespace atex::train
