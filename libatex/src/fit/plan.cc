// The fitter's plan: greedy rate–distortion search over the levers (fit.h). Applying a plan
// to a budget is apply_plan.cc.
#include <algorithm>
#include <cmath>
#include <deque>
#include <map>
#include <memory>
#include <optional>

#include "atex/file_io.h"
#include "atex/fit.h"
#include "candidate_evaluator.h"
#include "levers.h"
#include "measure.h"
#include "plan_state.h"
#include "proposals.h"
#include "texture_shrink.h"

namespace atex::fit {

using internal::Better;
using internal::Cached;
using internal::Candidate;
using internal::CandidateEvaluator;
using internal::Evaluated;
using internal::InitialState;
using internal::KeyOf;
using internal::kNoGain;
using internal::Measured;
using internal::Measurer;
using internal::MoveKey;
using internal::Pending;
using internal::PlanTail;
using internal::Proposals;
using internal::State;
using internal::StepScale;
using internal::Stopwatch;

namespace {

// kInvalidArgument for options or probes a plan cannot be built with.
Status CheckPlanInputs(const ProbeRenderer& renderer, const PlanOptions& options) {
  if (!(options.prune_fraction > 0 && options.prune_fraction < 1) ||
      !(options.texture_fraction > 0 && options.texture_fraction <= 1)) {
    return MakeError(StatusCode::kInvalidArgument, "fit: step fractions must be in (0, 1)");
  }
  if (!(options.min_texture_step >= 0 && options.min_texture_step <= 1)) {
    return MakeError(StatusCode::kInvalidArgument, "fit: the smallest texture step ", options.min_texture_step,
                     " is outside [0, 1]");
  }
  if (!(options.step_growth >= 1 && options.step_growth <= 16)) {
    return MakeError(StatusCode::kInvalidArgument, "fit: step growth ", options.step_growth, " outside [1, 16]");
  }
  if (options.parallel_candidates < 0 || options.parallel_candidates > 64) {
    return MakeError(StatusCode::kInvalidArgument, "fit: parallel candidates ", options.parallel_candidates,
                     " outside 0..64");
  }
  if ((options.levers & ~kAllLevers) != 0 || options.levers == 0) {
    return MakeError(StatusCode::kInvalidArgument, "fit: the lever set ", options.levers,
                     " names no lever or an unknown one");
  }
  if (renderer.probes().empty()) {
    return MakeError(StatusCode::kInvalidArgument, "fit: no probe views to measure distortion from");
  }
  return Status::Ok();
}

// The proposals whose cost was measured at an earlier state and may still win, cheapest
// first, less `skip`: the lazy greedy refreshes them in this order.
template <typename Skip>
std::vector<const Move*> StaleByCost(const std::vector<Move>& proposals, const std::map<MoveKey, Cached>& cache,
                                     const Skip& skip) {
  std::vector<const Move*> stale;
  for (const Move& p : proposals) {
    const auto it = cache.find(KeyOf(p));
    if (it != cache.end() && !it->second.fresh && it->second.ratio != kNoGain && !skip(p)) stale.push_back(&p);
  }
  std::stable_sort(stale.begin(), stale.end(),
                   [&](const Move* a, const Move* b) { return Better(cache.at(KeyOf(*a)), cache.at(KeyOf(*b))); });
  return stale;
}

// After `move` is taken every cost is stale, and the taken lever's is forgotten: its next step
// is a different move (a new count, a new encoding).
void ForgetAfter(const Move& move, std::map<MoveKey, Cached>* cache) {
  for (auto& entry : *cache) entry.second.fresh = false;
  cache->erase(KeyOf(move));
  if (move.lever == Lever::kEncoding) {
    // Both 16-bit options of a stream are decided once one is taken.
    for (ScalarEncoding e : {ScalarEncoding::kFloat16, ScalarEncoding::kQuant16, ScalarEncoding::kQuant8}) {
      cache->erase(MoveKey{static_cast<int>(Lever::kEncoding), static_cast<int>(move.stream), static_cast<int>(e)});
    }
  }
}

// Reports the move just taken to PlanOptions::progress, then asks PlanOptions::cancelled:
// kCancelled when it says stop.
Status AfterMove(const PlanOptions& options, const Plan& plan, const Move& move, const Measured& current) {
  if (options.progress) {
    options.progress(FitProgress{static_cast<int>(plan.moves.size()), current.bytes, options.floor_bytes,
                                 StrCat(DescribeMove(move), ": ", current.bytes, " bytes, proxy PSNR ",
                                        current.distortion > 0 ? -10.0 * std::log10(current.distortion) : 99.0)});
  }
  if (options.cancelled && options.cancelled()) {
    return MakeError(StatusCode::kCancelled, "fit: cancelled after move ", plan.moves.size());
  }
  return Status::Ok();
}

// The states Plan::tail keeps, collected while the plan is built (moved in, not copied): the
// state before the last move taken, and those before the last few moves that changed the
// content (no encoding moves). ApplyPlan's refill replays from the latest one at or before the
// move it tries (FirstRefillPrefix, PrefixStates): without them it replays from the input.
class TailKeeper {
 public:
  // Keeps the states before the last `content_states` content moves (at least 1).
  explicit TailKeeper(size_t content_states) : content_states_(std::max<size_t>(content_states, 1)) {}

  // `before` is the state before `move`, the plan's move number `index`.
  void Taken(const Move& move, size_t index, std::shared_ptr<const State> before) {
    before_last_ = std::move(before);
    if (move.lever != Lever::kEncoding) {
      if (before_content_.size() == content_states_) before_content_.erase(before_content_.begin());
      before_content_.emplace_back(index, before_last_);
    }
  }
  // The tail of a plan of `moves` moves built from `asset` with `write`, whose last state is `last`.
  std::shared_ptr<const PlanTail> Finish(const Asset& asset, const WriteOptions& write, size_t moves,
                                         std::shared_ptr<const State> last) {
    auto tail = std::make_shared<PlanTail>();
    tail->input = &asset;
    tail->input_gaussians = asset.gaussians.size();
    tail->write = write;
    for (auto& [index, kept] : before_content_) {
      if (index + 1 == moves) continue;  // before_last_
      tail->indices.push_back(index);
      tail->states.push_back(std::move(kept));
    }
    if (before_last_) {
      tail->indices.push_back(moves - 1);
      tail->states.push_back(std::move(before_last_));
    }
    tail->indices.push_back(moves);
    tail->states.push_back(std::move(last));
    return tail;
  }

 private:
  size_t content_states_;
  std::shared_ptr<const State> before_last_;
  std::deque<std::pair<size_t, std::shared_ptr<const State>>> before_content_;  // (move index, state)
};

// How many states before content moves the tail keeps: a refill usually undoes a few of the
// last content moves, each replayed from the latest kept state before it. Up to eight, fewer
// where they would take more than a sixteenth of the machine's memory (a Panoptic state is
// about 150 MB).
size_t TailContentStates(const Asset& asset) {
  const uint64_t fit = MemoryLimit(UINT64_MAX) / 16 / internal::AssetArrayBytes(asset);
  return static_cast<size_t>(std::clamp<uint64_t>(fit, 2, 8));
}

// Makes the taken evaluation's state the current one (`*state`) and tells the evaluator. An
// encoding move's state is a copy of the state it was prepared at, with its write options.
void MakeCurrent(Evaluated&& taken, std::shared_ptr<const State>* state, CandidateEvaluator* evaluator) {
  const std::shared_ptr<const State> from = taken.next ? nullptr : taken.base;
  const WriteOptions write = taken.write;
  *state = std::move(taken).Next();
  evaluator->Taken(from.get(), from ? &write : nullptr);
}

}  // namespace

StatusOr<Plan> BuildPlan(const Asset& asset, ProbeRenderer* renderer, const PlanOptions& options) {
  ATEX_RETURN_IF_ERROR(CheckPlanInputs(*renderer, options));
  ATEX_RETURN_IF_ERROR(ValidateAsset(asset));
  const ProbeRenderer::CacheCounts before = renderer->cache_counts();
  const double loads_before = renderer->load_seconds();
  Plan plan;
  Stopwatch whole;
  plan.prune_order = ImportanceOrder(asset, options.seed);
  plan.levers = options.levers;
  plan.min_grid_resolution = options.min_grid_resolution;
  // Shared and never changed: preparations still running for an earlier state keep theirs.
  std::shared_ptr<const State> state = std::make_shared<const State>(InitialState(asset, options.write));
  plan.texture_memo = state->memo;
  // Most candidates change one or two chunks of the current state; the others are
  // compressed once, not once per candidate.
  EncodeCache chunks;
  Measurer measurer(renderer, &chunks, &plan.timing, internal::PruneMeasure::kRangeStable,
                    /*keep_decoded=*/static_cast<bool>(options.accept_more));
  // Reference: the untrimmed asset exactly as given (before any re-encoding).
  ATEX_ASSIGN_OR_RETURN(Measured current, measurer.Start(asset, *state));
  plan.initial_bytes = current.bytes;
  plan.initial_distortion = current.distortion;

  // Lazy greedy: each proposal keeps the cost per byte measured at an earlier state
  // (costs change slowly between moves); a stale best is measured again, and a move is
  // taken only when the best cost is a fresh one (measured at the current state).
  std::map<MoveKey, Cached> cache;
  StepScale scale = StepScale::AtStart(options, current.bytes);
  CandidateEvaluator evaluator(options, &plan, &measurer, &state, &current, &scale);
  TailKeeper tail(TailContentStates(asset));
  while (current.bytes > options.floor_bytes) {
    Stopwatch propose_clock;
    const std::vector<Move> proposals = Proposals(state->asset, state->write, options, scale);
    plan.timing.propose_seconds += propose_clock.Lap();
    if (proposals.empty()) break;
    // The best evaluation made at the current state, with its state and decoded asset.
    std::optional<std::pair<MoveKey, Evaluated>> best_fresh;
    const auto remember = [&](const Move& p, Evaluated e) {
      cache[KeyOf(p)] = e.cost;
      if (e.cost.ratio != kNoGain && (!best_fresh || Better(e.cost, best_fresh->second.cost))) {
        best_fresh.emplace(KeyOf(p), std::move(e));
      }
    };
    // The proposals never measured: all of them at the start, then a taken lever's next step.
    std::vector<const Move*> unmeasured;
    for (const Move& p : proposals) {
      if (cache.count(KeyOf(p)) == 0) unmeasured.push_back(&p);
    }
    // Refreshes are serial (each pass below refreshes one), so the stale proposals likely to be
    // refreshed next, cheapest first, are prepared beforehand beside the wave being prepared.
    // A refresh takes its speculative preparation when there is one: made at the same state,
    // it is the one the refresh would make, so the plan does not depend on it. The rest are
    // dropped when a move is taken.
    std::map<MoveKey, Pending> speculative;
    const auto stash = [&](const Move& p, Pending e) {
      ++plan.timing.prepared_ahead;
      speculative.emplace(KeyOf(p), std::move(e));
    };
    const auto spare = [&](const std::vector<const Move*>& wave) {
      return StaleByCost(proposals, cache, [&](const Move& p) {
        return speculative.count(KeyOf(p)) > 0 ||
               std::find(wave.begin(), wave.end(), &p) != wave.end();
      });
    };
    ATEX_RETURN_IF_ERROR(evaluator.EvaluateAll(unmeasured, remember, spare(unmeasured), stash));
    // Each pass either takes a fresh best or refreshes a stale one, so proposals.size() + 1
    // passes always suffice.
    const Move* chosen = nullptr;
    for (size_t pass = 0; pass <= proposals.size() && chosen == nullptr; ++pass) {
      const Move* best = nullptr;
      for (const Move& p : proposals) {
        if (best == nullptr || Better(cache[KeyOf(p)], cache[KeyOf(*best)])) best = &p;
      }
      const Cached& cost = cache[KeyOf(*best)];
      if (cost.ratio == kNoGain) break;
      if (cost.fresh && best_fresh && best_fresh->first == KeyOf(*best)) {
        chosen = best;
        continue;
      }
      const auto ready = speculative.find(KeyOf(*best));
      if (ready == speculative.end()) {
        ATEX_RETURN_IF_ERROR(evaluator.EvaluateAll({best}, remember, spare({best}), stash));
        continue;
      }
      StatusOr<Evaluated> e = evaluator.Collect(&ready->second);
      speculative.erase(ready);
      if (!e.ok()) return e.status();
      ATEX_RETURN_IF_ERROR(evaluator.Score(&*e));
      remember(*best, std::move(*e));
    }
    plan.timing.prepared_unused += static_cast<int>(speculative.size());
    for (const auto& [key, pending] : speculative) evaluator.Drop(pending);
    if (chosen == nullptr) break;  // no lever saves bytes any more
    Evaluated& taken = best_fresh->second;
    ATEX_ASSIGN_OR_RETURN(Measured measured, measurer.Take(taken.Ref(), taken.candidate));
    Move move = *chosen;
    move.bytes_after = measured.bytes;
    move.distortion_after = measured.distortion;
    if (options.accept_more) {
      ATEX_ASSIGN_OR_RETURN(bool more, options.accept_more(taken.candidate.decoded, move));
      if (!more) break;
    }
    tail.Taken(move, plan.moves.size(), std::move(state));
    MakeCurrent(std::move(taken), &state, &evaluator);
    current = measured;
    plan.moves.push_back(move);
    scale.Taken(move.lever, options.step_growth);
    ForgetAfter(move, &cache);
    ATEX_RETURN_IF_ERROR(AfterMove(options, plan, move, current));
  }
  evaluator.Finish();
  plan.tail = tail.Finish(asset, options.write, plan.moves.size(), std::move(state));
  plan.timing.total_seconds = whole.Lap();
  plan.timing.render_load_seconds = renderer->load_seconds() - loads_before;
  const ProbeRenderer::CacheCounts after = renderer->cache_counts();
  plan.timing.probe_cache = {after.deformed - before.deformed, after.deform_reused - before.deform_reused,
                             after.tiles_drawn - before.tiles_drawn, after.tiles_reused - before.tiles_reused};
  return plan;
}

}  // namespace atex::fit
