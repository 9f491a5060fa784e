// Element-wise sums and finiteness checks of the CPU backend's gradient sets (internal to
// libatex/src/train).
#pragma once

#include <cmath>
#include <utility>
#include <vector>

#include "atex/deform.h"
#include "atex/model.h"

namespace atex::train {

inline void AddInto(std::vector<float>* acc, const std::vector<float>& g) {
  for (size_t k = 0; k < g.size(); ++k) (*acc)[k] += g[k];
}

inline void AddInto(Gaussians* acc, const Gaussians& g) {
  AddInto(&acc->positions, g.positions);
  AddInto(&acc->rotations, g.rotations);
  AddInto(&acc->log_scales, g.log_scales);
  AddInto(&acc->opacity_logits, g.opacity_logits);
  AddInto(&acc->sh, g.sh);
}

inline void AddInto(DeformationField* acc, const DeformationField& g) {
  for (size_t s = 0; s < acc->planes.size(); ++s) {
    for (size_t p = 0; p < acc->planes[s].size(); ++p) AddInto(&acc->planes[s][p], g.planes[s][p]);
  }
  for (size_t l = 0; l < acc->trunk.size(); ++l) {
    AddInto(&acc->trunk[l].weight, g.trunk[l].weight);
    AddInto(&acc->trunk[l].bias, g.trunk[l].bias);
  }
  for (size_t h = 0; h < acc->heads.size(); ++h) {
    for (size_t k = 0; k < acc->heads[h].size(); ++k) {
      AddInto(&acc->heads[h][k].weight, g.heads[h][k].weight);
      AddInto(&acc->heads[h][k].bias, g.heads[h][k].bias);
    }
  }
}

// The sum of parts[lo, hi) as a balanced binary tree: (lo..mid) + (mid..hi), mid = lo + n/2.
// With R = 2 ranks holding the two halves of a batch, rank 0's tree plus rank 1's tree is the
// tree of the whole batch, so data-parallel gradients are the single-rank ones bit for bit.
template <typename T>
T TreeSum(std::vector<T>& parts, size_t lo, size_t hi) {
  if (hi - lo == 1) return std::move(parts[lo]);
  const size_t mid = lo + (hi - lo) / 2;
  T sum = TreeSum(parts, lo, mid);
  AddInto(&sum, TreeSum(parts, mid, hi));
  return sum;
}

inline bool AllFinite(const std::vector<float>& v) {
  for (float x : v) {
    if (!std::isfinite(x)) return false;
  }
  return true;
}

inline bool AllFinite(const Gaussians& g) {
  return AllFinite(g.positions) && AllFinite(g.rotations) && AllFinite(g.log_scales) &&
         AllFinite(g.opacity_logits) && AllFinite(g.sh);
}

inline bool AllFinite(const DeformationField& f) {
  for (const auto& scale : f.planes) {
    for (const auto& plane : scale) {
      if (!AllFinite(plane)) return false;
    }
  }
  for (const auto& l : f.trunk) {
    if (!AllFinite(l.weight) || !AllFinite(l.bias)) return false;
  }
  for (const auto& head : f.heads) {
    for (const auto& l : head) {
      if (!AllFinite(l.weight) || !AllFinite(l.bias)) return false;
    }
  }
  return true;
}

}  // namespace atex::train
