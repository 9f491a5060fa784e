// CandidateEvaluator (candidate_evaluator.h).
#include "candidate_evaluator.h"

#include <algorithm>
#include <new>
#include <thread>

#include "atex/file_io.h"

namespace atex::fit::internal {

uint64_t AssetArrayBytes(const Asset& asset) {
  const Gaussians& g = asset.gaussians;
  uint64_t bytes = sizeof(float) * (g.positions.size() + g.rotations.size() + g.log_scales.size() +
                                    g.opacity_logits.size() + g.sh.size() + g.time_windows.size());
  if (asset.textures) bytes += sizeof(float) * asset.textures->texels.size();
  return std::max<uint64_t>(bytes, 1);
}

size_t CandidatesAtOnce(const PlanOptions& options, const Asset& asset) {
  if (options.parallel_candidates > 0) return static_cast<size_t>(options.parallel_candidates);
  const uint64_t per_candidate = 4 * AssetArrayBytes(asset);
  const uint64_t fit = MemoryLimit(UINT64_MAX) / per_candidate;
  return std::clamp<size_t>(std::min<uint64_t>(fit, std::thread::hardware_concurrency()), 1, 4);
}

namespace {

// Next steps of spares prepared ahead at once, at most: a spare is rarely taken, and each next
// step holds a candidate's copies of the asset. Those of the candidates the plan waits for (one
// or two a move) are not limited.
constexpr size_t kMaxSpareNextSteps = 2;
// Candidates that the next steps may hold at once, counted for memory: those of spares, and
// about two of waited-for candidates.
constexpr size_t kNextStepCandidates = kMaxSpareNextSteps + 2;

}  // namespace

CandidateEvaluator::CandidateEvaluator(const PlanOptions& options, Plan* plan, Measurer* measurer,
                                       const std::shared_ptr<const State>* state, const Measured* current,
                                       const StepScale* scale)
    : options_(options),
      plan_(plan),
      measurer_(measurer),
      state_(state),
      current_(current),
      scale_(scale),
      width_(CandidatesAtOnce(options, (*state)->asset)),
      beside_(measurer->PreparesBesideScores()),
      may_prepare_next_(beside_ && width_ > 1 &&
                        MemoryLimit(UINT64_MAX) / (4 * AssetArrayBytes((*state)->asset)) >=
                            2 * (width_ + kNextStepCandidates)),
      current_at_(state->get()),
      // With next steps, the speculative preparations (next steps, spares) run on as many
      // background threads as the plan's width, beside the urgent ones.
      pool_(width_ > 1 ? width_ + (may_prepare_next_ ? 1 : 0) : 0, may_prepare_next_ ? width_ : 0) {}

StatusOr<Evaluated> CandidateEvaluator::Collect(Pending* pending) {
  Wait([&] { pool_.Finish(pending->task); });
  return std::move(*pending->result);
}

void CandidateEvaluator::Drop(const Pending& pending) {
  pool_.Cancel(pending.task);
  if (!beside_) pool_.WaitIdle();
}

void CandidateEvaluator::Taken(const State* from, const WriteOptions* write) {
  moved_ = true;
  std::lock_guard<std::mutex> lock(next_mutex_);
  next_steps_on_ = may_prepare_next_;
  current_at_ = state_->get();
  for (NextStep& n : next_steps_) {
    // The taken encoding move's next step: its state is now the copy (the same content).
    if (from != nullptr && n.at.get() == from && n.write && *n.write == *write) {
      n.at = *state_;
      n.write.reset();
      n.line->base = current_at_;
    }
  }
  CancelNextStepsLocked(current_at_);
}

void CandidateEvaluator::Finish() {
  {
    std::lock_guard<std::mutex> lock(next_mutex_);
    next_steps_on_ = false;
    CancelNextStepsLocked(nullptr);
    plan_->timing.next_steps_prepared = next_steps_started_;
    plan_->timing.next_steps_used = next_steps_used_;
  }
  Wait([&] { pool_.WaitIdle(); });
  std::lock_guard<std::mutex> lock(mutex_);
  plan_->timing.overlap_seconds = std::max(0.0, busy_ - waited_);
}

void CandidateEvaluator::CancelNextStepsLocked(const State* at) {
  std::erase_if(next_steps_, [&](const NextStep& n) {
    if (n.at.get() == at && !n.write) return false;
    pool_.Cancel(n.pending.task);
    return true;
  });
}

std::optional<Pending> CandidateEvaluator::TakeNextStep(const Move& proposal) {
  std::lock_guard<std::mutex> lock(next_mutex_);
  const auto it = std::find_if(next_steps_.begin(), next_steps_.end(), [&](const NextStep& n) {
    return n.at == *state_ && !n.write && KeyOf(n.move) == KeyOf(proposal) && n.move.count == proposal.count;
  });
  if (it == next_steps_.end()) return std::nullopt;
  NextStep taken = std::move(*it);
  next_steps_.erase(it);
  ++next_steps_used_;
  pool_.Promote(taken.pending.task);
  taken.line->may_follow = true;  // the plan took it: its own next step may start
  FollowLocked(taken.line);
  return taken.pending;
}

void CandidateEvaluator::FollowLocked(const std::shared_ptr<Line>& line) {
  if (!line->may_follow || line->followed || !line->after) return;
  const auto after_spares =
      std::count_if(next_steps_.begin(), next_steps_.end(), [](const NextStep& n) { return n.after_spare; });
  // A candidate not prepared at the current state can no longer be taken.
  if (!next_steps_on_ || line->base != current_at_ ||
      (line->spare && static_cast<size_t>(after_spares) >= kMaxSpareNextSteps)) {
    line->after = nullptr;
    return;
  }
  line->followed = true;
  std::shared_ptr<const State> at = std::move(line->after);
  std::optional<WriteOptions> write = std::move(line->after_write);
  const std::optional<Move> next =
      NextStepAfter(at->asset, write ? *write : at->write, line->move, options_, line->scale);
  if (!next) return;
  auto next_line = std::make_shared<Line>();
  next_line->move = *next;
  next_line->base = at.get();
  next_line->scale = line->scale;
  next_line->scale.Taken(line->move.lever, options_.step_growth);
  ++next_steps_started_;
  // Before the spares (it is needed whenever its candidate is taken), after what the plan waits for.
  Pending pending = Start(at, *next, next_line, PreparationPool::Priority::kSoon, write);
  next_steps_.push_back(
      NextStep{std::move(at), std::move(write), *next, std::move(pending), std::move(next_line), line->spare});
}

Status CandidateEvaluator::Score(Evaluated* e) {
  if (e->encoded) ++plan_->timing.measurements;
  if (!e->prepared) return Status::Ok();
  ATEX_RETURN_IF_ERROR(measurer_->Score(&e->candidate));
  const Measured& measured = e->candidate.measured;
  if (measured.bytes >= current_->bytes) return Status::Ok();
  const uint64_t saving = current_->bytes - measured.bytes;
  const double damage = std::max(0.0, measured.distortion - current_->distortion);
  e->cost = Cached{damage / static_cast<double>(saving), saving, true};
  return Status::Ok();
}

Pending CandidateEvaluator::Submit(const Move& proposal, bool urgent) {
  if (std::optional<Pending> ready = TakeNextStep(proposal)) return *ready;
  auto line = std::make_shared<Line>();
  line->move = proposal;
  line->base = state_->get();
  line->scale = *scale_;
  line->spare = !urgent;
  line->may_follow = true;
  return Start(*state_, proposal, std::move(line),
               urgent ? PreparationPool::Priority::kUrgent : PreparationPool::Priority::kLater);
}

Pending CandidateEvaluator::Start(const std::shared_ptr<const State>& at, const Move& proposal,
                                  std::shared_ptr<Line> line, PreparationPool::Priority priority,
                                  std::optional<WriteOptions> write) {
  Pending p;
  p.result = std::make_shared<StatusOr<Evaluated>>(Status(StatusCode::kInternal, "candidate not prepared"));
  p.task = pool_.Submit([this, at, write = std::move(write), proposal, line = std::move(line),
                         result = p.result] { *result = Prepare(at, write, proposal, line); },
                        priority);
  return p;
}

StatusOr<Evaluated> CandidateEvaluator::Prepare(const std::shared_ptr<const State>& at,
                                                const std::optional<WriteOptions>& write, const Move& proposal,
                                                const std::shared_ptr<Line>& line) {
  Stopwatch whole;
  StatusOr<Evaluated> e = Status(StatusCode::kInternal, "candidate not prepared");
  try {
    e = PrepareAt(at, write, proposal, line);
  } catch (const std::bad_alloc&) {
    e = Status(StatusCode::kLimitExceeded, "out of memory preparing a fit candidate");
  } catch (const std::exception& ex) {
    e = Status(StatusCode::kInternal, StrCat("preparing a fit candidate: ", ex.what()));
  }
  std::lock_guard<std::mutex> lock(mutex_);
  busy_ += whole.Lap();
  return e;
}

StatusOr<Evaluated> CandidateEvaluator::PrepareAt(const std::shared_ptr<const State>& at,
                                                  const std::optional<WriteOptions>& write, const Move& proposal,
                                                  const std::shared_ptr<Line>& line) {
  Evaluated e;
  e.cost = Cached{kNoGain, 0, true};
  Stopwatch clock;
  Status applied = Status::Ok();
  if (proposal.lever == Lever::kEncoding) {
    e.base = at;
    e.write = write ? *write : at->write;
    SetEncoding(&e.write, proposal.stream, proposal.encoding);  // ApplyMove's encoding move
  } else {
    auto next = internal::AppliedTo(*at, proposal, plan_->prune_order, options_.min_grid_resolution);
    applied = next.status();
    if (next.ok()) e.next = std::make_shared<const State>(std::move(next).value());
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    plan_->timing.apply_seconds += clock.Lap();
  }
  // A move the state cannot take (e.g. nothing left to halve) is not a move.
  if (!applied.ok()) return e;
  if (line) {
    std::lock_guard<std::mutex> lock(next_mutex_);
    line->after = e.next ? e.next : e.base;
    if (!e.next) line->after_write = e.write;
    FollowLocked(line);
  }
  e.encoded = true;
  auto candidate = measurer_->Prepare(e.Ref(), proposal);
  if (!candidate.ok()) {
    // A stream that an encoding cannot hold (f16 overflow) is simply not a move.
    if (candidate.status().code() == StatusCode::kOutOfRange) return e;
    return candidate.status();
  }
  e.candidate = std::move(*candidate);
  e.prepared = true;
  return e;
}

}  // namespace atex::fit::internal
