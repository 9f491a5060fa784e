// The conversions between assets, model states and render requests, the scene extent, and the
// ModelState helpers of the Backend contract (atex/train/backend.h: group names, zeroed moments).
#include <algorithm>
#include <cmath>

#include "atex/deform.h"
#include "atex/train/backend.h"
#include "atex/train/trainer.h"
#include "trained_asset.h"

namespace atex::train {

const char* ParamGroupName(int group) {
  static const char* kNames[kParamGroupCount] = {"positions", "rotations", "log_scales", "opacity", "sh_dc",
                                                 "sh_rest",   "texels",    "grid",       "mlp"};
  return group >= 0 && group < kParamGroupCount ? kNames[group] : "unknown";
}

void ResetMoments(ModelState* state) {
  state->m_gaussians = Gaussians();
  state->v_gaussians = Gaussians();
  state->m_texels.clear();
  state->v_texels.clear();
  state->m_deformation.reset();
  state->v_deformation.reset();
  FillMissingMoments(state);
  state->adam_steps.fill(0);
}

double CameraExtent(const std::vector<View>& views) {
  if (views.empty()) return 1.0;
  std::array<double, 3> mean{0, 0, 0};
  for (const View& v : views) {
    const auto c = v.camera.Center();
    for (int k = 0; k < 3; ++k) mean[k] += c[k] / views.size();
  }
  double radius = 0;
  for (const View& v : views) {
    const auto c = v.camera.Center();
    radius = std::max(radius, std::hypot(c[0] - mean[0], c[1] - mean[1], c[2] - mean[2]));
  }
  return radius > 0 ? 1.1 * radius : 1.0;
}

void FillMissingMoments(ModelState* state) {
  const Gaussians& g = state->gaussians;
  const size_t n = g.size();
  if (state->m_gaussians.size() != n || state->v_gaussians.size() != n ||
      state->m_gaussians.sh.size() != g.sh.size() || state->v_gaussians.sh.size() != g.sh.size()) {
    for (Gaussians* m : {&state->m_gaussians, &state->v_gaussians}) {
      *m = Gaussians();
      m->sh_degree = g.sh_degree;
      m->Resize(n);
    }
  }
  const size_t texels = state->textures ? state->textures->texels.size() : 0;
  if (state->m_texels.size() != texels || state->v_texels.size() != texels) {
    state->m_texels.assign(texels, 0.0f);
    state->v_texels.assign(texels, 0.0f);
  }
  if (!state->deformation) {
    state->m_deformation.reset();
    state->v_deformation.reset();
  } else if (!state->m_deformation || !state->v_deformation) {
    state->m_deformation = ZerosLike(*state->deformation);
    state->v_deformation = ZerosLike(*state->deformation);
  }
}

ModelState RenderStateFromAsset(const Asset& asset) {
  ModelState state;
  state.gaussians = asset.gaussians;
  state.textures = asset.textures;
  state.deformation = asset.deformation;
  return state;
}

ModelState StateFromAsset(const Asset& asset) {
  ModelState state = RenderStateFromAsset(asset);
  ResetMoments(&state);
  return state;
}

Asset AssetFromState(const ModelState& state, const Metadata& metadata) {
  Asset asset;
  asset.gaussians = state.gaussians;
  asset.textures = state.textures;
  asset.deformation = state.deformation;
  asset.metadata = metadata;
  return asset;
}

RenderRequest RenderRequestFor(const Asset& asset) {
  RenderRequest r;
  r.active_sh_degree = asset.gaussians.sh_degree;
  r.apply_deformation = asset.deformation.has_value();
  r.use_textures = asset.textures.has_value();
  r.background = asset.metadata.background;
  return r;
}

std::pair<std::array<float, 3>, std::array<float, 3>> PositionBounds(const Gaussians& gaussians) {
  std::array<float, 3> lo{1e30f, 1e30f, 1e30f}, hi{-1e30f, -1e30f, -1e30f};
  for (size_t i = 0; i < gaussians.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], gaussians.positions[3 * i + k]);
      hi[k] = std::max(hi[k], gaussians.positions[3 * i + k]);
    }
  }
  return {lo, hi};
}

GaussianStats FitterStats(const TrainingStats& stats, size_t count, bool textured, const GrowthAblations& ablations) {
  GaussianStats gs;
  gs.importance = stats.importance;
  gs.importance.resize(count, 0.0f);
  if (textured && stats.texture.bins > 0 && stats.texture.demand_sum.size() == count * stats.texture.bins) {
    const GrowthEvidence e = ComputeGrowthEvidence(stats.texture, ablations);
    gs.texture_demand = e.score;
    gs.peak_scale_u = e.scale_u;
    gs.peak_scale_v = e.scale_v;
  } else {
    gs.texture_demand.assign(count, 0.0f);
    gs.peak_scale_u.assign(count, 0.0f);
    gs.peak_scale_v.assign(count, 0.0f);
  }
  return gs;
}

}  // namespace atex::train
