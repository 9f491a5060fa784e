// Budget arithmetic (fit.h): the smallest asset a lever set can reach, its size, and the
// refusal of budgets below it.
#include <limits>

#include "atex/fit.h"
#include "levers.h"
#include "plan_state.h"
#include "texture_shrink.h"

namespace atex::fit {

namespace internal {

StatusOr<State> SmallestState(const Asset& asset, const WriteOptions& write, int min_grid_resolution,
                              LeverSet levers) {
  State out = InitialState(asset, write);
  Asset& smallest = out.asset;
  if (HasLever(levers, Lever::kPrune) && asset.gaussians.size() > 1) {
    // Seed 0, not the fit's seed: the size that CheckBudget promises must not depend on it.
    const std::vector<uint32_t> order = ImportanceOrder(asset, 0);
    const double one_gaussian = 1.0 / static_cast<double>(asset.gaussians.size());
    ATEX_ASSIGN_OR_RETURN(smallest, KeepMostImportant(asset, order, one_gaussian, &out.kept));
  }
  if (HasLever(levers, Lever::kShDegree)) {
    while (smallest.gaussians.sh_degree > 0) ATEX_RETURN_IF_ERROR(LowerShDegree(&smallest));
  }
  if (HasLever(levers, Lever::kTextures)) {
    ATEX_RETURN_IF_ERROR(ShrinkTextures(&smallest, std::numeric_limits<uint64_t>::max()).status());
  } else if (HasLever(levers, Lever::kAllTextures)) {  // the same 1×1 pool, its texture_mode kept
    while (smallest.textures && ShrinkableTexels(*smallest.textures) > 0) {
      ATEX_RETURN_IF_ERROR(HalveAllTextures(&smallest));
    }
  }
  if (HasLever(levers, Lever::kGrid)) {
    while (CanCoarsenGrid(smallest, min_grid_resolution)) {
      ATEX_RETURN_IF_ERROR(CoarsenGrid(&smallest, min_grid_resolution));
    }
  }
  if (HasLever(levers, Lever::kEncoding)) {
    for (int s = 0; s < static_cast<int>(Stream::kCount); ++s) {
      SetEncoding(&out.write, static_cast<Stream>(s), ScalarEncoding::kQuant8);
    }
  }
  return out;
}

}  // namespace internal

StatusOr<uint64_t> MinimumBytes(const Asset& asset, const WriteOptions& write, int min_grid_resolution,
                                LeverSet levers) {
  ATEX_ASSIGN_OR_RETURN(internal::State smallest, internal::SmallestState(asset, write, min_grid_resolution, levers));
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, EncodeAsset(smallest.asset, smallest.write));
  return static_cast<uint64_t>(bytes.size());
}

Status CheckBudget(const Asset& asset, const WriteOptions& write, uint64_t budget_bytes, int min_grid_resolution,
                   LeverSet levers) {
  ATEX_ASSIGN_OR_RETURN(uint64_t minimum, MinimumBytes(asset, write, min_grid_resolution, levers));
  if (budget_bytes < minimum) {
    return MakeError(StatusCode::kBudgetTooSmall, "budget of ", budget_bytes,
                     " bytes is below the smallest valid asset that the levers ", LeverSetNames(levers),
                     " can reach from this input, ", minimum,
                     " bytes (prune: one Gaussian; sh: degree 0; textures: 1x1; encoding: every stream q8;"
                     " grid: minimum resolution)");
  }
  return Status::Ok();
}

}  // namespace atex::fit
