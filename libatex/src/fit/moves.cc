// Applying one move of a plan (fit.h): the prune lever's removal in importance order, and
// the fixed-count protocol (KeepMostImportant). The other levers live in levers.cc and
// texture_shrink.cc.
#include <algorithm>
#include <cmath>

#include "atex/fit.h"
#include "levers.h"
#include "texture_shrink.h"

namespace atex::fit {

Status ApplyMove(const Move& move, const std::vector<uint32_t>& prune_order, Asset* asset, WriteOptions* write,
                 std::vector<uint32_t>* kept, int min_grid_resolution, TextureShrinkMemo* memo) {
  switch (move.lever) {
    case Lever::kPrune: {
      const size_t n = asset->gaussians.size();
      if (kept->size() != n) return MakeError(StatusCode::kInternal, "fit: kept list out of step with the asset");
      if (move.count >= n) {
        return MakeError(StatusCode::kInvalidArgument, "fit: cannot prune ", move.count, " of ", n, " Gaussians");
      }
      std::vector<uint8_t> keep(n, 1);
      uint64_t removed = 0;
      for (uint32_t input_index : prune_order) {
        if (removed == move.count) break;
        const auto it = std::lower_bound(kept->begin(), kept->end(), input_index);
        if (it == kept->end() || *it != input_index) continue;  // already gone
        const size_t current = static_cast<size_t>(it - kept->begin());
        if (keep[current]) {
          keep[current] = 0;
          ++removed;
        }
      }
      *asset = SubsetGaussians(*asset, keep);
      std::vector<uint32_t> still;
      still.reserve(n - removed);
      for (size_t i = 0; i < n; ++i)
        if (keep[i]) still.push_back((*kept)[i]);
      *kept = std::move(still);
      return Status::Ok();
    }
    case Lever::kTextures:
      return ShrinkTextures(asset, move.count, memo).status();
    case Lever::kShDegree:
      return LowerShDegree(asset);
    case Lever::kEncoding:
      SetEncoding(write, move.stream, move.encoding);
      return Status::Ok();
    case Lever::kGrid:
      return CoarsenGrid(asset, min_grid_resolution);
    case Lever::kAllTextures:
      return HalveAllTextures(asset);
  }
  return MakeError(StatusCode::kInternal, "fit: unknown lever");
}

StatusOr<Asset> KeepMostImportant(const Asset& asset, const std::vector<uint32_t>& order, double fraction,
                                  std::vector<uint32_t>* kept) {
  const size_t n = asset.gaussians.size();
  if (!(fraction > 0.0 && fraction <= 1.0)) {
    return MakeError(StatusCode::kInvalidArgument, "keep-count fraction ", fraction, " is not in (0, 1]");
  }
  if (order.size() != n) {
    return MakeError(StatusCode::kInvalidArgument, "importance order has ", order.size(), " entries for ", n,
                     " Gaussians (the --order-from asset must have the same Gaussians)");
  }
  std::vector<uint8_t> seen(n, 0);
  for (uint32_t i : order) {
    if (i >= n || seen[i]) return MakeError(StatusCode::kInvalidArgument, "importance order is not a permutation");
    seen[i] = 1;
  }
  const size_t keep_count = std::clamp<size_t>(static_cast<size_t>(std::ceil(fraction * n - 1e-9)), 1, n);
  std::vector<uint8_t> keep(n, 0);
  for (size_t k = n - keep_count; k < n; ++k) keep[order[k]] = 1;  // the most important are last
  if (kept != nullptr) {
    kept->clear();
    for (size_t i = 0; i < n; ++i)
      if (keep[i]) kept->push_back(static_cast<uint32_t>(i));
  }
  return SubsetGaussians(asset, keep);
}

}  // namespace atex::fit
