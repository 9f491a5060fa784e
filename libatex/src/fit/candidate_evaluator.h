// The plan's candidate measurements (plan.cc): the lazy greedy's cached costs, one evaluated
// proposal, and the evaluator that prepares proposals on a pool of threads and scores them in
// order. Not part of the public API.
#pragma once

#include <algorithm>
#include <cstdint>
#include <deque>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "atex/fit.h"
#include "measure.h"
#include "plan_state.h"
#include "preparation_pool.h"

namespace atex::fit::internal {

// A proposal's cost per byte saved, measured at the current state (fresh) or an earlier one.
struct Cached {
  double ratio = 0;
  uint64_t saving = 0;
  bool fresh = false;
};
constexpr double kNoGain = std::numeric_limits<double>::infinity();
struct Evaluated {
  Cached cost;
  bool encoded = false;   // the move applied and was encoded (a measurement once scored)
  bool prepared = false;  // false: not a move at this state (cost stays kNoGain)
  // The state after the move (kept only for the best fresh evaluation): `next`, or for an
  // encoding move, which changes only the write options, the state it was prepared at (`base`)
  // with `write`: its asset is copied only when the move is taken (Next).
  std::optional<State> next;
  std::shared_ptr<const State> base;
  WriteOptions write;
  Candidate candidate;    // its measurement and decode

  StateRef Ref() const {
    return next ? StateRef(*next) : StateRef(base->asset, write, base->kept);
  }
  State Next() && {
    if (next) return std::move(*next);
    State s = CopyState(*base);  // on several threads: the plan waits for it
    s.write = write;
    return s;
  }
};
inline bool Better(const Cached& a, const Cached& b) {
  return a.ratio < b.ratio || (a.ratio == b.ratio && a.saving > b.saving);
}

// How many candidates to prepare at once: PlanOptions::parallel_candidates, or for 0 the
// cores (at most 4), fewer when that many copies of the asset would not fit in half the
// machine's memory. Counted as four copies per candidate, an upper bound: the state's copy (none
// for an encoding move), its file, its decode (whose arrays a GPU render state takes over, or
// copies with --quality).
size_t CandidatesAtOnce(const PlanOptions& options, const Asset& asset);

// The bytes of an asset's per-Gaussian arrays and texels in memory (at least 1): what a copy
// of its state costs.
uint64_t AssetArrayBytes(const Asset& asset);

// A preparation handed to the pool: its result is written by the task, read once it finished.
struct Pending {
  std::shared_ptr<PreparationPool::Task> task;
  std::shared_ptr<StatusOr<Evaluated>> result;
};

// Applies proposals to the current state and measures them: prepared (the move applied to a
// copy of the state, encoded and decoded: CPU work that several proposals do at once, on the
// pool's threads), then scored (the probe renders, one at a time, in proposal order: the plan
// does not depend on how many were prepared at once). `state` and `current` are BuildPlan's,
// read at each call; a preparation keeps the state it was submitted at.
//
// Where the measurer allows it (PreparesBesideScores: GPU backends), a proposal is scored as soon
// as its own preparation is done, while the later ones and the speculative ones are prepared,
// and a move is taken without waiting for the speculative preparations it makes useless (they
// are cancelled, or finish unused). Otherwise (the CPU) each wave is prepared whole, then scored,
// and nothing is prepared while a move is taken.
class CandidateEvaluator {
 public:
  CandidateEvaluator(const PlanOptions& options, Plan* plan, Measurer* measurer,
                     const std::shared_ptr<const State>* state, const Measured* current)
      : options_(options), plan_(plan), measurer_(measurer), state_(state), current_(current),
        width_(CandidatesAtOnce(options, (*state)->asset)), beside_(measurer->PreparesBesideScores()),
        pool_(width_ > 1 ? width_ : 0) {}

  // Evaluates `proposals`, at most `width_` prepared at a time, and hands each to `remember` in
  // order. `spare` (proposals likely to be evaluated next at this state) fill the last wave's
  // free places: they are prepared, not scored, and handed to `stash` as pending (errors
  // included) for later.
  template <typename Remember, typename Stash>
  Status EvaluateAll(const std::vector<const Move*>& proposals, const Remember& remember,
                     const std::vector<const Move*>& spare, const Stash& stash) {
    const size_t spares = std::min(spare.size(), (width_ - proposals.size() % width_) % width_);
    size_t next = 0;
    std::deque<Pending> window;  // submitted, not yet scored
    const auto submit = [&] {
      while (next < proposals.size() && window.size() < width_) window.push_back(Submit(*proposals[next++], true));
      if (next == proposals.size()) {
        for (size_t i = 0; i < spares; ++i) stash(*spare[i], Submit(*spare[i], false));
        next = proposals.size() + 1;  // spares submitted
      }
    };
    for (size_t scored = 0; scored < proposals.size(); ++scored) {
      if (window.empty() || beside_) submit();
      if (!beside_ && scored % width_ == 0) Wait([&] { pool_.WaitIdle(); });
      StatusOr<Evaluated> e = Collect(&window.front());
      window.pop_front();
      if (beside_) submit();  // the next proposal is prepared while this one is scored
      if (!e.ok()) return e.status();
      ATEX_RETURN_IF_ERROR(Score(&*e));
      remember(*proposals[scored], std::move(*e));
    }
    return Status::Ok();
  }

  // The result of a pending preparation, prepared on this thread when no worker has started it.
  StatusOr<Evaluated> Collect(Pending* pending);

  // Drops a pending preparation that will not be used.
  void Drop(const Pending& pending);

  // Waits for every preparation; then the timings are complete.
  void Finish();

  // Scores a prepared proposal; it then counts as a measurement.
  Status Score(Evaluated* e);

 private:
  Pending Submit(const Move& proposal, bool urgent);

  // Time this thread spends waiting for preparations or running them: the rest of the summed
  // preparation time ran beside other work (PlanTiming::overlap_seconds).
  template <typename Fn>
  void Wait(const Fn& fn) {
    Stopwatch clock;
    fn();
    std::lock_guard<std::mutex> lock(mutex_);
    waited_ += clock.Lap();
  }

  // Thread-safe: several run at once. An exception becomes the candidate's error.
  StatusOr<Evaluated> Prepare(const std::shared_ptr<const State>& at, const Move& proposal);
  // The move applied to `at` (an encoding move: `at` itself with other write options), then
  // the Measurer's preparation.
  StatusOr<Evaluated> PrepareAt(const std::shared_ptr<const State>& at, const Move& proposal);

  const PlanOptions& options_;
  Plan* plan_;
  Measurer* measurer_;
  const std::shared_ptr<const State>* state_;
  const Measured* current_;
  const size_t width_;
  const bool beside_;      // measurer_->PreparesBesideScores()
  std::mutex mutex_;       // the timing sums written by preparations running at once
  double busy_ = 0;        // summed preparation seconds
  double waited_ = 0;      // seconds BuildPlan's thread spent in Wait
  PreparationPool pool_;   // last: destroyed (its running tasks finished) before the rest
};

}  // namespace atex::fit::internal
