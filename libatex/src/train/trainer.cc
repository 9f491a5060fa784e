// atex::train::Train, and the training loop's set-up, phase order and final asset
// (training_loop.h: a phase's steps are in training_step.cc, camera colours and checkpoints in
// training_records.cc).
#include "atex/train/trainer.h"

#include <algorithm>
#include <cmath>
#include <tuple>

#include "atex/deform.h"
#include "atex/init.h"
#include "atex/render.h"
#include "atex/train/config_check.h"
#include "stage1_init.h"
#include "trained_asset.h"
#include "training_loop.h"

namespace atex::train::detail {

static std::vector<double> ViewTimes(const std::vector<View>& views) {
  std::vector<double> times;
  times.reserve(views.size());
  for (const View& v : views) times.push_back(v.camera.time);
  return times;
}

const char* PhaseName(Phase p) {
  switch (p) {
    case Phase::kCoarse: return "coarse";
    case Phase::kFine: return "fine";
    case Phase::kTextures: return "textures";
  }
  return "?";
}

TrainingLoop::TrainingLoop(const Dataset& dataset, Backend& backend, const TrainerOptions& options)
    : data_(dataset), backend_(backend), options_(options), config_(options.config), dp_(options.communicator),
      schedule_(config_.seed, dataset.train_views().size()),
      time_schedule_(config_.seed, ViewTimes(dataset.train_views())) {}

StatusOr<TrainSummary> TrainingLoop::Run(const Asset* initial) {
  if (data_.train_views().empty()) return MakeError(StatusCode::kInvalidArgument, "dataset has no training views");
  // Every value in range and no contradiction with the dataset before anything trains.
  ATEX_RETURN_IF_ERROR(CrossCheckConfig(config_, data_, options_.stages, &summary_.warnings));
  for (const std::string& w : summary_.warnings) Event("warning: " + w);
  extent_ = CameraExtent(data_.train_views());
  if (!options_.metrics_csv.empty() && dp_.is_root()) {
    csv_.open(options_.metrics_csv, std::ios::out | std::ios::trunc);
    if (!csv_) return MakeError(StatusCode::kIoError, "cannot write ", options_.metrics_csv);
    csv_ << "phase,step,loss,psnr,gaussians,lr_position,seconds\n";
  }
  Phase start_phase = Phase::kCoarse;
  int start_step = 0;
  if (!options_.resume_dir.empty()) {
    ATEX_ASSIGN_OR_RETURN(Checkpoint cp, ReadCheckpoint(options_.resume_dir));
    ATEX_RETURN_IF_ERROR(CheckResumable(cp));
    metadata_ = cp.metadata;
    const std::string phase = cp.trainer.value("phase", "coarse");
    start_phase = phase == "fine" ? Phase::kFine : phase == "textures" ? Phase::kTextures : Phase::kCoarse;
    start_step = cp.trainer.value("step", 0);
    lr_scale_ = cp.trainer.value("lr_scale", 1.0);
    total_steps_ = cp.trainer.value("total_steps", 0);
    ATEX_RETURN_IF_ERROR(backend_.Load(cp.state));
    ATEX_RETURN_IF_ERROR(LoadCameraColours(metadata_));
    Event(StrCat("resumed from ", options_.resume_dir, " at ", PhaseName(start_phase), " step ", start_step));
  } else if (options_.stages & kStage1) {
    ATEX_RETURN_IF_ERROR(InitializeStage1());
  } else {
    if (initial == nullptr || !initial->deformation) {
      return MakeError(StatusCode::kInvalidArgument,
                       "stage 2 alone needs a stage-1 asset with a deformation field (--init)");
    }
    for (int k = 0; k < 3; ++k) {
      if (std::abs(initial->metadata.background[k] - config_.background[k]) > 1e-6f) {
        return MakeError(StatusCode::kInvalidArgument, "background [", config_.background[0], ",",
                         config_.background[1], ",", config_.background[2], "] differs from the --init asset's [",
                         initial->metadata.background[0], ",", initial->metadata.background[1], ",",
                         initial->metadata.background[2], "], the one its stage-1 model was trained on");
      }
    }
    metadata_ = initial->metadata;
    ATEX_RETURN_IF_ERROR(backend_.Load(StateFromAsset(*initial)));
    ATEX_RETURN_IF_ERROR(LoadCameraColours(metadata_));
    start_phase = Phase::kTextures;
  }

  const std::vector<Phase> phases = PhasesToRun(start_phase);
  PreloadTrainingImages();
  run_start_ = Clock::now();
  for (Phase phase : phases) {
    if (summary_.stopped_by_time_limit) break;
    const int first = phase == start_phase ? start_step : 0;
    if (phase == Phase::kTextures && first == 0) {
      if (initial != nullptr && initial->textures && !(options_.stages & kStage1) && options_.resume_dir.empty()) {
        // Fine-tuning an asset that already has its pool (e.g. `atex fit --finetune`): keep it.
        texel_budget_ = initial->textures->texel_count();
        has_texture_pool_ = true;
        Event(StrCat("kept the initial asset's ", initial->textures->texel_count(), " texels"));
      } else if (config_.stage2.textures != TextureMode::kNone) {
        ATEX_RETURN_IF_ERROR(AttachTextures());
      }
    }
    if (phase == Phase::kTextures && first > 0) has_texture_pool_ = config_.stage2.textures != TextureMode::kNone;
    if (phase == Phase::kFine && first == 0 && config_.stage1.fast_objects.enabled) {
      ATEX_ASSIGN_OR_RETURN(std::string added, AddFastObjectSeeds(data_, config_, backend_));
      Event(added);
    }
    ATEX_RETURN_IF_ERROR(RunPhase(phase, first));
  }
  return Finish();
}

Status TrainingLoop::CheckResumable(const Checkpoint& cp) {
  const std::string dir = options_.resume_dir;
  if (cp.trainer.contains("dataset")) {
    const std::string name = cp.trainer.value("dataset", "");
    const size_t views = cp.trainer.value("train_views", size_t{0});
    if (name != data_.name() || (views != 0 && views != data_.train_views().size())) {
      return MakeError(StatusCode::kInvalidArgument, "--resume ", dir, ": the checkpoint was trained on dataset '",
                       name, "' (", views, " training views), not '", data_.name(), "' (",
                       data_.train_views().size(), ")");
    }
  } else {
    Event(StrCat("note: checkpoint ", dir, " does not name its dataset (written before issue 24); not checked"));
  }
  if (cp.trainer.contains("config")) {
    ATEX_ASSIGN_OR_RETURN(TrainConfig saved, ConfigFromJson(cp.trainer.at("config"), config_));
    std::vector<std::string> changed;
    ATEX_RETURN_IF_ERROR(CheckResumeConfig(saved, config_, &changed).WithContext(dir));
    for (const std::string& c : changed) Event("resume: changed " + c);
  }
  return Status::Ok();
}

std::vector<Phase> TrainingLoop::PhasesToRun(Phase start) const {
  std::vector<Phase> phases;
  if (options_.stages & kStage1) {
    phases.push_back(Phase::kCoarse);
    phases.push_back(Phase::kFine);
  }
  // Stage 2 without textures is the untextured control of a stage-2 run (the same joint
  // fine-tuning of the Gaussians and the deformation, no texture pool) when stage 2 alone is
  // asked for; after stage 1 in the same run, "none" means plain 4DGS: stage 1 only.
  const bool textures = config_.stage2.textures != TextureMode::kNone;
  if ((options_.stages & kStage2) && (textures || !(options_.stages & kStage1))) {
    phases.push_back(Phase::kTextures);
  }
  auto it = std::find(phases.begin(), phases.end(), start);
  return it == phases.end() ? std::vector<Phase>{} : std::vector<Phase>(it, phases.end());
}

const std::vector<View>& TrainingLoop::ProgressEvalViews() {
  const std::vector<View>& all = data_.test_views();
  const size_t wanted = config_.eval_views > 0 ? static_cast<size_t>(config_.eval_views) : all.size();
  if (wanted >= all.size()) return all;
  if (progress_eval_views_.empty()) {
    for (size_t i = 0; i < wanted; ++i) progress_eval_views_.push_back(all[i * all.size() / wanted]);
  }
  return progress_eval_views_;
}

void TrainingLoop::PreloadTrainingImages() {
  const std::vector<View>& train = data_.train_views();
  const long long n = static_cast<long long>(train.size());
  const uint64_t pixels = n > 0 ? uint64_t(train[0].camera.width) * train[0].camera.height : 0;
  if (n == 0 || pixels * 3 * sizeof(float) * uint64_t(n) > data_.cache_limit()) return;
#pragma omp parallel for schedule(dynamic, 1)
  for (long long i = 0; i < n; ++i) (void)data_.LoadImage(train[i]);
}

Status TrainingLoop::InitializeStage1() {
  ATEX_ASSIGN_OR_RETURN(Stage1Start start, InitialStage1State(data_, config_));
  Event(start.event);
  metadata_ = std::move(start.metadata);
  return backend_.Load(start.state);
}

Status TrainingLoop::AttachTextures() {
  Gaussians canonical;
  ATEX_RETURN_IF_ERROR(backend_.ReadGaussians(&canonical));
  ATEX_ASSIGN_OR_RETURN(TexturePool pool, atex::AttachTextures(canonical, config_.stage2.textures));
  texel_budget_ = static_cast<uint64_t>(std::llround(config_.stage2.texel_budget_fraction * 16.0 *
                                                     static_cast<double>(canonical.size())));
  Event(StrCat("attached ", TextureModeName(config_.stage2.textures), " textures to ", canonical.size(),
               " Gaussians (texel budget ", texel_budget_, ")"));
  if (config_.stage2.textures == TextureMode::kAdaptive) NoteLateGrowth();
  has_texture_pool_ = true;
  return backend_.AttachTextures(pool);
}

void TrainingLoop::NoteLateGrowth() {
  const int iterations = config_.stage2.iterations;
  int last = 0;
  for (int step : config_.stage2.growth_steps) last = std::max(last, step);
  if (last == 0 || iterations <= 0) return;
  if (last > iterations) {  // a growth at the last step still runs (after it), with 0 steps left
    Event(StrCat("note: growth step ", last, " is not reached in ", iterations, " stage-2 steps"));
  } else if (2 * last > iterations) {
    Event(StrCat("note: the last growth (step ", last, ") leaves ", iterations - last, " of ", iterations,
                 " stage-2 steps to the grown textures; the paper grows at 10 % and 20 % of its schedule "
                 "(stage2.growth_steps)"));
  }
}

Status TrainingLoop::Cancelled(Phase phase, int step) {
  if (!options_.checkpoint_dir.empty()) ATEX_RETURN_IF_ERROR(SaveCheckpoint(phase, step));
  return MakeError(StatusCode::kCancelled, "training stopped at ", PhaseName(phase), " step ", step,
                   options_.checkpoint_dir.empty() ? "" : " (checkpoint written)");
}

void TrainingLoop::Event(const std::string& text) {
  summary_.events.push_back(text);
  TrainProgress p;
  p.event = text;
  Report(p);
}

StatusOr<TrainSummary> TrainingLoop::Finish() {
  ModelState state;
  ATEX_RETURN_IF_ERROR(backend_.Save(&state));
  const bool textured = state.textures.has_value();
  metadata_.texture_mode = textured ? std::string(TextureModeName(config_.stage2.textures)) : "none";
  metadata_.background = config_.background;
  metadata_.extra["trainer"] = {{"name", "atex train"},
                                {"backend", backend_.name()},
                                {"dataset", data_.name()},
                                {"seed", config_.seed},
                                {"config", ConfigToJson(config_)}};
  // Training-only per-camera colour corrections: test views render without them.
  if (!colours_.empty()) metadata_.extra["camera_colour"] = colours_.ToJson();
  // Bounds of the final canonical positions.
  if (state.gaussians.size() > 0) {
    std::tie(metadata_.bounds_min, metadata_.bounds_max) = PositionBounds(state.gaussians);
  }
  summary_.asset = AssetFromState(state, metadata_);
  TrainingStats stats;
  ATEX_RETURN_IF_ERROR(dp_.ReadStats(backend_, kStatsImportance | (textured ? kStatsTexture : 0), &stats));
  summary_.asset.stats = FitterStats(stats, state.gaussians.size(), textured, config_.stage2.ablations);
  if (!data_.test_views().empty() && dp_.is_root()) {  // rank 0 evaluates (the other ranks' summaries: no test)
    const Phase last = textured ? Phase::kTextures : Phase::kFine;
    ATEX_ASSIGN_OR_RETURN(summary_.test, Evaluate(data_, backend_, data_.test_views(), EvalRequest(last),
                                                   {.dynamic_region = true}));
  }
  summary_.peak_memory_bytes = backend_.PeakMemoryBytes();
  return std::move(summary_);
}

}  // namespace atex::train::detail

namespace atex::train {

StatusOr<TrainSummary> Train(const Dataset& dataset, Backend& backend, const TrainerOptions& options,
                             const Asset* initial) {
  detail::TrainingLoop loop(dataset, backend, options);
  // The backend sums gradients across the ranks while it trains for this loop.
  ATEX_RETURN_IF_ERROR(backend.SetCommunicator(options.communicator));
  StatusOr<TrainSummary> summary = loop.Run(initial);
  if (!summary.ok() && options.communicator != nullptr && options.communicator->world_size() > 1) {
    // The other ranks may wait for this one in a collective: let them fail now.
    options.communicator->Abort(summary.status().ToString());
  }
  const Status detached = backend.SetCommunicator(nullptr);
  if (summary.ok() && !detached.ok()) return detached;
  return summary;
}

}  // namespace atex::train
