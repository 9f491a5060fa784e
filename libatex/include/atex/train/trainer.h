// The training loop of both stages (docs/architecture.md, "Training").
//
// Stage 1 (4DGaussians): initial Gaussians from the dataset (init.h), a coarse
// static phase, then the deformation phase, with densification and pruning.
// Stage 2 (AdaTex4D): one texture plane per Gaussian, joint fine-tuning with the
// topology fixed, anisotropic texture growth at the configured steps.
// Every decision is made here on the host; the Backend computes.
#pragma once

#include <functional>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "atex/dataset.h"
#include "atex/dynamic_region.h"
#include "atex/metrics.h"
#include "atex/model.h"
#include "atex/status.h"
#include "atex/train/backend.h"
#include "atex/train/communicator.h"
#include "atex/train/config.h"
#include "atex/train/densify.h"
#include "atex/train/texture_growth.h"

namespace atex::train {

struct TrainProgress {
  std::string phase;  // "coarse", "fine", "textures"
  int step = 0;       // within the phase (1-based after the step)
  int total = 0;
  double loss = 0;
  double psnr = 0;    // mean over the step's views
  size_t gaussians = 0;
  std::string event;  // non-empty for densification, growth, rollbacks, evaluations
};
// Return false to stop training (Train then fails with kCancelled after a final checkpoint).
using ProgressCallback = std::function<bool(const TrainProgress&)>;

enum Stages : int { kStage1 = 1, kStage2 = 2, kBothStages = 3 };

struct TrainerOptions {
  TrainConfig config;
  int stages = kBothStages;
  std::string checkpoint_dir;  // periodic checkpoints (empty: none)
  std::string resume_dir;      // continue from a checkpoint written by a previous run
  std::string metrics_csv;     // one row per logged step (empty: none)
  int log_every = 10;          // progress/CSV interval in steps
  ProgressCallback progress;
  // Data parallelism (docs/multi_gpu.md): this rank's communicator, or null for one rank. With
  // R ranks every rank calls Train with the same dataset, options and starting model; rank r
  // trains on its share of each step's views (the batch sizes must be multiples of R), the
  // backend sums the gradients and the loop sums the statistics, so all ranks make identical
  // updates and edits. Only rank 0 reports progress, writes the CSV and checkpoints, and
  // evaluates (the others' summaries have no test metrics); every rank returns the model.
  Communicator* communicator = nullptr;
  // Stop training after this many seconds (0 = no limit): the current phase ends, later
  // phases are skipped, and the asset is written as usual with an event saying so.
  double time_limit_seconds = 0;
};

struct ViewMetrics {
  int camera_id = -1;
  int timestep = -1;
  ImageMetrics metrics;
  // PSNR over the camera's dynamic region (atex/dynamic_region.h); NaN where the camera
  // has one frame (D-NeRF's moving camera), an empty region, or the evaluation skipped it.
  double dynamic_psnr = std::numeric_limits<double>::quiet_NaN();
  double dynamic_fraction = 0;  // share of the camera's pixels in its dynamic region
};
struct EvalResult {
  std::vector<ViewMetrics> views;
  ImageMetrics mean;  // unweighted mean over views
  // Mean of the per-view dynamic_psnr values that are not NaN (NaN if none) and how many there were.
  double dynamic_psnr = std::numeric_limits<double>::quiet_NaN();
  size_t dynamic_views = 0;
};

struct EvalOptions {
  // Also measure the dynamic-region PSNR. The region of a camera comes from all of the
  // dataset's frames of that camera (both splits), whichever subset `views` is.
  bool dynamic_region = true;
  double dynamic_threshold = kDefaultDynamicThreshold;  // τ of atex/dynamic_region.h
  // Threads of the CPU metrics (SSIM dominates); 0: OpenMP's default (every core). Fewer when
  // the evaluation runs beside other CPU work (atex fit evaluates its input beside the plan).
  int metric_threads = 0;
};

struct TrainSummary {
  Asset asset;
  double coarse_seconds = 0, fine_seconds = 0, textures_seconds = 0;
  int coarse_steps = 0, fine_steps = 0, texture_steps = 0;
  std::vector<DensifyReport> densifications;
  std::vector<GrowthReport> growths;
  std::vector<std::string> events;  // rollbacks and other notes, in order
  std::vector<std::string> warnings;  // suspicious settings (CrossCheckConfig), also in events
  bool stopped_by_time_limit = false;
  EvalResult test;                  // test views at the end (empty when the dataset has none)
  uint64_t peak_memory_bytes = 0;
};

// Trains per options.stages. Stage 2 alone needs `initial` (a stage-1 asset with its
// deformation field); stage 1 ignores it. The returned asset carries metadata
// (provenance, config) and per-Gaussian statistics for `atex fit`.
StatusOr<TrainSummary> Train(const Dataset& dataset, Backend& backend, const TrainerOptions& options,
                             const Asset* initial = nullptr);

// Renders `views` with the backend's current model and compares with the dataset's
// images (renders clamped to [0, 1] first, as 3DGS evaluates).
StatusOr<EvalResult> Evaluate(const Dataset& dataset, Backend& backend, const std::vector<View>& views,
                              const RenderRequest& request, const EvalOptions& options = {});

// The scene extent 3DGS uses for learning rates and densification: 1.1 × the largest
// distance of a training camera centre from their mean.
double CameraExtent(const std::vector<View>& views);

// Model state <-> asset (canonical parameters only; moments reset).
ModelState StateFromAsset(const Asset& asset);
// The parameters alone, with empty moments, for a Backend::Load that only renders: the backend
// starts empty moments at zero itself (Backend::Load's contract), where StateFromAsset's two
// zero-filled host copies triple what is copied and uploaded (the fitter loads every candidate
// it measures on a GPU: about 330 MB of zeros per measurement on a Panoptic-sized model).
ModelState RenderStateFromAsset(const Asset& asset);
Asset AssetFromState(const ModelState& state, const Metadata& metadata);
// A request that renders everything `asset` has: its deformation, textures, full SH
// degree and background.
RenderRequest RenderRequestFor(const Asset& asset);

}  // namespace atex::train

namespace atex::train {
// JSON forms for reports (`atex train --json`, `atex eval --json`, benchmarks).
nlohmann::json EvalToJson(const EvalResult& eval);
nlohmann::json SummaryToJson(const TrainSummary& summary);
}  // namespace atex::train
