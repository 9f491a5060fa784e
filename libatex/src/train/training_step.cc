// A training phase's steps (training_loop.h): the step request and its learning rates, the
// batch, rollback on non-finite numbers, logging, checkpoints and the time limit; then the
// decisions after a step: densification and pruning (stage 1), texture growth (stage 2).
#include <algorithm>
#include <cmath>

#include "atex/deform.h"
#include "atex/render.h"
#include "atex/train/densify.h"
#include "atex/train/texture_growth.h"
#include "trained_asset.h"
#include "training_loop.h"

namespace atex::train::detail {

int TrainingLoop::Iterations(Phase phase) const {
  switch (phase) {
    case Phase::kCoarse: return config_.stage1.coarse_iterations;
    case Phase::kFine: return config_.stage1.fine_iterations;
    case Phase::kTextures: return config_.stage2.iterations;
  }
  return 0;
}

StepRequest TrainingLoop::MakeRequest(Phase phase, int step) const {
  const Stage1Config& s1 = config_.stage1;
  const LearningRates& lr = s1.lr;
  StepRequest r;
  const bool textures = phase == Phase::kTextures;
  const double position = textures ? lr.position.final : lr.position.At(step);
  r.learning_rates[kGroupPositions] = position * extent_ * lr_scale_;
  r.learning_rates[kGroupRotations] = lr.rotation * lr_scale_;
  r.learning_rates[kGroupLogScales] = lr.log_scale * lr_scale_;
  r.learning_rates[kGroupOpacity] = lr.opacity * lr_scale_;
  r.learning_rates[kGroupShDc] = lr.sh_dc * lr_scale_;
  r.learning_rates[kGroupShRest] = lr.sh_rest * lr_scale_;
  if (phase != Phase::kCoarse) {
    r.learning_rates[kGroupGrid] = (textures ? lr.grid.final : lr.grid.At(step)) * lr_scale_;
    r.learning_rates[kGroupMlp] = (textures ? lr.mlp.final : lr.mlp.At(step)) * lr_scale_;
  }
  if (textures && has_texture_pool_) r.learning_rates[kGroupTexels] = lr.texels * lr_scale_;
  // SH degree grows by one every interval of stage-1 steps (it persists into stage 2).
  const int64_t sh_steps = phase == Phase::kCoarse ? step : s1.coarse_iterations + step;
  r.active_sh_degree = textures ? s1.sh_degree
                                : static_cast<int>(std::min<int64_t>(
                                      s1.sh_degree, sh_steps / std::max(1, s1.sh_increase_interval)));
  r.apply_deformation = phase != Phase::kCoarse;
  r.use_textures = textures && has_texture_pool_;
  r.lambda_dssim = textures ? config_.stage2.lambda_dssim : s1.lambda_dssim;
  if (phase == Phase::kFine || textures) {
    r.plane_tv = s1.regularizer.plane_tv;
    r.time_smoothness = s1.regularizer.time_smoothness;
    r.time_l1 = s1.regularizer.time_l1;
  }
  r.accumulate_densify_stats = !textures && s1.densify.enabled && step < s1.densify.until_step;
  r.accumulate_texture_stats = textures && has_texture_pool_ && config_.stage2.textures == TextureMode::kAdaptive;
  r.time_bins = config_.stage2.time_bins;
  r.time_min = data_.time_min();
  r.time_max = data_.time_max();
  r.background = config_.background;
  r.near_plane = config_.near_plane;
  return r;
}

Status TrainingLoop::RunPhase(Phase phase, int first_step) {
  const int total = Iterations(phase);
  const int batch = phase == Phase::kTextures ? config_.stage2.batch_size : config_.stage1.batch_size;
  const bool same_time = (phase == Phase::kFine && config_.stage1.same_time_batches) ||
                         (phase == Phase::kTextures && config_.stage2.same_time_batches);
  if (batch < 1 || batch % dp_.world_size() != 0) {
    return MakeError(StatusCode::kInvalidArgument, PhaseName(phase), " batch size ", batch,
                     " is not a positive multiple of ", dp_.world_size(), " ranks");
  }
  const auto start = Clock::now();
  const auto& train = data_.train_views();
  const int importance_from = total - std::max<int>(1, static_cast<int>(train.size()) / batch + 1);
  ModelState snapshot;
  bool have_snapshot = false;
  int rollbacks = 0;
  double loss_sum = 0, psnr_sum = 0;
  int logged = 0;
  size_t gaussians = 0;
  {
    Gaussians g;
    ATEX_RETURN_IF_ERROR(backend_.ReadGaussians(&g));
    gaussians = g.size();
  }
  if (phase != Phase::kTextures) ATEX_RETURN_IF_ERROR(backend_.ResetStats(kStatsDensify));
  // Importance is measured over the phase's last epoch only (the final model's view coverage).
  ATEX_RETURN_IF_ERROR(backend_.ResetStats(kStatsImportance));
  if (phase == Phase::kTextures && texel_budget_ == 0) {
    texel_budget_ = static_cast<uint64_t>(
        std::llround(config_.stage2.texel_budget_fraction * 16.0 * static_cast<double>(gaussians)));
  }

  for (int step = first_step; step < total; ++step) {
    // Keep a known-good state to return to if the numbers blow up.
    if (step % kSnapshotInterval == 0) {
      ATEX_RETURN_IF_ERROR(backend_.Save(&snapshot));
      have_snapshot = true;
    }
    StepRequest request = MakeRequest(phase, step);
    request.accumulate_importance = step >= importance_from;
    const std::vector<size_t> picks =
        ShareOfBatch(same_time ? time_schedule_.Views(total_steps_, batch) : schedule_.Views(total_steps_, batch),
                     dp_.rank(), dp_.world_size());
    std::vector<std::shared_ptr<const Image>> images;
    std::vector<TrainView> views;
    ATEX_RETURN_IF_ERROR(BatchViews(picks, &images, &views));
    ATEX_ASSIGN_OR_RETURN(StepResult result, backend_.Step(request, views));
    if (!result.finite) {
      // Name the batch: a corrupt frame shows up as the view that every failing batch shares.
      std::string batch_views;
      for (const TrainView& v : views) batch_views += (batch_views.empty() ? "" : ", ") + v.camera->name;
      if (!have_snapshot || ++rollbacks > kMaxRollbacks) {
        return MakeError(StatusCode::kNumericalError, PhaseName(phase), " step ", step,
                         ": non-finite loss or gradients and no recovery left (", rollbacks - 1,
                         " rollbacks); views of the batch: ", batch_views);
      }
      lr_scale_ *= 0.5;
      ATEX_RETURN_IF_ERROR(backend_.Load(snapshot));
      Event(StrCat(PhaseName(phase), " step ", step, ": NaN/Inf detected (views ", batch_views,
                   "); rolled back to the last snapshot and halved the learning rates (scale ", lr_scale_, ")"));
      step = (step / kSnapshotInterval) * kSnapshotInterval - 1;  // redo from the snapshot
      continue;
    }
    ++total_steps_;
    loss_sum += result.loss;
    for (double p : result.view_psnr) psnr_sum += p / result.view_psnr.size();
    ++logged;

    ATEX_RETURN_IF_ERROR(AfterStep(phase, step, &gaussians));
    ATEX_RETURN_IF_ERROR(MaybeFitCameraColours(phase, step, request.active_sh_degree));
    const bool last = step + 1 == total;
    if ((step + 1) % std::max(1, options_.log_every) == 0 || last) {
      TrainProgress progress{PhaseName(phase), step + 1, total, loss_sum / logged, psnr_sum / logged, gaussians, ""};
      if (csv_) {
        csv_ << progress.phase << ',' << progress.step << ',' << progress.loss << ',' << progress.psnr << ','
             << gaussians << ',' << request.learning_rates[kGroupPositions] << ',' << Seconds(start) << '\n';
      }
      loss_sum = psnr_sum = 0;
      logged = 0;
      bool stop = !Report(progress);
      ATEX_RETURN_IF_ERROR(dp_.AgreeWithRoot(&stop));  // rank 0's callback decides for all
      if (stop) return Cancelled(phase, step + 1);
    }
    if (config_.checkpoint_every > 0 && !options_.checkpoint_dir.empty() &&
        (step + 1) % config_.checkpoint_every == 0 && !last) {
      ATEX_RETURN_IF_ERROR(SaveCheckpoint(phase, step + 1));
    }
    bool out_of_time = options_.time_limit_seconds > 0 && Seconds(run_start_) > options_.time_limit_seconds && !last;
    if (options_.time_limit_seconds > 0) ATEX_RETURN_IF_ERROR(dp_.AgreeWithRoot(&out_of_time));  // rank 0's clock
    if (out_of_time) {
      summary_.stopped_by_time_limit = true;
      Event(StrCat("time limit of ", options_.time_limit_seconds, " s reached at ", PhaseName(phase), " step ",
                   step + 1, " of ", total, ": stopping early"));
      AddPhaseTime(phase, Seconds(start), step + 1 - first_step);
      return Status::Ok();
    }
    if (config_.eval_every > 0 && (step + 1) % config_.eval_every == 0 && !last) {
      ATEX_RETURN_IF_ERROR(dp_.CheckReplicasAgree(backend_, StrCat(PhaseName(phase), " step ", step + 1)));
      if (dp_.is_root() && !data_.test_views().empty()) {  // a report only: rank 0 evaluates
        ATEX_ASSIGN_OR_RETURN(EvalResult eval, Evaluate(data_, backend_, ProgressEvalViews(), EvalRequest(phase),
                                                        {.dynamic_region = false}));
        Event(StrCat(PhaseName(phase), " step ", step + 1, ": test PSNR ", eval.mean.psnr, " SSIM ", eval.mean.ssim));
      }
    }
  }
  ATEX_RETURN_IF_ERROR(dp_.CheckReplicasAgree(backend_, StrCat("the end of the ", PhaseName(phase), " phase")));
  AddPhaseTime(phase, Seconds(start), total - first_step);
  return Status::Ok();
}

Status TrainingLoop::BatchViews(const std::vector<size_t>& picks, std::vector<std::shared_ptr<const Image>>* images,
                                std::vector<TrainView>* views) {
  const auto& train = data_.train_views();
  for (size_t index : picks) {
    const View& v = train[index];
    const uint64_t key = static_cast<uint64_t>(index) + 1;
    const ColourAffine& colour = colours_.For(v.camera_id);
    // A view away from its home rank (ShareOfBatch) is rendered here this once: unless the
    // configuration keeps every image everywhere, its image is not kept on this device, so that
    // each device holds only its rank's share of the images.
    const bool keep = config_.images_on_every_gpu || HomeRank(index, dp_.world_size()) == dp_.rank();
    if (backend_.HasTarget(key)) {  // on the device already: no host decode
      views->push_back({&v.camera, nullptr, key, colour, keep});
      continue;
    }
    ATEX_ASSIGN_OR_RETURN(auto image, data_.LoadImage(v));
    images->push_back(image);
    views->push_back({&v.camera, images->back().get(), key, colour, keep});
  }
  return Status::Ok();
}

void TrainingLoop::AddPhaseTime(Phase phase, double seconds, int steps) {
  switch (phase) {
    case Phase::kCoarse: summary_.coarse_seconds += seconds, summary_.coarse_steps += steps; break;
    case Phase::kFine: summary_.fine_seconds += seconds, summary_.fine_steps += steps; break;
    case Phase::kTextures: summary_.textures_seconds += seconds, summary_.texture_steps += steps; break;
  }
}

Status TrainingLoop::AfterStep(Phase phase, int step, size_t* gaussians) {
  const int done = step + 1;
  if (phase == Phase::kTextures) {
    const auto& steps = config_.stage2.growth_steps;
    if (config_.stage2.textures != TextureMode::kAdaptive || !has_texture_pool_ ||
        std::find(steps.begin(), steps.end(), done) == steps.end()) {
      return Status::Ok();
    }
    TrainingStats stats;
    ATEX_RETURN_IF_ERROR(dp_.ReadStats(backend_, kStatsTexture, &stats));  // summed over the ranks
    ModelState layout;
    ATEX_RETURN_IF_ERROR(backend_.Save(&layout));
    const GrowthEvidence evidence = ComputeGrowthEvidence(stats.texture, config_.stage2.ablations);
    GrowthReport report;
    ATEX_ASSIGN_OR_RETURN(TextureResize resize,
                          PlanTextureGrowth(*layout.textures, evidence, config_.stage2, texel_budget_, &report));
    ATEX_RETURN_IF_ERROR(backend_.ResizeTextures(resize));
    ATEX_RETURN_IF_ERROR(backend_.ResetStats(kStatsTexture));
    summary_.growths.push_back(report);
    Event(StrCat("growth at step ", done, ": ", report.grown, " of ", report.candidates, " candidates grew (u ",
                 report.grown_u_only, ", v ", report.grown_v_only, ", both ", report.grown_both, "), texels ",
                 report.texels_before, " -> ", report.texels_after, " (budget ", report.texel_budget, ", ",
                 report.rejected_budget, " refused)"));
    return Status::Ok();
  }
  const DensifyConfig& d = config_.stage1.densify;
  if (!d.enabled) return Status::Ok();
  const bool reset_here = d.opacity_reset_interval > 0 && done % d.opacity_reset_interval == 0 &&
                          (phase == Phase::kCoarse || d.opacity_reset_in_fine);
  const bool densify_here = done > d.from_step && done < d.until_step && done % d.interval == 0;
  if (!densify_here && !reset_here) return Status::Ok();
  GaussianEdit edit;
  DensifyReport report;
  if (densify_here) {
    TrainingStats stats;
    ATEX_RETURN_IF_ERROR(dp_.ReadStats(backend_, kStatsDensify, &stats));  // summed (radii: max) over the ranks
    Gaussians canonical;
    ATEX_RETURN_IF_ERROR(backend_.ReadGaussians(&canonical));
    // Size pruning starts once the stage is past one opacity-reset interval (4DGaussians).
    const bool prune_size = d.opacity_reset_interval > 0 && done > d.opacity_reset_interval;
    std::vector<uint16_t> observers;
    if (d.min_observing_cameras > 0) {
      if (observing_cameras_.empty()) {
        for (const View* v : FirstTimestepViews(data_.train_views())) observing_cameras_.push_back(v->camera);
      }
      observers = CountObservingCameras(canonical, observing_cameras_, config_.near_plane);
    }
    ATEX_ASSIGN_OR_RETURN(edit, PlanDensification(canonical, stats.densify, d, extent_, prune_size,
                                                  config_.seed + total_steps_, &report, &observers));
  } else {
    Gaussians canonical;
    ATEX_RETURN_IF_ERROR(backend_.ReadGaussians(&canonical));
    edit = PlanPrune(canonical, {});  // keep everyone; only the opacity reset below
    report.before = report.after = canonical.size();
  }
  if (reset_here) {
    edit.cap_opacity_logit = std::log(0.01f / 0.99f);  // 3DGS/4DGaussians: opacity capped at 0.01
    Event(StrCat(PhaseName(phase), " step ", done, ": opacity reset"));
  }
  if (edit.source.empty() && report.before > 0) {
    // Nothing left to train or render: stop with the cause instead of carrying on empty.
    return MakeError(StatusCode::kNumericalError, PhaseName(phase), " step ", done, ": pruning would remove all ",
                     report.before, " Gaussians (min_opacity ", d.min_opacity, ", world-size limit ",
                     d.max_world_scale_fraction, " x extent); lower stage1.densify.min_opacity or check the data");
  }
  ATEX_RETURN_IF_ERROR(backend_.ApplyEdit(edit));
  summary_.densifications.push_back(report);
  *gaussians = report.after;
  return Status::Ok();
}

}  // namespace atex::train::detail
