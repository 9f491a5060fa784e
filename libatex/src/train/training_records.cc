// What the training loop records beside its steps (training_loop.h): per-camera colour fits and
// their reload, the render request of evaluations, checkpoints.
#include "trained_asset.h"
#include "training_loop.h"

namespace atex::train::detail {

Status TrainingLoop::MaybeFitCameraColours(Phase phase, int step, int active_sh_degree) {
  const CameraColourConfig& c = config_.camera_colour;
  if (!c.enabled || phase == Phase::kTextures) return Status::Ok();
  const int stage1_step = (phase == Phase::kCoarse ? 0 : config_.stage1.coarse_iterations) + step + 1;
  const bool due = stage1_step == c.first_step ||
                   (c.interval > 0 && stage1_step > c.first_step && (stage1_step - c.first_step) % c.interval == 0);
  if (!due) return Status::Ok();
  RenderRequest request = EvalRequest(phase);
  request.active_sh_degree = active_sh_degree;
  // Rank 0 fits (the replicas are identical) and sends the corrections to the others.
  nlohmann::json fitted;
  if (dp_.is_root()) {
    ATEX_RETURN_IF_ERROR(colours_.Fit(data_, backend_, request, c));
    fitted = colours_.ToJson();
  }
  ATEX_RETURN_IF_ERROR(dp_.BroadcastJson(&fitted));
  if (!dp_.is_root()) {
    ATEX_ASSIGN_OR_RETURN(colours_, CameraColours::FromJson(fitted));
  }
  Event(StrCat(PhaseName(phase), " step ", step + 1, ": camera colours fitted (", colours_.Summary(), ")"));
  return Status::Ok();
}

Status TrainingLoop::LoadCameraColours(const Metadata& metadata) {
  if (!metadata.extra.contains("camera_colour")) return Status::Ok();
  StatusOr<CameraColours> loaded = CameraColours::FromJson(metadata.extra["camera_colour"]);
  if (!loaded.ok()) return MakeError(loaded.status().code(), "metadata.camera_colour: ", loaded.status().message());
  colours_ = std::move(*loaded);
  if (!colours_.empty()) Event(StrCat("camera colours from the model: ", colours_.Summary()));
  return Status::Ok();
}

RenderRequest TrainingLoop::EvalRequest(Phase phase) const {
  RenderRequest r;
  r.active_sh_degree = config_.stage1.sh_degree;
  r.apply_deformation = phase != Phase::kCoarse;
  r.use_textures = phase == Phase::kTextures && has_texture_pool_;
  r.background = config_.background;
  r.near_plane = config_.near_plane;
  return r;
}

Status TrainingLoop::SaveCheckpoint(Phase phase, int step) {
  if (!dp_.is_root()) return Status::Ok();
  ModelState state;
  ATEX_RETURN_IF_ERROR(backend_.Save(&state));
  nlohmann::json trainer = {{"phase", PhaseName(phase)}, {"step", step},          {"lr_scale", lr_scale_},
                            {"total_steps", total_steps_}, {"config", ConfigToJson(config_)},
                            {"dataset", data_.name()}, {"dataset_kind", DatasetKindName(data_.kind())},
                            {"train_views", data_.train_views().size()}};
  // The writer checks that the metadata's texture mode matches the textures (stage 2
  // starts from a stage-1 asset whose metadata says "none").
  Metadata metadata = metadata_;
  metadata.texture_mode = state.textures ? std::string(TextureModeName(config_.stage2.textures)) : "none";
  if (!colours_.empty()) metadata.extra["camera_colour"] = colours_.ToJson();
  return WriteCheckpoint(options_.checkpoint_dir, state, metadata, trainer);
}

}  // namespace atex::train::detail
