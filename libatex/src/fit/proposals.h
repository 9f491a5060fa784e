// The plan's proposals (plan.cc): each lever's next move at a state, the divisible levers'
// growing step sizes, and a proposal's identity across states. Not part of the public API.
#pragma once

#include <optional>
#include <tuple>
#include <vector>

#include "atex/fit.h"
#include "plan_state.h"

namespace atex::fit::internal {

// Step multipliers of the divisible levers (PlanOptions::step_growth): 1 until a lever wins
// twice in a row.
struct StepScale {
  double prune = 1, textures = 1;
  std::optional<Lever> last;  // the lever of the last move taken

  // A divisible lever that wins again takes a larger step next time; any other move resets.
  void Taken(Lever lever, double growth);
};

// The next move of every lever at a state of `asset` written with `write` (prune and texture
// counts sized to the state and the lever's step scale), in a fixed order.
std::vector<Move> Proposals(const Asset& asset, const WriteOptions& write, const PlanOptions& options,
                            const StepScale& scale);

// Identity of a proposal across states (counts change with the state, the kind does not).
using MoveKey = std::tuple<int, int, int>;
MoveKey KeyOf(const Move& move);

// What the plan proposes for `taken`'s lever once `taken` is taken (for an encoding move: its
// stream's next encoding), at the state after it (`asset` written with `write`), with `scale`
// the step scale before `taken`. Nothing when the lever has no move left there.
std::optional<Move> NextStepAfter(const Asset& asset, const WriteOptions& write, const Move& taken,
                                  const PlanOptions& options, StepScale scale);

}  // namespace atex::fit::internal
