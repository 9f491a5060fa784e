// The plan's proposals (proposals.h).
#include "proposals.h"

#include <algorithm>
#include <cmath>

#include "container/attribute_stream.h"
#include "levers.h"

namespace atex::fit::internal {

StepScale StepScale::AtStart(const PlanOptions& options, uint64_t input_bytes) {
  StepScale scale;
  if (input_bytes > options.floor_bytes) {
    scale.min_texture_bytes = options.min_texture_step * static_cast<double>(input_bytes - options.floor_bytes);
  }
  return scale;
}

void StepScale::Taken(Lever lever, double growth) {
  // Without this, each encoding move between texture steps reset them to their fraction: on
  // Panoptic uniform models 12-15 of the plans' 20-21 moves were texture steps of 0.5-1 % of the
  // bytes, each a measurement (BENCHMARKS.md, thirtieth session).
  if (lever != Lever::kPrune && lever != Lever::kTextures) return;
  const bool again = last == lever;
  if (!again) prune = textures = 1;
  if (again && lever == Lever::kPrune) prune = std::min(prune * growth, 1e6);
  if (again && lever == Lever::kTextures) textures = std::min(textures * growth, 1e6);
  last = lever;
}

uint64_t HalvingsToSave(const TexturePool& pool, ScalarEncoding texels, double bytes) {
  if (!(bytes > 0)) return 0;
  const auto halvings_of = [](int side) { return side == 4 ? 2 : side == 2 ? 1 : 0; };
  uint64_t halvings = 0, removable = 0;
  for (size_t i = 0; i < pool.size(); ++i) {
    halvings += halvings_of(pool.heights[i]) + halvings_of(pool.widths[i]);
    removable += static_cast<uint64_t>(pool.heights[i]) * pool.widths[i] - 1;
  }
  if (halvings == 0) return 0;
  const double per_halving = static_cast<double>(removable * kTexelChannels * container::EncodingBytes(texels)) /
                             static_cast<double>(halvings);
  return static_cast<uint64_t>(std::min(std::ceil(bytes / per_halving), static_cast<double>(halvings)));
}

std::vector<Move> Proposals(const Asset& a, const WriteOptions& write, const PlanOptions& o, const StepScale& scale) {
  std::vector<Move> moves;
  const size_t n = a.gaussians.size();
  const auto allowed = [&](Lever lever) { return HasLever(o.levers, lever); };
  if (allowed(Lever::kPrune) && n > 1) {
    Move m;
    m.lever = Lever::kPrune;
    const double fraction = std::min(o.prune_fraction * scale.prune, std::max(o.prune_fraction, 0.5));
    m.count = std::clamp<uint64_t>(static_cast<uint64_t>(fraction * static_cast<double>(n)), 1, n - 1);
    moves.push_back(m);
  }
  if (allowed(Lever::kAllTextures) && a.textures && ShrinkableTexels(*a.textures) > 0) {
    Move m;
    m.lever = Lever::kAllTextures;
    moves.push_back(m);
  }
  if (allowed(Lever::kTextures) && a.textures && ShrinkableTexels(*a.textures) > 0) {
    uint64_t growable = 0;
    for (size_t i = 0; i < a.textures->size(); ++i) growable += a.textures->heights[i] * a.textures->widths[i] > 1;
    Move m;
    m.lever = Lever::kTextures;
    const double fraction = std::min(o.texture_fraction * scale.textures, 1.0);
    m.count =
        std::max<uint64_t>({1, static_cast<uint64_t>(fraction * static_cast<double>(growable)),
                            HalvingsToSave(*a.textures, GetEncoding(write, Stream::kTexels), scale.min_texture_bytes)});
    moves.push_back(m);
  }
  if (allowed(Lever::kShDegree) && a.gaussians.sh_degree > 0) {
    Move m;
    m.lever = Lever::kShDegree;
    moves.push_back(m);
  }
  for (int s = 0; allowed(Lever::kEncoding) && s < static_cast<int>(Stream::kCount); ++s) {
    const auto stream = static_cast<Stream>(s);
    if (stream == Stream::kShRest && a.gaussians.sh_degree == 0) continue;
    if (stream == Stream::kTexels && !a.textures) continue;
    if (stream == Stream::kDeformationGrids && !a.deformation) continue;
    const ScalarEncoding current = GetEncoding(write, stream);
    std::vector<ScalarEncoding> next;
    if (current == ScalarEncoding::kFloat32) next = {ScalarEncoding::kFloat16, ScalarEncoding::kQuant16};
    if (current == ScalarEncoding::kFloat16 || current == ScalarEncoding::kQuant16) next = {ScalarEncoding::kQuant8};
    for (ScalarEncoding e : next) {
      Move m;
      m.lever = Lever::kEncoding;
      m.stream = stream;
      m.encoding = e;
      moves.push_back(m);
    }
  }
  if (allowed(Lever::kGrid) && CanCoarsenGrid(a, o.min_grid_resolution)) {
    Move m;
    m.lever = Lever::kGrid;
    moves.push_back(m);
  }
  return moves;
}

MoveKey KeyOf(const Move& m) {
  return {static_cast<int>(m.lever), m.lever == Lever::kEncoding ? static_cast<int>(m.stream) : -1,
          m.lever == Lever::kEncoding ? static_cast<int>(m.encoding) : -1};
}

std::optional<Move> NextStepAfter(const Asset& asset, const WriteOptions& write, const Move& taken,
                                  const PlanOptions& options, StepScale scale) {
  scale.Taken(taken.lever, options.step_growth);
  for (const Move& m : Proposals(asset, write, options, scale)) {
    // An encoding move's next step is its stream's next encoding (q8 after f16 or q16).
    const bool same = taken.lever == Lever::kEncoding ? m.lever == Lever::kEncoding && m.stream == taken.stream
                                                      : KeyOf(m) == KeyOf(taken);
    if (same) return m;
  }
  return std::nullopt;
}

}  // namespace atex::fit::internal
