// One `atex fit` run as a library call: the fixed-count protocol, the budget or
// quality-floor fit, the fine-tune and re-fit, and several budgets sharing one plan.
// The front end (tools/cmd_fit.cc) parses, calls RunFit, writes the outputs and prints
// the report; nothing here prints, exits or writes files. The method is in fit.h and
// docs/fit.md.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "atex/dataset.h"
#include "atex/fit.h"
#include "atex/model.h"
#include "atex/status.h"
#include "atex/train/backend.h"
#include "atex/train/trainer.h"

namespace atex::fit {

struct FitRunOptions {
  // Byte budgets; the plan is built for the smallest and serves the others. Empty: no
  // budget (then keep_count or quality must be set).
  std::vector<uint64_t> budgets;
  double keep_count = 0;          // (0, 1]: keep this fraction of the Gaussians first; 0: off
  const Asset* order_from = nullptr;  // keep_count's importance order from this asset (same Gaussians)
  double quality = 0;             // > 0: the smallest asset whose test PSNR stays >= this (needs a dataset)
  int probes = 8;                 // probe views (>= 1)
  int probe_size = 256;           // longer side of the probe renders, pixels (>= 8)
  int eval_views = 0;             // test views for PSNR, evenly spaced; 0 = all
  int finetune = 0;               // stage-2 steps on the trimmed model, then a re-fit (needs a dataset, one budget)
  bool keep_stats = false;        // keep the GSTA chunk in the outputs
  uint64_t seed = 6666;
  LeverSet levers = kDefaultLevers;
  double step_growth = 2.0;       // PlanOptions::step_growth, in [1, 16]
  double min_texture_step = PlanOptions{}.min_texture_step;  // PlanOptions::min_texture_step, in [0, 1]
  int parallel_candidates = 0;    // PlanOptions::parallel_candidates (0: automatic), in [0, 64]
  // A second backend for the input's test evaluation: it then runs on another thread while the
  // plan is built, instead of before it (with a dataset; not with a quality floor, which needs
  // the input's score first). Must not be the run's backend. Null: before the plan, on the
  // run's backend.
  train::Backend* input_eval_backend = nullptr;
  std::function<void(const FitProgress&)> progress;  // each move taken
  // Asked after each move taken (PlanOptions::cancelled): true stops the run with kCancelled.
  std::function<bool()> cancelled;
  // Fine-tune progress (return false to stop training early).
  std::function<bool(const train::TrainProgress&)> finetune_progress;
};

// kInvalidArgument naming the option when the options are inconsistent: no mode, both a
// budget and a quality floor, probes < 1, probe_size < 8, eval_views or finetune < 0,
// keep_count outside [0, 1], a quality floor or fine-tune without a dataset, fine-tune
// with several budgets, a non-finite quality, step_growth, min_texture_step or
// parallel_candidates out of range.
Status ValidateFitRunOptions(const FitRunOptions& options, bool have_dataset);

// One fitted file.
struct FitRunOutput {
  uint64_t budget_bytes = 0;  // 0 without a budget (keep-count or quality mode)
  Fitted fitted;              // bytes to write, the decoded asset, moves
  // budget_bytes, bytes, components, levers; test metrics (with a dataset); the plan's
  // estimated_psnr_vs_input for this output (not for a keep-count subset without a plan), or
  // smallest_fallback in its place.
  nlohmann::json report;
};

struct FitRunReport {
  // outputs[0] is the main output (the smallest budget, or the only file); the others
  // follow in the order of options.budgets.
  std::vector<FitRunOutput> outputs;
  size_t main_budget_index = 0;  // index into options.budgets of outputs[0]
  // The --json report (docs/fit.md), without output paths: "input", "backend", "distortion",
  // "keep_count", "finetune", "output", "other_budgets", "budget_bytes", "quality_floor_psnr",
  // "levers", "moves", "plan_timing", "estimated_psnr_vs_input", "seconds".
  nlohmann::json json;
};

// Fits the encoded asset `input_bytes`. `dataset` may be null (orbit probes, no test
// metrics); `backend` renders the probes (CUDA when present; the CPU backend or null for
// the CPU probe renderer) and runs the fine-tune. Errors: ValidateFitRunOptions', the
// input's decode errors, kBudgetTooSmall (CheckBudget), kOutOfRange when a quality floor
// cannot be reached (the input itself scores below it).
StatusOr<FitRunReport> RunFit(const std::vector<uint8_t>& input_bytes, const Dataset* dataset,
                              train::Backend* backend, const FitRunOptions& options);

// What each lever removed between two assets, with `write`'s final encodings (report JSON).
nlohmann::json LeverSummary(const Asset& before, const Asset& after, const WriteOptions& write);

// The fine-tune configuration for a trimmed asset: the dataset kind's default config,
// stage 2 only, `steps` steps, no growth, the asset's texture mode, SH degree and
// background kept (topology and texture sizes fixed).
train::TrainerOptions FinetuneOptions(const Dataset& dataset, const Asset& asset, int steps, uint64_t seed);

}  // namespace atex::fit
