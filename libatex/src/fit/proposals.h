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
// twice in a row among the divisible levers.
struct StepScale {
  double prune = 1, textures = 1;
  std::optional<Lever> last;  // the lever of the last divisible move taken (prune or textures)
  // A texture move's estimated saving, at least (PlanOptions::min_texture_step of the bytes the
  // plan sheds): set once, when the plan starts.
  double min_texture_bytes = 0;

  // The scale of a plan with `options` from an input of `input_bytes` (encoded as the plan
  // starts): every multiplier 1, and the texture floor set.
  static StepScale AtStart(const PlanOptions& options, uint64_t input_bytes);
  // A divisible lever that wins again takes a larger step next time; the other divisible
  // lever's move resets both. A move taken once (an encoding, SH degree, grid or all-textures
  // move) leaves the scale as it is: it ends no streak, because it is no step of a lever
  // that could have been taken in smaller pieces.
  void Taken(Lever lever, double growth);
};

// The next move of every lever at a state of `asset` written with `write` (prune and texture
// counts sized to the state and the lever's step scale; a texture count also to
// scale.min_texture_bytes), in a fixed order.
std::vector<Move> Proposals(const Asset& asset, const WriteOptions& write, const PlanOptions& options,
                            const StepScale& scale);

// The texture halvings (texture_shrink.h) that save an estimated `bytes` of `pool` written
// with `texels` (its raw bytes: texels removed × channels × the encoding's bytes, at the
// average halving of the pool); 0 when `bytes` ≤ 0 or nothing can be halved.
uint64_t HalvingsToSave(const TexturePool& pool, ScalarEncoding texels, double bytes);

// Identity of a proposal across states (counts change with the state, the kind does not).
using MoveKey = std::tuple<int, int, int>;
MoveKey KeyOf(const Move& move);

// What the plan proposes for `taken`'s lever once `taken` is taken (for an encoding move: its
// stream's next encoding), at the state after it (`asset` written with `write`), with `scale`
// the step scale before `taken`. Nothing when the lever has no move left there.
std::optional<Move> NextStepAfter(const Asset& asset, const WriteOptions& write, const Move& taken,
                                  const PlanOptions& options, StepScale scale);

}  // namespace atex::fit::internal
