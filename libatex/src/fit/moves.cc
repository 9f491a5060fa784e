// Applying one move of a plan (fit.h): the prune lever's removal in importance order, and
// the fixed-count protocol (KeepMostImportant). The other levers live in levers.cc and
// texture_shrink.cc.
#include <algorithm>
#include <cmath>

#include "atex/fit.h"
#include "levers.h"
#include "plan_state.h"
#include "texture_shrink.h"

namespace atex::fit {
namespace {

// A prune of move.count Gaussians, least important first (`prune_order`, input indices), from an
// asset of `n` Gaussians whose input indices are `kept`: which of them stay (`keep`, [n]) and
// their input indices (`still`).
Status PruneMask(const Move& move, const std::vector<uint32_t>& prune_order, size_t n,
                 const std::vector<uint32_t>& kept, std::vector<uint8_t>* keep, std::vector<uint32_t>* still) {
  if (kept.size() != n) return MakeError(StatusCode::kInternal, "fit: kept list out of step with the asset");
  if (move.count >= n) {
    return MakeError(StatusCode::kInvalidArgument, "fit: cannot prune ", move.count, " of ", n, " Gaussians");
  }
  keep->assign(n, 1);
  uint64_t removed = 0;
  for (uint32_t input_index : prune_order) {
    if (removed == move.count) break;
    const auto it = std::lower_bound(kept.begin(), kept.end(), input_index);
    if (it == kept.end() || *it != input_index) continue;  // already gone
    const size_t current = static_cast<size_t>(it - kept.begin());
    if ((*keep)[current]) {
      (*keep)[current] = 0;
      ++removed;
    }
  }
  still->clear();
  still->reserve(n - removed);
  for (size_t i = 0; i < n; ++i)
    if ((*keep)[i]) still->push_back(kept[i]);
  return Status::Ok();
}

}  // namespace

Status ApplyMove(const Move& move, const std::vector<uint32_t>& prune_order, Asset* asset, WriteOptions* write,
                 std::vector<uint32_t>* kept, int min_grid_resolution, TextureShrinkMemo* memo) {
  switch (move.lever) {
    case Lever::kPrune: {
      std::vector<uint8_t> keep;
      std::vector<uint32_t> still;
      ATEX_RETURN_IF_ERROR(PruneMask(move, prune_order, asset->gaussians.size(), *kept, &keep, &still));
      *asset = SubsetGaussians(*asset, keep);
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

namespace internal {

State CopyState(const State& state) {
  return State{CopyAsset(state.asset), state.write, state.kept, state.memo, state.texture_residuals};
}

Status ApplyInPlace(const Move& move, const std::vector<uint32_t>& prune_order, int min_grid_resolution, State* state) {
  if (move.lever == Lever::kPrune || move.lever == Lever::kTextures || move.lever == Lever::kAllTextures) {
    state->texture_residuals = nullptr;
  }
  return ApplyMove(move, prune_order, &state->asset, &state->write, &state->kept, min_grid_resolution,
                   state->memo.get());
}

StatusOr<State> AppliedTo(const State& from, const Move& move, const std::vector<uint32_t>& prune_order,
                          int min_grid_resolution) {
  if (move.lever == Lever::kPrune) {
    State next;
    std::vector<uint8_t> keep;
    ATEX_RETURN_IF_ERROR(PruneMask(move, prune_order, from.asset.gaussians.size(), from.kept, &keep, &next.kept));
    next.asset = SubsetGaussians(from.asset, keep);
    next.write = from.write;
    next.memo = from.memo;
    if (const PoolResiduals* r = from.texture_residuals.get()) {  // one texture per Gaussian
      auto kept_residuals = std::make_shared<PoolResiduals>();
      kept_residuals->reserve(next.kept.size());
      for (size_t i = 0; i < keep.size(); ++i)
        if (keep[i]) kept_residuals->push_back((*r)[i]);
      next.texture_residuals = std::move(kept_residuals);
    }
    return next;
  }
  if (move.lever == Lever::kTextures && from.asset.textures) {
    // The shrunk pool is built from `from`'s: a copy of the input pool would be replaced whole.
    State next{CopyAsset(from.asset, /*with_texture_pool=*/false), from.write, from.kept, from.memo, nullptr};
    TexturePool pool;
    auto residuals = std::make_shared<PoolResiduals>();
    ATEX_ASSIGN_OR_RETURN(const uint64_t done, ShrinkTexturePool(from.asset, move.count, from.memo.get(), &pool,
                                                                 from.texture_residuals.get(), residuals.get()));
    next.asset.textures = std::move(pool);
    next.texture_residuals = std::move(residuals);
    MarkTexturesShrunk(&next.asset, done);
    return next;
  }
  State next = CopyState(from);
  ATEX_RETURN_IF_ERROR(ApplyInPlace(move, prune_order, min_grid_resolution, &next));
  return next;
}

}  // namespace internal
}  // namespace atex::fit
