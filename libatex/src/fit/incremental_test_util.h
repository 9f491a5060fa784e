// For the incremental probe renderer's tests (incremental_probes_test.cc,
// incremental_full_test.cc): a small dynamic asset, its probe cameras and candidate maps.
#pragma once

#include <cstdint>
#include <numeric>
#include <vector>

#include "atex/fit.h"
#include "container/synthetic_asset.h"
#include "fit/incremental_probes.h"

namespace atex::fit::testing {

// Textured (1×1 and larger), SH degree 1, with a deformation field that moves SH too.
inline Asset DynamicAsset(uint64_t seed, size_t n = 700) {
  container::SyntheticAssetOptions o;
  o.seed = seed;
  o.gaussians = n;
  o.sh_degree = 1;
  o.textures = container::SyntheticTextures::kMixed;
  o.sh_head = true;
  return container::MakeSyntheticAsset(o);
}

inline std::vector<Camera> Cameras(const Asset& asset) {
  std::vector<Camera> cameras;
  for (const Probe& p : OrbitProbes(asset, 4, 64, 48)) cameras.push_back(p.camera);
  return cameras;
}

// Every Gaussian new to the base.
inline internal::CandidateMap AllNew(size_t n) {
  internal::CandidateMap m;
  m.base_of.assign(n, internal::kNoBase);
  m.changed.resize(n);
  std::iota(m.changed.begin(), m.changed.end(), 0u);
  return m;
}

// A prune of n Gaussians that drops those with i % modulo == residue: the keep mask, and the kept
// Gaussians' indices in the base (base_index[i], or i when base_index is empty).
struct Prune {
  std::vector<uint8_t> keep;
  std::vector<uint32_t> kept;
};
inline Prune PruneEvery(size_t n, size_t modulo, size_t residue, const std::vector<uint32_t>& base_index = {}) {
  Prune p;
  p.keep.assign(n, 1);
  for (size_t i = 0; i < n; ++i) {
    p.keep[i] = i % modulo != residue;
    if (p.keep[i]) p.kept.push_back(base_index.empty() ? static_cast<uint32_t>(i) : base_index[i]);
  }
  return p;
}

inline std::vector<uint32_t> Iota(size_t n) {
  std::vector<uint32_t> v(n);
  std::iota(v.begin(), v.end(), 0u);
  return v;
}

}  // namespace atex::fit::testing
