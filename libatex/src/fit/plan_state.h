// The fitter's internal state shared by the search (plan.cc), the application of a plan
// (apply_plan.cc) and the refill (refill.cc). Not part of the public API.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <memory>
#include <numeric>
#include <optional>
#include <vector>

#include "atex/fit.h"
#include "texture_shrink.h"

namespace atex::fit::internal {

// Seconds since construction or the previous Lap.
class Stopwatch {
 public:
  double Lap() {
    const auto now = std::chrono::steady_clock::now();
    const double seconds = std::chrono::duration<double>(now - last_).count();
    last_ = now;
    return seconds;
  }

 private:
  std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
};

struct State {
  Asset asset;
  WriteOptions write;
  std::vector<uint32_t> kept;
  // Shared by every state derived from the same InitialState (copies share it).
  std::shared_ptr<TextureShrinkMemo> memo;
  // The residuals of `asset`'s textures, one per texture, when known (null otherwise): set by a
  // texture move, gathered by a prune, shared by moves that leave the textures alone.
  std::shared_ptr<const PoolResiduals> texture_residuals;
};

State InitialState(const Asset& asset, const WriteOptions& write);

// The whole-file encodes of ApplyPlan and its refill (trials and replays), through one chunk
// cache (most of them differ in a few chunks), counted and timed for the report; and the time
// spent building the states they encode (Built), apart.
class TrialEncoder {
 public:
  // One encode, logged (trials()) as {move, count, bytes}: `move` the index of the move whose
  // count it tries and `count` that count (-1 for an encode that tries no count), bytes -1 when
  // the encode failed.
  StatusOr<std::vector<uint8_t>> operator()(const Asset& asset, const WriteOptions& write, int64_t move = -1,
                                            int64_t count = -1) {
    Stopwatch clock;
    auto bytes = EncodeAsset(asset, write, &cache_);
    seconds_ += clock.Lap();
    ++count_;
    trials_.push_back({move, count, bytes.ok() ? static_cast<int64_t>(bytes->size()) : -1});
    return bytes;
  }
  // Logs a size known without an encode (a move's whole count: the bytes the plan had with it).
  void Note(int64_t move, int64_t count, uint64_t bytes) {
    trials_.push_back({move, count, static_cast<int64_t>(bytes)});
  }
  const std::vector<std::array<int64_t, 3>>& trials() const { return trials_; }
  // Returns build() (a state to encode, or its status), timed into build_seconds().
  template <typename Build>
  auto Built(Build&& build) {
    Stopwatch clock;
    auto state = build();
    build_seconds_ += clock.Lap();
    return state;
  }
  int count() const { return count_; }
  double seconds() const { return seconds_; }
  double build_seconds() const { return build_seconds_; }

 private:
  EncodeCache cache_;
  std::vector<std::array<int64_t, 3>> trials_;
  int count_ = 0;
  double seconds_ = 0;
  double build_seconds_ = 0;
};

// BuildPlan's states after some of its last moves (Plan::tail): `states[i]` is the state after
// moves[0, indices[i]): after all its moves, after all but the last, and before each of its
// last few content moves (no encoding moves; TailContentStates, plan.cc), in increasing index
// order. Valid for ApplyPlan calls given the very asset
// object BuildPlan was given, unchanged, and its write options: ApplyPlan checks the address,
// the Gaussian count and the write options; that the asset was not changed in place between
// the two calls is the caller's part (RunFit passes the same const object to both).
struct PlanTail {
  const Asset* input = nullptr;
  size_t input_gaussians = 0;
  WriteOptions write;
  std::vector<size_t> indices;
  std::vector<std::shared_ptr<const State>> states;

  bool Serves(const Asset& asset, const WriteOptions& w) const {
    return &asset == input && asset.gaussians.size() == input_gaussians && w == write;
  }
  // The state after moves[0, index), or null when not kept.
  const State* After(size_t index) const {
    for (size_t i = 0; i < indices.size(); ++i)
      if (indices[i] == index) return states[i].get();
    return nullptr;
  }
};

// The smallest asset `levers` reach from `asset` (MinimumBytes encodes it): its encodings and
// the input index of each Gaussian kept. ApplyPlan falls back to it below the plan's end.
StatusOr<State> SmallestState(const Asset& asset, const WriteOptions& write, int min_grid_resolution, LeverSet levers);

// A copy of `state` whose arrays are copied on several threads (CopyAsset): a Panoptic state
// is 150 MB.
State CopyState(const State& state);

// The state after `move` applied to `from` (ApplyMove), without copying first what the move
// replaces: a prune gathers the Gaussians it keeps from `from` directly, and a texture move
// builds its pool from `from`'s.
StatusOr<State> AppliedTo(const State& from, const Move& move, const std::vector<uint32_t>& prune_order,
                          int min_grid_resolution);

// `move` applied to `state` in place (ApplyMove); a move that changes textures forgets their
// residuals.
Status ApplyInPlace(const Move& move, const std::vector<uint32_t>& prune_order, int min_grid_resolution, State* state);

// The state after moves[begin, end) applied to `start`; moves[k] (if in range) with its count
// replaced by `count_k` (0: skipped). The first move applied reads `start` (AppliedTo).
StatusOr<State> ApplyRange(const State& start, const Plan& plan, const std::vector<Move>& moves, size_t begin,
                           size_t end, size_t k, uint64_t count_k);

// After an indivisible last move: gives the slack below the budget back by undoing the moves
// before it, latest first (the plan took moves cheapest first, so the latest ones did the
// most damage per byte). A divisible move's count is lowered to the smallest that still
// fits; when even count 0 fits (the move is undone entirely and slack remains), the move is
// dropped and the next earlier move is tried; when it is needed whole, or only partly undone,
// the budget binds there and the refill stops. An indivisible move (an encoding, the SH
// degree, the grid) is undone whole when the output without it still fits and grows, else
// skipped. Every state taken was encoded and fits, so the output stays within the budget.
// `checkpoint`, when given, is the state after moves[0, checkpoint_index), replayed once by
// the caller, and `tail` (may be null) the plan's kept states when `moves` start with the
// plan's own: the refill builds the states it needs from the latest of them before the move it
// tries instead of from the input.
Status RefillSlack(const Asset& asset, const Plan& plan, const WriteOptions& write, uint64_t budget,
                   std::vector<Move>* moves, State* state, std::vector<uint8_t>* bytes, TrialEncoder* encode,
                   std::optional<State> checkpoint = std::nullopt, size_t checkpoint_index = 0,
                   const PlanTail* tail = nullptr);

// The index of the first move RefillSlack replays from a prefix when moves[0, end) come before
// an indivisible last move: the latest one that is no encoding move (those are undone without
// a replay). `end` when there is none.
size_t FirstRefillPrefix(const std::vector<Move>& moves, size_t end);

}  // namespace atex::fit::internal
