// IncrementalProbes' base (incremental_probes.h): the importance render that starts it,
// and the commits that move it to a rendered candidate.
#include <new>

#include "incremental_probes.h"
#include "incremental_probes_state.h"

namespace atex::fit::internal {

StatusOr<std::vector<float>> IncrementalProbes::RenderImportance(const Asset& asset, std::vector<Image>* images) {
  const size_t n = asset.gaussians.size();
  CandidateMap all;
  all.base_of.assign(n, kNoBase);
  all.changed.resize(n);
  for (size_t j = 0; j < n; ++j) all.changed[j] = static_cast<uint32_t>(j);
  std::shared_ptr<const Pending> pending;
  weigh_ = true;
  StatusOr<std::vector<Image>> renders = Render(asset, all, &pending);
  weigh_ = false;
  if (!renders.ok()) return renders.status();
  std::vector<float> importance(n, 0.0f);
  for (const PendingProbe& pp : pending->probes) {
    for (size_t j = 0; j < n; ++j) importance[j] += pp.importance[j];
  }
  ATEX_RETURN_IF_ERROR(Commit(*pending));
  if (images != nullptr) *images = std::move(*renders);
  return importance;
}

Status IncrementalProbes::Commit(const Pending& pending) {
  if (pending.generation != generation_) {
    return MakeError(StatusCode::kInvalidArgument,
                     "probe render: committing a candidate rendered against an earlier base");
  }
  try {
    CommitUnchecked(pending);
  } catch (const std::bad_alloc&) {
    return MakeError(StatusCode::kLimitExceeded, "fit: probe render: out of memory");
  }
  return Status::Ok();
}

void IncrementalProbes::CommitUnchecked(const Pending& pending) {
  const size_t n = pending.size;
  std::vector<uint32_t> fresh_of(n, kNoBase);
  for (size_t k = 0; k < pending.changed.size(); ++k) fresh_of[pending.changed[k]] = static_cast<uint32_t>(k);
  std::vector<uint32_t> cand_of(base_size_, kNoBase);
  for (size_t j = 0; j < n; ++j)
    if (pending.base_of[j] != kNoBase) cand_of[pending.base_of[j]] = static_cast<uint32_t>(j);
  Texels texels;
  if (pending.settings.textured) {
    const Texels& fresh = pending.changed_texels;
    texels.offset.assign(1, 0);
    for (size_t j = 0; j < n; ++j) {
      const bool f = fresh_of[j] != kNoBase;
      const Texels& from = f ? fresh : texels_;
      const size_t i = f ? fresh_of[j] : pending.base_of[j];
      texels.height.push_back(from.height[i]);
      texels.constant.push_back(from.constant[i]);
      texels.width.push_back(from.width[i]);
      texels.values.insert(texels.values.end(), from.values.begin() + from.offset[i] * 4,
                           from.values.begin() + from.offset[i + 1] * 4);
      texels.offset.push_back(texels.values.size() / 4);
    }
  }
  // The splats move within their arrays when every kept one moves down or stays (a prune,
  // a change of values): candidate j reads base Gaussian base_of[j] >= j, which no earlier
  // candidate has written. Otherwise (new Gaussians before kept ones) into new arrays.
  bool in_place = probes_.size() == pending.probes.size();
  for (size_t j = 0; j < n && in_place; ++j) {
    in_place = pending.base_of[j] == kNoBase ? fresh_of[j] != kNoBase : pending.base_of[j] >= j;
  }
  for (size_t p = 0; p < probes_.size() && in_place; ++p) in_place = probes_[p].splats.size() >= n;
  std::vector<ProbeBase> probes(pending.probes.size());
  for (size_t p = 0; p < probes.size(); ++p) {
    const PendingProbe& pp = pending.probes[p];
    const ProbeBase& old = probes_[p];
    ProbeBase& nb = probes[p];
    if (!in_place) {
      nb.splats.resize(n);
      for (size_t j = 0; j < n; ++j) {
        nb.splats[j] = fresh_of[j] != kNoBase ? pp.fresh[fresh_of[j]] : old.splats[pending.base_of[j]];
      }
    }
    const size_t tiles = size_t(pp.tiles_total);
    nb.tile_ranges.assign(tiles + 1, 0);
    for (size_t i = 0, t = 0; t < tiles; ++t) {
      if (i < pp.tiles.size() && size_t(pp.tiles[i]) == t) {
        nb.tile_list.insert(nb.tile_list.end(), pp.lists.begin() + pp.list_ranges[i],
                            pp.lists.begin() + pp.list_ranges[i + 1]);
        nb.tile_depth.insert(nb.tile_depth.end(), pp.list_depths.begin() + pp.list_ranges[i],
                             pp.list_depths.begin() + pp.list_ranges[i + 1]);
        ++i;
      } else if (!old.tile_ranges.empty()) {
        // An unaffected tile holds only unchanged survivors.
        for (uint64_t e = old.tile_ranges[t]; e < old.tile_ranges[t + 1]; ++e) {
          nb.tile_list.push_back(cand_of[old.tile_list[e]]);
        }
        nb.tile_depth.insert(nb.tile_depth.end(), old.tile_depth.begin() + old.tile_ranges[t],
                             old.tile_depth.begin() + old.tile_ranges[t + 1]);
      }
      nb.tile_ranges[t + 1] = nb.tile_list.size();
    }
    nb.color = pp.color;
    nb.stops = pp.stops;
  }
  // Nothing allocates from here (the resize only shrinks): the base changes whole or not at all.
  for (size_t p = 0; p < probes.size() && in_place; ++p) {
    const PendingProbe& pp = pending.probes[p];
    std::vector<Splat>& splats = probes_[p].splats;
    for (size_t j = 0; j < n; ++j) {
      if (fresh_of[j] != kNoBase) {
        splats[j] = pp.fresh[fresh_of[j]];
      } else if (pending.base_of[j] != j) {
        splats[j] = splats[pending.base_of[j]];
      }
    }
    splats.resize(n);
    probes[p].splats = std::move(splats);
  }
  probes_ = std::move(probes);
  texels_ = std::move(texels);
  base_size_ = n;
  settings_ = std::make_unique<Settings>(pending.settings);
  ++generation_;
}

}  // namespace atex::fit::internal
