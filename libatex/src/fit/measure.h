// The fitter's measurements of states (plan.cc): exact file bytes and probe distortion.
// Not part of the public API.
//
// Every state is encoded (exact bytes; unchanged chunks come from the cache) and read back
// (the exact values a reader gets, computed from the state's values: container/read_back.h).
// On a GPU backend the decoded asset is rendered in full. On the CPU the probes are rendered incrementally against
// the current state (incremental_probes.h): a candidate projects and composites only what its
// move changed.
//
// Prune moves on the CPU are measured range-stable (PruneMeasure::kRangeStable): the
// rendered asset is the current one less the removed Gaussians. A prune changes the
// quantisation ranges of the q8/q16 streams (each stream keeps its min and max over the
// Gaussians, and the least important Gaussians hold extremes), so its exact decode moves
// every Gaussian by a fraction of a quantisation step, and an exact measurement renders
// everything again (all tiles, and the deformation of every Gaussian when the positions'
// range moved). The range-stable measurement charges a prune with its removals only, and
// the rendered asset keeps the survivors' earlier values when it is taken: the moves
// after it are measured by what they change of the exact decode (texels, encodings),
// applied to the rendered asset. So the distortions the plan records leave out the
// re-rounding of survivors after range changes, a noise of a fraction of a quantisation
// step; the bytes are always exact (every candidate is encoded), and so is the output
// (ApplyPlan encodes it). kRangeStableConfirmed renders each taken prune's exact decode
// instead (the distortions are then the exact ones, as kExact's); on the lego sample all
// three give the same plan (BENCHMARKS.md, issue 23).
#pragma once

#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "atex/fit.h"
#include "container/read_back.h"
#include "cpu_probes.h"
#include "incremental_probes.h"
#include "plan_state.h"

namespace atex::fit::internal {

// What a measurement reads of a state: its asset, its encodings and the input index of each
// Gaussian kept. An encoding candidate is measured on its state's own asset with other write
// options (no copy of the asset).
struct StateRef {
  StateRef(const State& s) : asset(s.asset), write(s.write), kept(s.kept) {}  // NOLINT: implicit on purpose
  StateRef(const Asset& a, const WriteOptions& w, const std::vector<uint32_t>& k) : asset(a), write(w), kept(k) {}
  const Asset& asset;
  const WriteOptions& write;
  const std::vector<uint32_t>& kept;
};

struct Measured {
  uint64_t bytes = 0;
  double distortion = 0;
};

enum class PruneMeasure {
  kExact,                 // the candidate's exact decode, as every other move
  kRangeStable,           // range-stable (the default)
  kRangeStableConfirmed,  // range-stable candidates; the taken one rendered from its exact decode
};

// A measured candidate, with what Measurer::Take needs.
struct Candidate {
  Measured measured;
  Asset decoded;         // what a reader of the candidate gets
  CandidateMap map;      // against the current state (CPU only)
  bool range_stable = false;
  std::shared_ptr<const IncrementalProbes::Pending> pending;  // CPU only
  // GPU only: `decoded`'s render state, built by Prepare (beside other preparations) for Score,
  // and how to render it. Unless the Measurer keeps decodes, the render state takes `decoded`'s
  // arrays (moved, not copied) and `decoded` keeps only its metadata.
  std::shared_ptr<const train::ModelState> render_state;
  train::StateKeys render_keys;  // of render_state's arrays: the backend keeps those it holds
  train::RenderRequest request;
};

class Measurer {
 public:
  // `renderer` renders the probes; on the CPU (renderer->cpu_renderer() not null)
  // incrementally. Timings and counts go to `timing`. `keep_decoded`: every Candidate keeps its
  // whole `decoded` asset (PlanOptions::accept_more reads it); otherwise a GPU candidate's
  // arrays go to its render state.
  Measurer(ProbeRenderer* renderer, EncodeCache* chunks, MeasureTiming* timing,
           PruneMeasure prune = PruneMeasure::kRangeStable, bool keep_decoded = true);
  ~Measurer();

  // Whether Prepare may run while Score runs, and whether Take may run while a Prepare started
  // before it still runs: true on a GPU backend, where Score renders the candidate's own render
  // state and Take changes nothing Prepare reads. On the CPU, Take changes the current state
  // that Prepare compares candidates with, and both render on every core.
  bool PreparesBesideScores() const { return incremental_ == nullptr; }

  // Renders the reference (`input` as given) and measures `initial`, which becomes the current state.
  StatusOr<Measured> Start(const Asset& input, const State& initial);
  // Measures `next`, the current state after `move`: Prepare, then Score. Encoding errors
  // come back as they are (kOutOfRange: a stream the encoding cannot hold). The caller
  // counts it in MeasureTiming::measurements (a prepared candidate may go unused).
  StatusOr<Candidate> Measure(StateRef next, const Move& move);
  // The CPU part of a measurement: encode, read back and (on the CPU path) which Gaussians the
  // candidate changes. Several may run at once (BuildPlan prepares a state's proposals in
  // parallel); none may run during Start, nor during Score or Take unless
  // PreparesBesideScores().
  StatusOr<Candidate> Prepare(StateRef next, const Move& move);
  // The distortion of a prepared candidate: the probe renders. One at a time.
  Status Score(Candidate* candidate);
  // The candidate (measured at the current state) becomes the current state; returns its
  // measurement (with kRangeStableConfirmed, a range-stable one is rendered exactly first).
  StatusOr<Measured> Take(StateRef next, const Candidate& candidate);

 private:
  StatusOr<Candidate> Encode(StateRef state);  // thread-safe (timing_ under timing_mutex_)
  StatusOr<double> Distortion(const Candidate& candidate, const CandidateMap& map,
                              std::shared_ptr<const IncrementalProbes::Pending>* pending);

  // What DecodedAsWritten does not model (Draco positions): the file, encoded and decoded.
  StatusOr<Candidate> EncodeAndDecode(StateRef state);

  ProbeRenderer* renderer_;
  EncodeCache* chunks_;
  // A candidate changes one or two streams: the others' read backs are copies.
  container::ReadBackCache read_back_;
  MeasureTiming* timing_;
  std::mutex timing_mutex_;  // Prepare's updates of timing_ (Score and Take write other fields)
  PruneMeasure prune_;
  bool keep_decoded_;
  std::vector<Image> reference_;
  CpuProbeRenderer* cpu_ = nullptr;                 // CPU only
  IncrementalProbes* incremental_ = nullptr;        // CPU only (cpu_'s)
  Asset current_;                                   // the current state's decode (CPU only)
  std::vector<uint32_t> current_kept_;
};

}  // namespace atex::fit::internal
