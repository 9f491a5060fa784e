// Giving slack below the budget back after an indivisible last move (ApplyPlan, fit.h).
#include <memory>
#include <optional>

#include "atex/fit.h"
#include "count_search.h"
#include "plan_state.h"

namespace atex::fit::internal {
namespace {

// A replayed state that fits the budget: the count it gives the bisected move, the state and
// its encoded bytes.
struct Refill {
  uint64_t count = 0;
  State state;
  std::vector<uint8_t> bytes;
};

// The states after moves[0, k) for the descending k of RefillSlack, each built from the
// latest state kept before k: one of the plan's (Plan::tail: the states before its last
// content moves), the caller's checkpoint, or one of its own taken up to kStride moves
// earlier. Replaying a whole plan of 78 moves on a 140 MB asset takes ~13 s (0.17 s per move
// applied, measured on the Panoptic uniform fit), and the refill needs one prefix per move it
// tries. A kept state stays valid while the moves before it stay as they are (RefillSlack
// only changes or removes the move it tries, at or after the index it asks for).
class PrefixStates {
 public:
  // `checkpoint`, when given, is the state after moves[0, checkpoint_index); `tail` (may be
  // null) holds the plan's states, for a refill of the plan's own moves.
  PrefixStates(const Asset& asset, const WriteOptions& write, const Plan& plan, std::shared_ptr<TextureShrinkMemo> memo,
               std::optional<State> checkpoint, size_t checkpoint_index, const PlanTail* tail)
      : asset_(asset),
        write_(write),
        plan_(plan),
        memo_(std::move(memo)),
        checkpoint_(std::move(checkpoint)),
        checkpoint_index_(checkpoint_index),
        tail_(tail) {}

  // Before() timed as a state build of `encode` (the report's refill_state_seconds).
  StatusOr<State> Before(const std::vector<Move>& moves, size_t k, TrialEncoder* encode) {
    return encode->Built([&] { return Before(moves, k); });
  }

 private:
  StatusOr<State> Before(const std::vector<Move>& moves, size_t k) {
    const State* from = nullptr;
    size_t from_index = 0;
    for (size_t i = 0; tail_ != nullptr && i < tail_->indices.size(); ++i) {
      if (tail_->indices[i] <= k && (from == nullptr || tail_->indices[i] > from_index)) {
        from = tail_->states[i].get();
        from_index = tail_->indices[i];
      }
    }
    if (checkpoint_ && checkpoint_index_ <= k && (from == nullptr || checkpoint_index_ > from_index)) {
      from = &*checkpoint_;
      from_index = checkpoint_index_;
    }
    if (from == nullptr) {  // from the input, to a checkpoint the next (smaller) k can start from
      const size_t index = k > kStride ? k - kStride : 0;
      State start = InitialState(asset_, write_);
      start.memo = memo_;  // the textures of every replay are mostly the same
      ATEX_ASSIGN_OR_RETURN(State at, ApplyRange(start, plan_, moves, 0, index, moves.size(), 0));
      checkpoint_ = std::move(at);
      checkpoint_index_ = index;
      from = &*checkpoint_;
      from_index = index;
    }
    return ApplyRange(*from, plan_, moves, from_index, k, moves.size(), 0);
  }

  static constexpr size_t kStride = 8;
  const Asset& asset_;
  const WriteOptions& write_;
  const Plan& plan_;
  const std::shared_ptr<TextureShrinkMemo> memo_;
  std::optional<State> checkpoint_;
  size_t checkpoint_index_ = 0;
  const PlanTail* tail_;
};

// The smallest count of moves[k] (the other moves as they are) whose output fits `budget`:
// 0 if that fits, else searched on [1, count) (count_search.h); `full_bytes` is the size with
// the whole count, known to fit. nullopt when no smaller count fits (the whole move is
// needed). `prefix` is the state after moves[0, k), applied once, not once per trial: a
// texture move on a large asset takes most of a second to apply.
StatusOr<std::optional<Refill>> SmallestFittingRefill(const State& prefix, const Plan& plan,
                                                      const std::vector<Move>& moves, size_t k, uint64_t budget,
                                                      uint64_t full_bytes, TrialEncoder* encode) {
  encode->Note(static_cast<int64_t>(k), static_cast<int64_t>(moves[k].count), full_bytes);
  // With a large slack the move is usually undone entirely: one trial instead of a search.
  ATEX_ASSIGN_OR_RETURN(State without,
                        encode->Built([&] { return ApplyRange(prefix, plan, moves, k, moves.size(), k, 0); }));
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> without_bytes,
                        (*encode)(without.asset, without.write, static_cast<int64_t>(k), 0));
  if (without_bytes.size() <= budget) {
    return std::optional<Refill>(Refill{0, std::move(without), std::move(without_bytes)});
  }
  std::optional<Refill> best;  // the last fitting trial: the smallest count found to fit so far
  const auto bytes_at = [&](uint64_t count) -> StatusOr<uint64_t> {
    ATEX_ASSIGN_OR_RETURN(State trial,
                          encode->Built([&] { return ApplyRange(prefix, plan, moves, k, moves.size(), k, count); }));
    ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> trial_bytes,
                          (*encode)(trial.asset, trial.write, static_cast<int64_t>(k), static_cast<int64_t>(count)));
    const uint64_t size = trial_bytes.size();
    if (size <= budget) best = Refill{count, std::move(trial), std::move(trial_bytes)};
    return size;
  };
  ATEX_ASSIGN_OR_RETURN(const uint64_t count, SmallestFittingCount(0, without_bytes.size(), moves[k].count, full_bytes,
                                                                   budget, bytes_at, nullptr, EnoughSlack(budget)));
  if (count == moves[k].count) return std::optional<Refill>();
  return best;
}

// Undoes the encoding move moves[k] when the output without it fits the budget and grows:
// returns whether it did (then `state` and `bytes` are the output's). Encoding moves change
// only the write options (ApplyMove), so the output without moves[k] is the current asset
// with moves[k]'s stream back at the encoding it had before moves[k]: no replay, and one
// stream encoded (the others come from the cache). When a later move sets the same stream,
// undoing moves[k] changes nothing.
//
// A file's size is the sum of its chunks', and moves[k] changed one stream's chunk. While the
// asset's content is what it was when moves[k] was measured (`same_content`: no move after it
// and no change of the refill touched anything but encodings), undoing it adds back what it
// saved, `saved` bytes. A trial predicted over the budget by more than a margin is skipped.
StatusOr<bool> UndoEncoding(const WriteOptions& write, const std::vector<Move>& moves, size_t k, uint64_t budget,
                            bool same_content, uint64_t saved, State* state, std::vector<uint8_t>* bytes,
                            TrialEncoder* encode) {
  const Move& undone = moves[k];
  for (size_t i = k + 1; i < moves.size(); ++i) {
    if (moves[i].lever == Lever::kEncoding && moves[i].stream == undone.stream) return false;
  }
  // The margin covers what a chunk's size may not add exactly (none known): 1 % of the budget.
  if (same_content && bytes->size() + saved > budget + budget / 100) return false;
  ScalarEncoding before = GetEncoding(write, undone.stream);
  for (size_t i = 0; i < k; ++i) {
    if (moves[i].lever == Lever::kEncoding && moves[i].stream == undone.stream) before = moves[i].encoding;
  }
  WriteOptions without = state->write;
  SetEncoding(&without, undone.stream, before);
  auto trial_bytes = (*encode)(state->asset, without);
  // A stream the earlier encoding cannot hold is not an undo.
  if (!trial_bytes.ok() || trial_bytes->size() > budget || trial_bytes->size() <= bytes->size()) return false;
  state->write = without;
  *bytes = std::move(*trial_bytes);
  return true;
}

}  // namespace

size_t FirstRefillPrefix(const std::vector<Move>& moves, size_t end) {
  for (size_t k = end; k-- > 0;) {
    if (moves[k].lever != Lever::kEncoding) return k;
  }
  return end;
}

// After an indivisible last move: gives the slack below the budget back by undoing the moves
// before it, latest first (the plan took moves cheapest first, so the latest ones did the
// most damage per byte). A divisible move's count is lowered to the smallest that still
// fits; when even count 0 fits (the move is undone entirely and slack remains), the move is
// dropped and the next earlier move is tried; when it is needed whole, or only partly undone,
// the budget binds there and the refill stops. An indivisible move (an encoding, the SH
// degree, the grid) is undone whole when the output without it still fits and grows, else
// skipped. Every state taken was encoded and fits, so the output stays within the budget.
// The refill stops, and its count searches end, once fewer than EnoughSlack(budget) bytes
// are left unused (count_search.h).
Status RefillSlack(const Asset& asset, const Plan& plan, const WriteOptions& write, uint64_t budget,
                   std::vector<Move>* moves, State* state, std::vector<uint8_t>* bytes, TrialEncoder* encode,
                   std::optional<State> checkpoint, size_t checkpoint_index, const PlanTail* tail) {
  std::optional<size_t> earliest_changed;  // index (after any removals) of the earliest move changed
  PrefixStates prefixes(asset, write, plan, state->memo, std::move(checkpoint), checkpoint_index, tail);
  // The latest prefix built (the state after moves[0, prefix_index)), kept for the replay at
  // the end: the refill only changes moves at or after the index it tries.
  std::optional<State> prefix;
  size_t prefix_index = 0;
  // No move after the one tried is a content move (every one of them was tried before it,
  // and one that is no encoding move stays, or was changed: either way the content differs).
  bool same_content = moves->back().lever == Lever::kEncoding;
  for (size_t k = moves->size() - 1; k-- > 0;) {  // every move before the last, latest first
    if (budget - bytes->size() < EnoughSlack(budget)) break;  // spent as far as it is worth
    if ((*moves)[k].lever == Lever::kEncoding) {
      const uint64_t before = k == 0 ? plan.initial_bytes : (*moves)[k - 1].bytes_after;
      const uint64_t saved = before > (*moves)[k].bytes_after ? before - (*moves)[k].bytes_after : 0;
      ATEX_ASSIGN_OR_RETURN(const bool undone,
                            UndoEncoding(write, *moves, k, budget, same_content, saved, state, bytes, encode));
      if (undone) {
        moves->erase(moves->begin() + static_cast<std::ptrdiff_t>(k));
        earliest_changed = k;
      }
      continue;
    }
    same_content = false;
    ATEX_ASSIGN_OR_RETURN(prefix, prefixes.Before(*moves, k, encode));
    prefix_index = k;
    if (!(*moves)[k].divisible()) {
      auto trial = encode->Built([&] { return ApplyRange(*prefix, plan, *moves, k, moves->size(), k, 0); });
      if (!trial.ok()) continue;  // the moves after it do not apply without it: keep it
      auto trial_bytes = (*encode)(trial->asset, trial->write);
      if (!trial_bytes.ok() || trial_bytes->size() > budget || trial_bytes->size() <= bytes->size()) continue;
      *state = std::move(*trial);
      *bytes = std::move(*trial_bytes);
      moves->erase(moves->begin() + static_cast<std::ptrdiff_t>(k));
      earliest_changed = k;
      continue;
    }
    ATEX_ASSIGN_OR_RETURN(std::optional<Refill> refill,
                          SmallestFittingRefill(*prefix, plan, *moves, k, budget, bytes->size(), encode));
    if (!refill) break;  // move k is needed whole: the budget binds here
    *state = std::move(refill->state);
    *bytes = std::move(refill->bytes);
    earliest_changed = k;
    if (refill->count > 0) {
      (*moves)[k].count = refill->count;
      break;  // partly undone: the budget binds here
    }
    // Undone entirely and still under budget: drop it and spend the rest on an earlier move.
    moves->erase(moves->begin() + static_cast<std::ptrdiff_t>(k));
  }
  if (!earliest_changed) return Status::Ok();
  // The sizes recorded for the earliest changed move and later ones belong to the plan; measure
  // the real ones. (Their distortion stays the plan's estimate: ApplyPlan does not render.)
  // From the last checkpoint, not the input: every move before the earliest changed one is as
  // it was when the checkpoint was taken.
  // The last move (never changed here) ends at the output, whose size is known.
  State replay;
  if (prefix && prefix_index == *earliest_changed) {
    replay = std::move(*prefix);
  } else {
    ATEX_ASSIGN_OR_RETURN(replay, prefixes.Before(*moves, *earliest_changed, encode));
  }
  for (size_t i = *earliest_changed; i + 1 < moves->size(); ++i) {
    ATEX_RETURN_IF_ERROR(
        encode->Built([&] { return ApplyInPlace((*moves)[i], plan.prune_order, plan.min_grid_resolution, &replay); }));
    ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> step_bytes, (*encode)(replay.asset, replay.write));
    (*moves)[i].bytes_after = step_bytes.size();
  }
  moves->back().bytes_after = bytes->size();
  return Status::Ok();
}

}  // namespace atex::fit::internal
