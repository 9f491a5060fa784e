// The fitter's plan: greedy rate–distortion search over the levers (fit.h). Applying a plan
// to a budget is apply_plan.cc.
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <system_error>
#include <thread>
#include <tuple>

#include "atex/file_io.h"
#include "atex/fit.h"
#include "levers.h"
#include "measure.h"
#include "plan_state.h"
#include "texture_shrink.h"

namespace atex::fit {

using internal::Candidate;
using internal::InitialState;
using internal::Measured;
using internal::Measurer;
using internal::PlanTail;
using internal::State;
using internal::Stopwatch;

namespace {

// Step multipliers of the divisible levers (PlanOptions::step_growth): 1 until a lever wins
// twice in a row.
struct StepScale {
  double prune = 1, textures = 1;
  std::optional<Lever> last;  // the lever of the last move taken

  // A divisible lever that wins again takes a larger step next time; any other move resets.
  void Taken(Lever lever, double growth) {
    const bool again = last == lever;
    if (!again) prune = textures = 1;
    if (again && lever == Lever::kPrune) prune = std::min(prune * growth, 1e6);
    if (again && lever == Lever::kTextures) textures = std::min(textures * growth, 1e6);
    last = lever;
  }
};

// The next move of every lever at `state` (prune and texture counts sized to the state and
// the lever's step scale).
std::vector<Move> Proposals(const State& state, const PlanOptions& o, const StepScale& scale) {
  std::vector<Move> moves;
  const Asset& a = state.asset;
  const size_t n = a.gaussians.size();
  const auto allowed = [&](Lever lever) { return HasLever(o.levers, lever); };
  if (allowed(Lever::kPrune) && n > 1) {
    Move m;
    m.lever = Lever::kPrune;
    const double fraction = std::min(o.prune_fraction * scale.prune, std::max(o.prune_fraction, 0.5));
    m.count = std::clamp<uint64_t>(static_cast<uint64_t>(fraction * static_cast<double>(n)), 1, n - 1);
    moves.push_back(m);
  }
  if (allowed(Lever::kAllTextures) && a.textures && ShrinkableTexels(*a.textures) > 0) {
    Move m;
    m.lever = Lever::kAllTextures;
    moves.push_back(m);
  }
  if (allowed(Lever::kTextures) && a.textures && ShrinkableTexels(*a.textures) > 0) {
    uint64_t growable = 0;
    for (size_t i = 0; i < a.textures->size(); ++i) growable += a.textures->heights[i] * a.textures->widths[i] > 1;
    Move m;
    m.lever = Lever::kTextures;
    const double fraction = std::min(o.texture_fraction * scale.textures, 1.0);
    m.count = std::max<uint64_t>(1, static_cast<uint64_t>(fraction * static_cast<double>(growable)));
    moves.push_back(m);
  }
  if (allowed(Lever::kShDegree) && a.gaussians.sh_degree > 0) {
    Move m;
    m.lever = Lever::kShDegree;
    moves.push_back(m);
  }
  for (int s = 0; allowed(Lever::kEncoding) && s < static_cast<int>(Stream::kCount); ++s) {
    const auto stream = static_cast<Stream>(s);
    if (stream == Stream::kShRest && a.gaussians.sh_degree == 0) continue;
    if (stream == Stream::kTexels && !a.textures) continue;
    if (stream == Stream::kDeformationGrids && !a.deformation) continue;
    const ScalarEncoding current = GetEncoding(state.write, stream);
    std::vector<ScalarEncoding> next;
    if (current == ScalarEncoding::kFloat32) next = {ScalarEncoding::kFloat16, ScalarEncoding::kQuant16};
    if (current == ScalarEncoding::kFloat16 || current == ScalarEncoding::kQuant16) next = {ScalarEncoding::kQuant8};
    for (ScalarEncoding e : next) {
      Move m;
      m.lever = Lever::kEncoding;
      m.stream = stream;
      m.encoding = e;
      moves.push_back(m);
    }
  }
  if (allowed(Lever::kGrid) && CanCoarsenGrid(a, o.min_grid_resolution)) {
    Move m;
    m.lever = Lever::kGrid;
    moves.push_back(m);
  }
  return moves;
}

// Identity of a proposal across states (counts change with the state, the kind does not).
using MoveKey = std::tuple<int, int, int>;
MoveKey KeyOf(const Move& m) {
  return {static_cast<int>(m.lever), m.lever == Lever::kEncoding ? static_cast<int>(m.stream) : -1,
          m.lever == Lever::kEncoding ? static_cast<int>(m.encoding) : -1};
}

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
  State next;             // the state after the move (kept only for the best fresh evaluation)
  Candidate candidate;    // its measurement and decode
};
bool Better(const Cached& a, const Cached& b) {
  return a.ratio < b.ratio || (a.ratio == b.ratio && a.saving > b.saving);
}

// kInvalidArgument for options or probes a plan cannot be built with.
Status CheckPlanInputs(const ProbeRenderer& renderer, const PlanOptions& options) {
  if (!(options.prune_fraction > 0 && options.prune_fraction < 1) ||
      !(options.texture_fraction > 0 && options.texture_fraction <= 1)) {
    return MakeError(StatusCode::kInvalidArgument, "fit: step fractions must be in (0, 1)");
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

// fn(0) .. fn(count - 1), on one thread each when count > 1; results in order. An exception
// becomes the candidate's error; when a thread cannot be started, the rest run here, serially.
template <typename Fn>
std::vector<StatusOr<Evaluated>> PrepareAll(size_t count, const Fn& fn) {
  std::vector<StatusOr<Evaluated>> results(count, Status(StatusCode::kInternal, "candidate not prepared"));
  const auto run = [&](size_t i) {
    try {
      results[i] = fn(i);
    } catch (const std::bad_alloc&) {
      results[i] = Status(StatusCode::kLimitExceeded, "out of memory preparing a fit candidate");
    } catch (const std::exception& e) {
      results[i] = Status(StatusCode::kInternal, StrCat("preparing a fit candidate: ", e.what()));
    }
  };
  std::vector<std::thread> threads;
  threads.reserve(count);
  size_t started = 0;
  if (count > 1) {
    try {
      for (; started < count; ++started) threads.emplace_back(run, started);
    } catch (const std::system_error&) {
      // No more threads: the candidates not started are prepared on this one.
    }
  }
  for (size_t i = started; i < count; ++i) run(i);
  for (std::thread& t : threads) t.join();
  return results;
}

// How many candidates to prepare at once: PlanOptions::parallel_candidates, or for 0 the
// cores (at most 4), fewer when that many copies of the asset would not fit in half the
// machine's memory (each candidate holds about four: the state's copy, its file, its decode and,
// on a GPU backend, the decode's render state).
size_t CandidatesAtOnce(const PlanOptions& options, const Asset& asset) {
  if (options.parallel_candidates > 0) return static_cast<size_t>(options.parallel_candidates);
  const Gaussians& g = asset.gaussians;
  uint64_t bytes = sizeof(float) * (g.positions.size() + g.rotations.size() + g.log_scales.size() +
                                    g.opacity_logits.size() + g.sh.size() + g.time_windows.size());
  if (asset.textures) bytes += sizeof(float) * asset.textures->texels.size();
  const uint64_t per_candidate = 4 * std::max<uint64_t>(bytes, 1);
  const uint64_t fit = MemoryLimit(UINT64_MAX) / per_candidate;
  return std::clamp<size_t>(std::min<uint64_t>(fit, std::thread::hardware_concurrency()), 1, 4);
}

// Applies proposals to the current state and measures them: prepared (the move applied to a
// copy of the state, encoded and decoded: CPU work that several proposals do at once), then
// scored (the probe renders, one at a time, in proposal order: the plan does not depend on how
// many were prepared at once). `state` and `current` are BuildPlan's, read at each call.
class CandidateEvaluator {
 public:
  CandidateEvaluator(const PlanOptions& options, Plan* plan, Measurer* measurer, const State* state,
                     const Measured* current)
      : options_(options), plan_(plan), measurer_(measurer), state_(state), current_(current),
        width_(CandidatesAtOnce(options, state->asset)) {}

  // Evaluates `proposals`, `width_` prepared at a time, and hands each to `remember` in order.
  // `spare` (proposals likely to be evaluated next at this state) fill the last wave's free
  // places: they are prepared, not scored, and handed to `stash` (errors included) for later.
  template <typename Remember, typename Stash>
  Status EvaluateAll(const std::vector<const Move*>& proposals, const Remember& remember,
                     const std::vector<const Move*>& spare, const Stash& stash) {
    for (size_t begin = 0; begin < proposals.size(); begin += width_) {
      const size_t count = std::min(width_, proposals.size() - begin);
      const bool last = begin + count == proposals.size();
      std::vector<const Move*> wave(proposals.begin() + static_cast<std::ptrdiff_t>(begin),
                                    proposals.begin() + static_cast<std::ptrdiff_t>(begin + count));
      for (size_t i = 0; last && i < spare.size() && wave.size() < width_; ++i) wave.push_back(spare[i]);
      wave_busy_ = 0;
      Stopwatch wave_clock;
      std::vector<StatusOr<Evaluated>> prepared =
          PrepareAll(wave.size(), [&](size_t i) { return Prepare(*wave[i]); });
      plan_->timing.overlap_seconds += std::max(0.0, wave_busy_ - wave_clock.Lap());
      for (size_t i = count; i < wave.size(); ++i) stash(*wave[i], std::move(prepared[i]));
      for (size_t i = 0; i < count; ++i) {
        if (!prepared[i].ok()) return prepared[i].status();
        ATEX_RETURN_IF_ERROR(Score(&*prepared[i]));
        remember(*wave[i], std::move(*prepared[i]));
      }
    }
    return Status::Ok();
  }

  // Scores a prepared proposal; it then counts as a measurement.
  Status Score(Evaluated* e) {
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

 private:
  // Thread-safe: several run at once between two moves.
  StatusOr<Evaluated> Prepare(const Move& proposal) {
    Evaluated e;
    e.cost = Cached{kNoGain, 0, true};
    Stopwatch clock, whole;
    const auto busy = [&] {  // this preparation's wall time, for the wave's overlap
      std::lock_guard<std::mutex> lock(mutex_);
      wave_busy_ += whole.Lap();
    };
    e.next = *state_;
    const Status applied = ApplyMove(proposal, plan_->prune_order, &e.next.asset, &e.next.write, &e.next.kept,
                                     options_.min_grid_resolution, e.next.memo.get());
    {
      std::lock_guard<std::mutex> lock(mutex_);
      plan_->timing.apply_seconds += clock.Lap();
    }
    if (!applied.ok()) {  // a move the state cannot take (e.g. nothing left to halve) is not a move
      busy();
      return e;
    }
    e.encoded = true;
    auto candidate = measurer_->Prepare(e.next, proposal);
    busy();
    if (!candidate.ok()) {
      // A stream that an encoding cannot hold (f16 overflow) is simply not a move.
      if (candidate.status().code() == StatusCode::kOutOfRange) return e;
      return candidate.status();
    }
    e.candidate = std::move(*candidate);
    e.prepared = true;
    return e;
  }

  const PlanOptions& options_;
  Plan* plan_;
  Measurer* measurer_;
  const State* state_;
  const Measured* current_;
  const size_t width_;
  std::mutex mutex_;       // the timing sums written by preparations running at once
  double wave_busy_ = 0;   // summed preparation seconds of the current wave
};

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

void ReportProgress(const PlanOptions& options, const Plan& plan, const Move& move, const Measured& current) {
  if (!options.progress) return;
  options.progress(FitProgress{static_cast<int>(plan.moves.size()), current.bytes, options.floor_bytes,
                               StrCat(DescribeMove(move), ": ", current.bytes, " bytes, proxy PSNR ",
                                      current.distortion > 0 ? -10.0 * std::log10(current.distortion) : 99.0)});
}

// The states Plan::tail keeps, collected while the plan is built (moved in, not copied): the
// state before the last move taken, and those before the last two moves that changed the
// content (no encoding moves: ApplyPlan's refill starts from the latest one before the last
// move, FirstRefillPrefix).
class TailKeeper {
 public:
  // `before` is the state before `move`, the plan's move number `index`.
  void Taken(const Move& move, size_t index, State before) {
    before_last_ = std::make_shared<const State>(std::move(before));
    if (move.lever != Lever::kEncoding) {
      if (before_content_.size() == 2) before_content_.erase(before_content_.begin());
      before_content_.emplace_back(index, before_last_);
    }
  }
  // The tail of a plan of `moves` moves built from `asset` with `write`, whose last state is `last`.
  std::shared_ptr<const PlanTail> Finish(const Asset& asset, const WriteOptions& write, size_t moves, State last) {
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
    tail->states.push_back(std::make_shared<const State>(std::move(last)));
    return tail;
  }

 private:
  std::shared_ptr<const State> before_last_;
  std::vector<std::pair<size_t, std::shared_ptr<const State>>> before_content_;  // (move index, state), two at most
};

}  // namespace

StatusOr<Plan> BuildPlan(const Asset& asset, ProbeRenderer* renderer, const PlanOptions& options) {
  ATEX_RETURN_IF_ERROR(CheckPlanInputs(*renderer, options));
  ATEX_RETURN_IF_ERROR(ValidateAsset(asset));
  const ProbeRenderer::CacheCounts before = renderer->cache_counts();
  Plan plan;
  Stopwatch whole;
  plan.prune_order = ImportanceOrder(asset, options.seed);
  plan.levers = options.levers;
  plan.min_grid_resolution = options.min_grid_resolution;
  State state = InitialState(asset, options.write);
  plan.texture_memo = state.memo;
  // Most candidates change one or two chunks of the current state; the others are
  // compressed once, not once per candidate.
  EncodeCache chunks;
  Measurer measurer(renderer, &chunks, &plan.timing);
  // Reference: the untrimmed asset exactly as given (before any re-encoding).
  ATEX_ASSIGN_OR_RETURN(Measured current, measurer.Start(asset, state));
  plan.initial_bytes = current.bytes;
  plan.initial_distortion = current.distortion;

  // Lazy greedy: each proposal keeps the cost per byte measured at an earlier state
  // (costs change slowly between moves); a stale best is measured again, and a move is
  // taken only when the best cost is a fresh one (measured at the current state).
  CandidateEvaluator evaluator(options, &plan, &measurer, &state, &current);
  std::map<MoveKey, Cached> cache;
  StepScale scale;
  TailKeeper tail;
  while (current.bytes > options.floor_bytes) {
    Stopwatch propose_clock;
    const std::vector<Move> proposals = Proposals(state, options, scale);
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
    std::map<MoveKey, StatusOr<Evaluated>> speculative;
    const auto stash = [&](const Move& p, StatusOr<Evaluated> e) {
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
      StatusOr<Evaluated> e = std::move(ready->second);
      speculative.erase(ready);
      if (!e.ok()) return e.status();
      ATEX_RETURN_IF_ERROR(evaluator.Score(&*e));
      remember(*best, std::move(*e));
    }
    plan.timing.prepared_unused += static_cast<int>(speculative.size());
    if (chosen == nullptr) break;  // no lever saves bytes any more
    Evaluated& taken = best_fresh->second;
    ATEX_ASSIGN_OR_RETURN(Measured measured, measurer.Take(taken.next, taken.candidate));
    Move move = *chosen;
    move.bytes_after = measured.bytes;
    move.distortion_after = measured.distortion;
    if (options.accept_more) {
      ATEX_ASSIGN_OR_RETURN(bool more, options.accept_more(taken.candidate.decoded, move));
      if (!more) break;
    }
    tail.Taken(move, plan.moves.size(), std::move(state));
    state = std::move(taken.next);
    current = measured;
    plan.moves.push_back(move);
    scale.Taken(move.lever, options.step_growth);
    for (auto& entry : cache) entry.second.fresh = false;
    cache.erase(KeyOf(move));  // its next step is a different move (new count, new encoding)
    if (move.lever == Lever::kEncoding) {
      // Both 16-bit options of a stream are decided once one is taken.
      for (ScalarEncoding e : {ScalarEncoding::kFloat16, ScalarEncoding::kQuant16, ScalarEncoding::kQuant8}) {
        cache.erase(MoveKey{static_cast<int>(Lever::kEncoding), static_cast<int>(move.stream), static_cast<int>(e)});
      }
    }
    ReportProgress(options, plan, move, current);
  }
  plan.tail = tail.Finish(asset, options.write, plan.moves.size(), std::move(state));
  plan.timing.total_seconds = whole.Lap();
  const ProbeRenderer::CacheCounts after = renderer->cache_counts();
  plan.timing.probe_cache = {after.deformed - before.deformed, after.deform_reused - before.deform_reused,
                             after.tiles_drawn - before.tiles_drawn, after.tiles_reused - before.tiles_reused};
  return plan;
}

}  // namespace atex::fit
