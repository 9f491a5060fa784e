// Applying a plan to a budget (fit.h): replay, the count search of the last divisible move, and the
// refill (refill.cc) below an indivisible one.
#include <numeric>
#include <optional>

#include "atex/fit.h"
#include "count_search.h"
#include "levers.h"
#include "plan_state.h"

namespace atex::fit {
namespace internal {

// The state after moves[begin, end) applied to `start`; moves[k] (if in range) with its count
// replaced by `count_k` (0: skipped).
StatusOr<State> ApplyRange(const State& start, const Plan& plan, const std::vector<Move>& moves, size_t begin,
                           size_t end, size_t k, uint64_t count_k) {
  std::optional<State> state;  // empty until the first move applied
  for (size_t i = begin; i < end; ++i) {
    Move m = moves[i];
    if (i == k) {
      if (count_k == 0) continue;
      m.count = count_k;
    }
    if (!state) {
      ATEX_ASSIGN_OR_RETURN(state, AppliedTo(start, m, plan.prune_order, plan.min_grid_resolution));
      continue;
    }
    ATEX_RETURN_IF_ERROR(ApplyInPlace(m, plan.prune_order, plan.min_grid_resolution, &*state));
  }
  if (!state) return CopyState(start);
  return std::move(*state);
}

State InitialState(const Asset& asset, const WriteOptions& write) {
  State s{CopyAsset(asset), write, {}, std::make_shared<TextureShrinkMemo>(), nullptr};
  s.kept.resize(asset.gaussians.size());
  std::iota(s.kept.begin(), s.kept.end(), 0u);
  return s;
}

// Fills `out` with the encoded output as a reader gets it (decoded from `bytes`).
Status FinishOutput(std::vector<uint8_t> bytes, State state, Fitted* out) {
  ReadOptions read;
  read.read_stats = false;
  ATEX_ASSIGN_OR_RETURN(out->asset, DecodeAsset(bytes.data(), bytes.size(), read));
  out->bytes = std::move(bytes);
  out->write = std::move(state.write);
  out->kept = std::move(state.kept);
  return Status::Ok();
}

// The greedy plan stopped above the budget (no single move saved bytes any more), but the
// levers' smallest asset may still fit: then it is the output, as CheckBudget promised.
StatusOr<Fitted> SmallestFallback(const Asset& asset, const Plan& plan, const WriteOptions& write,
                                  uint64_t budget_bytes, uint64_t reached) {
  Stopwatch whole;
  ATEX_ASSIGN_OR_RETURN(State smallest, SmallestState(asset, write, plan.min_grid_resolution, plan.levers));
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, EncodeAsset(smallest.asset, smallest.write));
  if (bytes.size() > budget_bytes) {
    return MakeError(StatusCode::kOutOfRange, "the fit plan reaches ", reached,
                     " bytes at best and the smallest asset of the levers ", LeverSetNames(plan.levers), " is ",
                     bytes.size(), " bytes, both above the budget of ", budget_bytes, " bytes");
  }
  Fitted out;
  ATEX_RETURN_IF_ERROR(FinishOutput(std::move(bytes), std::move(smallest), &out));
  out.smallest_fallback = true;
  out.plan_end_bytes = reached;
  out.apply_seconds = whole.Lap();
  return out;
}

}  // namespace internal

using internal::ApplyInPlace;
using internal::CopyState;
using internal::FinishOutput;
using internal::InitialState;
using internal::PlanTail;
using internal::RefillSlack;
using internal::SmallestFallback;
using internal::State;
using internal::Stopwatch;
using internal::TrialEncoder;

StatusOr<Fitted> ApplyPlan(const Asset& asset, const Plan& plan, const WriteOptions& write, uint64_t budget_bytes) {
  Stopwatch whole;
  // The plan's last states, when it was built from this very asset and these write options:
  // then the input's size is the plan's, and the replay starts from a kept state.
  const PlanTail* tail = plan.tail && plan.tail->Serves(asset, write) ? plan.tail.get() : nullptr;
  const auto initial_state = [&] {
    State s = InitialState(asset, write);
    // The plan's own texture residuals: its moves were applied to these textures already.
    if (plan.texture_memo) s.memo = plan.texture_memo;
    return s;
  };
  Fitted out;
  // The searches below encode many states that differ from each other in a few chunks.
  TrialEncoder encoder;
  const auto encode = [&encoder](const State& s) { return encoder(s.asset, s.write); };
  State state;
  std::vector<uint8_t> bytes;
  uint64_t input_bytes = plan.initial_bytes;
  if (tail == nullptr) {
    state = initial_state();
    ATEX_ASSIGN_OR_RETURN(bytes, encode(state));
    input_bytes = bytes.size();
  }
  if (input_bytes <= budget_bytes) {
    if (tail != nullptr) state = initial_state();
  } else {
    size_t j = 0;
    while (j < plan.moves.size() && plan.moves[j].bytes_after > budget_bytes) ++j;
    if (j == plan.moves.size()) {
      const uint64_t reached = plan.moves.empty() ? input_bytes : plan.moves.back().bytes_after;
      return SmallestFallback(asset, plan, write, budget_bytes, reached);
    }
    Move last = plan.moves[j];
    // The refill after an indivisible last move starts from the state before its first prefix
    // move: the plan's kept states (which RefillSlack reads itself) or a copy taken during this
    // replay, not replayed again from the input.
    const size_t checkpoint_index = last.divisible() ? j : internal::FirstRefillPrefix(plan.moves, j);
    std::optional<State> checkpoint;
    const State* kept = tail != nullptr ? tail->After(j) : nullptr;
    if (kept != nullptr) {
      state = CopyState(*kept);
      out.moves.assign(plan.moves.begin(), plan.moves.begin() + static_cast<std::ptrdiff_t>(j));
    } else {
      if (tail != nullptr) state = initial_state();
      for (size_t k = 0; k < j; ++k) {
        if (k == checkpoint_index) checkpoint = CopyState(state);
        ATEX_RETURN_IF_ERROR(ApplyInPlace(plan.moves[k], plan.prune_order, plan.min_grid_resolution, &state));
        out.moves.push_back(plan.moves[k]);
      }
    }
    if (last.divisible() && last.count > 1) {
      // Smallest count that fits: count 0 is the state before the move (above the budget, as
      // every earlier move's size), the full count is known to fit (count_search.h).
      const uint64_t before = j == 0 ? input_bytes : plan.moves[j - 1].bytes_after;
      const auto bytes_at = [&](uint64_t count) -> StatusOr<uint64_t> {
        Move m = last;
        m.count = count;
        ATEX_ASSIGN_OR_RETURN(State trial, AppliedTo(state, m, plan.prune_order, plan.min_grid_resolution));
        ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> trial_bytes, encode(trial));
        return static_cast<uint64_t>(trial_bytes.size());
      };
      const uint64_t whole_count = last.count;
      ATEX_ASSIGN_OR_RETURN(
          last.count, internal::SmallestFittingCount(0, before, last.count, last.bytes_after, budget_bytes, bytes_at,
                                                     nullptr, internal::EnoughSlack(budget_bytes)));
      if (last.count < whole_count) {
        // Not measured at the cut count: interpolated between the plan's measurements (Move).
        const double from = j == 0 ? plan.initial_distortion : plan.moves[j - 1].distortion_after;
        last.distortion_after =
            from + (last.distortion_after - from) * static_cast<double>(last.count) / static_cast<double>(whole_count);
      }
    }
    ATEX_RETURN_IF_ERROR(ApplyInPlace(last, plan.prune_order, plan.min_grid_resolution, &state));
    ATEX_ASSIGN_OR_RETURN(bytes, encode(state));
    last.bytes_after = bytes.size();
    out.moves.push_back(last);
    if (!last.divisible()) {
      // An indivisible last move (an encoding, the SH degree, the grid) can land far below the
      // budget; give the slack back by undoing moves before it, latest first.
      Stopwatch refill_clock;
      const int encodes_before = encoder.count();
      const double encode_seconds_before = encoder.seconds();
      const double build_seconds_before = encoder.build_seconds();
      ATEX_RETURN_IF_ERROR(RefillSlack(asset, plan, write, budget_bytes, &out.moves, &state, &bytes, &encoder,
                                       std::move(checkpoint), checkpoint_index, tail));
      out.refill_seconds = refill_clock.Lap();
      out.refill_encodes = encoder.count() - encodes_before;
      out.refill_encode_seconds = encoder.seconds() - encode_seconds_before;
      out.refill_state_seconds = encoder.build_seconds() - build_seconds_before;
      out.refill_trials.assign(encoder.trials().begin() + encodes_before, encoder.trials().end());
    }
  }
  // The output itself is encoded without the cache, whose hits rest on content fingerprints
  // (EncodeCache): its bytes never depend on them.
  ATEX_ASSIGN_OR_RETURN(bytes, EncodeAsset(state.asset, state.write));
  if (bytes.size() > budget_bytes) {
    // Replaying the plan must reproduce its sizes exactly; anything else is a bug, not a fit.
    return MakeError(StatusCode::kInternal, "fit: replaying the plan gave ", bytes.size(),
                     " bytes, above the budget of ", budget_bytes);
  }
  ATEX_RETURN_IF_ERROR(FinishOutput(std::move(bytes), std::move(state), &out));
  out.trial_encodes = encoder.count();
  out.trial_encode_seconds = encoder.seconds();
  out.apply_seconds = whole.Lap();
  return out;
}

}  // namespace atex::fit
