// CandidateEvaluator (candidate_evaluator.h).
#include "candidate_evaluator.h"

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

StatusOr<Evaluated> CandidateEvaluator::Collect(Pending* pending) {
  Wait([&] { pool_.Finish(pending->task); });
  return std::move(*pending->result);
}

void CandidateEvaluator::Drop(const Pending& pending) {
  pool_.Cancel(pending.task);
  if (!beside_) pool_.WaitIdle();
}

void CandidateEvaluator::Finish() {
  Wait([&] { pool_.WaitIdle(); });
  std::lock_guard<std::mutex> lock(mutex_);
  plan_->timing.overlap_seconds = std::max(0.0, busy_ - waited_);
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
  Pending p;
  p.result = std::make_shared<StatusOr<Evaluated>>(Status(StatusCode::kInternal, "candidate not prepared"));
  p.task = pool_.Submit([this, at = *state_, proposal, result = p.result] { *result = Prepare(at, proposal); },
                        urgent);
  return p;
}

StatusOr<Evaluated> CandidateEvaluator::Prepare(const std::shared_ptr<const State>& at, const Move& proposal) {
  Stopwatch whole;
  StatusOr<Evaluated> e = Status(StatusCode::kInternal, "candidate not prepared");
  try {
    e = PrepareAt(at, proposal);
  } catch (const std::bad_alloc&) {
    e = Status(StatusCode::kLimitExceeded, "out of memory preparing a fit candidate");
  } catch (const std::exception& ex) {
    e = Status(StatusCode::kInternal, StrCat("preparing a fit candidate: ", ex.what()));
  }
  std::lock_guard<std::mutex> lock(mutex_);
  busy_ += whole.Lap();
  return e;
}

StatusOr<Evaluated> CandidateEvaluator::PrepareAt(const std::shared_ptr<const State>& at, const Move& proposal) {
  Evaluated e;
  e.cost = Cached{kNoGain, 0, true};
  Stopwatch clock;
  Status applied = Status::Ok();
  if (proposal.lever == Lever::kEncoding) {
    e.base = at;
    e.write = at->write;
    SetEncoding(&e.write, proposal.stream, proposal.encoding);  // ApplyMove's encoding move
  } else {
    auto next = internal::AppliedTo(*at, proposal, plan_->prune_order, options_.min_grid_resolution);
    applied = next.status();
    if (next.ok()) e.next = std::move(next).value();
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    plan_->timing.apply_seconds += clock.Lap();
  }
  // A move the state cannot take (e.g. nothing left to halve) is not a move.
  if (!applied.ok()) return e;
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
