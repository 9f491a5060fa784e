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
#include "proposals.h"

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
  // with `write`: its asset is copied only when the move is taken (Next). `next` is shared: the
  // preparation of the lever's next step may read it already (CandidateEvaluator's next steps).
  std::shared_ptr<const State> next;
  std::shared_ptr<const State> base;
  WriteOptions write;
  Candidate candidate;    // its measurement and decode

  StateRef Ref() const {
    return next ? StateRef(*next) : StateRef(base->asset, write, base->kept);
  }
  std::shared_ptr<const State> Next() && {
    if (next) return std::move(next);
    State s = CopyState(*base);  // on several threads: the plan waits for it
    s.write = write;
    return std::make_shared<const State>(std::move(s));
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
//
// Next steps prepared ahead (GPU backends, once the plan has taken its first move): as soon as a
// candidate's state exists, the preparation of its lever's next step at that state starts
// beside it (NextStepAfter, with the step scale the plan will have then). A taken move's lever
// always proposes its next step at once, so when the candidate is taken, the plan's next wave
// asks for that very preparation (the same move at the same state) and takes it instead of
// starting again; the next step of a next step taken that way starts in turn, so a lever that
// keeps winning is prepared a move ahead. A content candidate's state is its own object; an
// encoding candidate's is the state it was prepared at with other write options (the plan copies
// it only when the move is taken, Evaluated::Next), so its next step is prepared at that state
// with those options, and moves to the copy when the move is taken (Taken). They are queued
// before the spares, and like them run on the pool's background threads, at the lowest priority
// (PreparationPool), so they do not slow the preparations the plan waits for; the pool also has
// one worker more for the urgent ones. Those made at another state are cancelled when a move is
// taken. The plan is the same with or without them: a preparation
// depends only on its state's content and its move.
class CandidateEvaluator {
 public:
  // `state`, `current` and `scale` are BuildPlan's, read at each call.
  CandidateEvaluator(const PlanOptions& options, Plan* plan, Measurer* measurer,
                     const std::shared_ptr<const State>* state, const Measured* current, const StepScale* scale);

  // Evaluates `proposals`, at most `width_` prepared at a time (before the first move, one more
  // where the pool keeps a worker for next steps, which are not prepared yet), and hands each to
  // `remember` in order. `spare` (proposals likely to be evaluated next at this state) fill the last wave's
  // free places: they are prepared, not scored, and handed to `stash` as pending (errors
  // included) for later.
  template <typename Remember, typename Stash>
  Status EvaluateAll(const std::vector<const Move*>& proposals, const Remember& remember,
                     const std::vector<const Move*>& spare, const Stash& stash) {
    const size_t spares = std::min(spare.size(), (width_ - proposals.size() % width_) % width_);
    size_t next = 0;
    std::deque<Pending> window;  // submitted, not yet scored
    const auto submit = [&] {
      const size_t at_once = moved_ ? width_ : std::max(width_, pool_.workers());
      while (next < proposals.size() && window.size() < at_once) window.push_back(Submit(*proposals[next++], true));
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

  // A move was taken (`state` is the new one): the next steps prepared at other states are
  // cancelled, and from now on candidates get theirs (where the measurer prepares
  // beside scores and the memory holds them). For an encoding move, `from` is the state it was
  // prepared at and `write` its write options: the new state is a copy of `from` with `write`.
  void Taken(const State* from = nullptr, const WriteOptions* write = nullptr);

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

  // What a preparation knows of the next step after its move: the step scale before its move,
  // whether it may start that next step (the plan submitted or took it) and, once applied, its
  // state. Guarded by next_mutex_.
  struct Line {
    Move move;
    const State* base = nullptr;  // the state it is prepared at (for matching)
    StepScale scale;
    bool spare = false;  // prepared in case a refresh needs it (the plan does not wait for it)
    bool may_follow = false;
    bool followed = false;  // its next step was started, or cannot be
    // Its state, until its next step starts: `after`, written with `after_write` when set (an
    // encoding move: `after` is the state it was prepared at).
    std::shared_ptr<const State> after;
    std::optional<WriteOptions> after_write;
  };
  // A next step being prepared at the state of the candidate before it: `at`, or for an encoding
  // candidate not yet taken `at` with `write`.
  struct NextStep {
    std::shared_ptr<const State> at;
    std::optional<WriteOptions> write;
    Move move;
    Pending pending;
    std::shared_ptr<Line> line;
    bool after_spare = false;  // the next step of a spare
  };

  // Starts the preparation of `proposal` at `at` (with `write` in place of its write options
  // when set); `line` (may be null) gets its state.
  Pending Start(const std::shared_ptr<const State>& at, const Move& proposal, std::shared_ptr<Line> line,
                PreparationPool::Priority priority, std::optional<WriteOptions> write = std::nullopt);
  // The next step prepared at the current state for `proposal`, taken out, or nothing.
  std::optional<Pending> TakeNextStep(const Move& proposal);
  // The preparation of `line`'s next step starts, when it may and its state exists.
  void FollowLocked(const std::shared_ptr<Line>& line);
  // Cancels the next steps not prepared at `at` (all for null).
  void CancelNextStepsLocked(const State* at);

  // Thread-safe: several run at once. An exception becomes the candidate's error.
  StatusOr<Evaluated> Prepare(const std::shared_ptr<const State>& at, const std::optional<WriteOptions>& write,
                              const Move& proposal, const std::shared_ptr<Line>& line);
  // The move applied to `at` (an encoding move: `at` itself with other write options: `write`,
  // when set, or its own, with the move's encoding), then the Measurer's preparation.
  StatusOr<Evaluated> PrepareAt(const std::shared_ptr<const State>& at, const std::optional<WriteOptions>& write,
                                const Move& proposal, const std::shared_ptr<Line>& line);

  const PlanOptions& options_;
  Plan* plan_;
  Measurer* measurer_;
  const std::shared_ptr<const State>* state_;
  const Measured* current_;
  const StepScale* scale_;
  const size_t width_;
  const bool beside_;      // measurer_->PreparesBesideScores()
  // Next steps may be prepared ahead: beside_, and the memory holds their candidates too.
  const bool may_prepare_next_;
  std::mutex mutex_;       // the timing sums written by preparations running at once
  double busy_ = 0;        // summed preparation seconds
  double waited_ = 0;      // seconds BuildPlan's thread spent in Wait
  std::mutex next_mutex_;  // the next steps and their lines
  bool next_steps_on_ = false;  // set by Taken, cleared by Finish
  bool moved_ = false;          // a move was taken (set by Taken; read on the plan's thread only)
  const State* current_at_;     // *state_, as of the last Taken
  std::vector<NextStep> next_steps_;
  int next_steps_started_ = 0, next_steps_used_ = 0;
  PreparationPool pool_;   // last: destroyed (its running tasks finished) before the rest
};

}  // namespace atex::fit::internal
