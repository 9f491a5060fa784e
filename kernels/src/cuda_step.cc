// The CUDA backend's training step: per view deform → render → loss → backward (one
// view's activations alive at a time), then one fused Adam update per group.
#include <algorithm>
#include <cmath>
#include <numeric>

#include "cuda_backend_impl.h"
#include "deform/time_window_cuda.h"
#include "loss/colour_affine.h"
#include "optim/adam_cuda.h"

namespace atex::cuda::internal {

StatusOr<train::StepResult> CudaBackend::Step(const train::StepRequest& request,
                                              std::span<const train::TrainView> views) {
  if (views.empty() || views.size() > kMaxBatch) {
    return MakeError(StatusCode::kInvalidArgument, "CUDA backend: batch of ", views.size(), " views (1..",
                     kMaxBatch, ")");
  }
  if (request.apply_deformation && !has_deformation_) {
    return MakeError(StatusCode::kInvalidArgument, "step asks for deformation but the model has none");
  }
  const bool textured = request.use_textures && has_textures_;
  // The global batch (backend.h, SetCommunicator): with R ranks every view's loss is divided by
  // R × views.size(), so that the summed gradients are those of one GPU with all the views.
  const int world = comm_ != nullptr ? comm_->world_size() : 1;
  const float batch = static_cast<float>(views.size()) * static_cast<float>(world);
  ATEX_RETURN_IF_ERROR(ZeroGrads());
  ATEX_RETURN_IF_ERROR(scalars_.Zero(stream_));
  ATEX_RETURN_IF_ERROR(flag_.Zero(stream_));
  train::StepResult result;
  result.view_psnr.resize(views.size());

  ATEX_RETURN_IF_ERROR(Mark("setup"));
  // The batch's cached targets become the most recent first, so that uploading the others
  // cannot evict one that the caller sent without its image (HasTarget).
  for (const train::TrainView& view : views) {
    auto it = targets_.find(view.image_key);
    if (it != targets_.end()) lru_.splice(lru_.begin(), lru_, it->second.second);
  }
  // Views of one time share one deformation pass: the deformed Gaussians are computed
  // once, the views' render gradients accumulate into the same dL/d(deformed) buffers,
  // and the deformation backward runs once for their sum (it is linear in them).
  const std::vector<size_t> order = TimeGroupedOrder(views);
  for (size_t position = 0; position < order.size(); ++position) {
    const size_t k = order[position];
    const Camera& camera = *views[k].camera;
    const bool first_of_time = position == 0 || views[order[position - 1]].camera->time != camera.time;
    const bool last_of_time =
        position + 1 == order.size() || views[order[position + 1]].camera->time != camera.time;
    ATEX_ASSIGN_OR_RETURN(const float* target, Target(views[k]));
    ATEX_RETURN_IF_ERROR(Mark("targets"));
    const detail::CameraModel<float> cam = detail::MakeCameraModel<float>(camera, request.near_plane);
    RenderInputs inputs;
    RenderGradients grads;
    ATEX_RETURN_IF_ERROR(PrepareView(request, camera.time, textured, first_of_time, &inputs, &grads));
    ATEX_RETURN_IF_ERROR(Mark("deform_forward"));
    const size_t pixels = size_t(camera.width) * camera.height;
    ATEX_RETURN_IF_ERROR(image_.Resize(pixels * 3));
    ATEX_RETURN_IF_ERROR(image_grad_.Resize(pixels * 3));
    ATEX_RETURN_IF_ERROR(render_->Forward(cam, inputs, image_.data(), nullptr,
                                          request.accumulate_importance ? importance_.data() : nullptr));
    ATEX_RETURN_IF_ERROR(Mark("render_forward"));
    // The camera's colour correction acts on a copy: the backward pass reads the render itself.
    const train::ColourAffine& colour = views[k].colour;
    const float* compared = image_.data();
    if (!colour.IsIdentity()) {
      ATEX_RETURN_IF_ERROR(corrected_.Resize(pixels * 3));
      ATEX_RETURN_IF_ERROR(loss_detail::LaunchColourAffine(image_.data(), corrected_.data(), pixels, colour, stream_));
      compared = corrected_.data();
    }
    ATEX_RETURN_IF_ERROR(loss_->Compute(compared, target, camera.width, camera.height,
                                        static_cast<float>(request.lambda_dssim), 1.0f / batch, image_grad_.data(),
                                        scalars_.data(), scalars_.data() + 2 + k));
    if (!colour.IsIdentity()) {
      ATEX_RETURN_IF_ERROR(loss_detail::LaunchScaleGradient(image_grad_.data(), pixels, colour, stream_));
    }
    ATEX_RETURN_IF_ERROR(Mark("loss"));
    RenderStats stats;
    const bool with_stats = request.accumulate_densify_stats || (request.accumulate_texture_stats && textured);
    if (with_stats) stats = MakeStats(request, camera, batch, textured);
    ATEX_RETURN_IF_ERROR(
        render_->Backward(cam, inputs, image_grad_.data(), nullptr, grads, with_stats ? &stats : nullptr));
    ATEX_RETURN_IF_ERROR(Mark("render_backward"));
    if (request.apply_deformation && last_of_time) {
      ++deform_passes_;
      ATEX_RETURN_IF_ERROR(deform_->Backward(deform_layout_, grid_.value.data(), mlp_.value.data(),
                                             static_cast<int>(count_), sh_coeffs_, static_cast<float>(camera.time),
                                             Canonical(), DeformedGrads(), grid_.grad.data(), mlp_.grad.data(),
                                             CanonicalGrads()));
      ATEX_RETURN_IF_ERROR(Mark("deform_backward"));
    }
  }
  // Summed across the ranks before the regularisers, which depend on the parameters alone and are
  // added once on every rank.
  if (world > 1) {
    ATEX_RETURN_IF_ERROR(ReduceGradients(request, textured));
    // With --profile: the all-reduce's share of the step, waits for the slower ranks included
    // (what overlapping it with the backward could at most save; BENCHMARKS.md, issue 25).
    ATEX_RETURN_IF_ERROR(Mark("all_reduce"));
  }
  if (request.apply_deformation &&
      (request.plane_tv > 0 || request.time_smoothness > 0 || request.time_l1 > 0)) {
    ATEX_RETURN_IF_ERROR(deform_->Regularizer(deform_layout_, grid_.value.data(),
                                              static_cast<float>(request.plane_tv),
                                              static_cast<float>(request.time_smoothness),
                                              static_cast<float>(request.time_l1), grid_.grad.data(),
                                              scalars_.data() + 1));
  }
  ATEX_RETURN_IF_ERROR(FlagNonFiniteGrads(request, textured));

  std::vector<float> scalars;
  ATEX_RETURN_IF_ERROR(scalars_.Download(&scalars, stream_));
  std::vector<int> flag;
  ATEX_RETURN_IF_ERROR(flag_.Download(&flag, stream_));
  // With several ranks scalars[0] is already the loss over all ranks' views (ReduceGradients summed
  // it with the gradients; a NaN on one rank reaches all of them). The flag needs no sum: it was
  // raised on the summed gradients, the same on every rank.
  result.photometric_loss = scalars[0];
  result.loss = scalars[0] + scalars[1];
  for (size_t k = 0; k < views.size(); ++k) {
    const double mse = scalars[2 + k] / (3.0 * views[k].camera->width * views[k].camera->height);
    result.view_psnr[k] = mse > 0 ? -10.0 * std::log10(mse) : 99.0;
  }
  result.finite = flag[0] == 0 && std::isfinite(result.loss);
  if (!result.finite) return result;  // no update: the trainer rolls back
  ATEX_RETURN_IF_ERROR(Mark("regularizer_and_checks"));
  ATEX_RETURN_IF_ERROR(ApplyAdam(request, textured));
  ATEX_RETURN_IF_ERROR(Mark("adam"));
  ATEX_RETURN_IF_ERROR(TrackMemory());
  if (options_.profile) ++profiled_steps_;
  return result;
}

// The order in which Step visits a batch's views: by time (stable), so that the views
// of one time are adjacent and share a deformation pass.
std::vector<size_t> CudaBackend::TimeGroupedOrder(std::span<const train::TrainView> views) {
  std::vector<size_t> order(views.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return views[a].camera->time < views[b].camera->time; });
  return order;
}

// Deforms the canonical Gaussians to `time` into the d_* buffers and zeroes their
// gradients (g_*), which the views of that time then accumulate.
Status CudaBackend::DeformAt(double time) {
  for (auto [buffer, width] : {std::pair{&d_positions_, 3}, std::pair{&d_log_scales_, 3},
                               std::pair{&d_rotations_, 4}, std::pair{&d_opacity_, 1},
                               std::pair{&d_sh_, 3 * sh_coeffs_}, std::pair{&g_positions_, 3},
                               std::pair{&g_log_scales_, 3}, std::pair{&g_rotations_, 4},
                               std::pair{&g_opacity_, 1}, std::pair{&g_sh_, 3 * sh_coeffs_}}) {
    ATEX_RETURN_IF_ERROR(buffer->Resize(count_ * width));
  }
  for (auto* b : {&g_positions_, &g_log_scales_, &g_rotations_, &g_opacity_, &g_sh_}) {
    ATEX_RETURN_IF_ERROR(b->Zero(stream_));
  }
  ATEX_RETURN_IF_ERROR(deform_->Forward(deform_layout_, grid_.value.data(), mlp_.value.data(),
                                        static_cast<int>(count_), sh_coeffs_, static_cast<float>(time), Canonical(),
                                        Deformed()));
  if (!has_time_windows_) return Status::Ok();
  return ApplyTimeWindows(time_windows_.data(), d_opacity_.data(), count_, static_cast<float>(time), stream_);
}

// Fills the render inputs of one view: the canonical Gaussians (coarse stage) or the
// deformed ones at `time`, and where their gradients go. `new_time`: deform and zero
// the deformed gradients; false: the previous view had the same time, so the deformed
// Gaussians are current and their gradients keep accumulating.
Status CudaBackend::PrepareView(const train::StepRequest& request, double time, bool textured, bool new_time,
                                RenderInputs* in, RenderGradients* grads) {
  in->count = static_cast<int>(count_);
  in->sh_coeffs = sh_coeffs_;
  in->active_sh_degree = std::min(request.active_sh_degree, sh_degree_);
  for (int k = 0; k < 3; ++k) in->background[k] = request.background[k];
  if (request.apply_deformation) {
    if (new_time) ATEX_RETURN_IF_ERROR(DeformAt(time));
    const GaussianTensors d = Deformed(), g = DeformedGrads();
    in->positions = d.positions;
    in->rotations = d.rotations;
    in->log_scales = d.log_scales;
    in->opacity = d.opacity;
    in->sh = d.sh;
    *grads = {g.positions, g.rotations, g.log_scales, g.opacity, g.sh, nullptr};
  } else {
    in->positions = positions_.value.data();
    in->rotations = rotations_.value.data();
    in->log_scales = log_scales_.value.data();
    in->opacity = opacity_.value.data();
    in->sh = sh_.value.data();
    *grads = {positions_.grad.data(), rotations_.grad.data(), log_scales_.grad.data(), opacity_.grad.data(),
              sh_.grad.data(), nullptr};
  }
  if (textured) {
    in->texels = texels_.value.data();
    in->texel_offsets = offsets_.data();
    in->texture_layout = layout_device_.data();
    grads->texels = texels_.grad.data();
  }
  return Status::Ok();
}

RenderStats CudaBackend::MakeStats(const train::StepRequest& request, const Camera& camera, float batch,
                                   bool textured) {
  RenderStats s;
  s.grad_scale = batch;  // the batch loss is the mean of the views' losses
  if (request.accumulate_densify_stats) {
    s.grad_norm_sum = grad_norm_sum_.data();
    s.visible_count = visible_count_.data();
    s.max_radius = max_radius_.data();
  }
  if (request.accumulate_texture_stats && textured) {
    if (bins_ != request.time_bins) {
      bins_ = request.time_bins;
      (void)ResetStats(train::kStatsTexture);
    }
    const double span = request.time_max - request.time_min;
    const double unit = span > 0 ? (camera.time - request.time_min) / span : 0.0;
    s.bins = bins_;
    s.bin = std::clamp(static_cast<int>(std::floor(unit * bins_)), 0, bins_ - 1);
    s.demand_sum = demand_sum_.data();
    s.bin_count = bin_count_.data();
    s.scale_u_sum = scale_u_sum_.data();
    s.scale_v_sum = scale_v_sum_.data();
  }
  return s;
}

Status CudaBackend::ZeroGrads() {
  for (Param* p : {&positions_, &rotations_, &log_scales_, &opacity_, &sh_})
    ATEX_RETURN_IF_ERROR(p->grad.Zero(stream_));
  if (has_textures_) ATEX_RETURN_IF_ERROR(texels_.grad.Zero(stream_));
  if (has_deformation_) {
    ATEX_RETURN_IF_ERROR(grid_.grad.Zero(stream_));
    ATEX_RETURN_IF_ERROR(mlp_.grad.Zero(stream_));
  }
  return Status::Ok();
}

Status CudaBackend::SetCommunicator(train::Communicator* comm) {
  if (comm != nullptr && comm->world_size() > 1) {
    // Refuse a host-only communicator now rather than at the first step.
    ATEX_RETURN_IF_ERROR(comm->AllReduceSumDevice({}, stream_));
  }
  comm_ = comm;
  return Status::Ok();
}

Status CudaBackend::ReduceGradients(const train::StepRequest& request, bool textured) {
  std::vector<train::Communicator::DeviceBuffer> buffers;
  for (Param* p : {&positions_, &rotations_, &log_scales_, &opacity_, &sh_})
    buffers.push_back({p->grad.data(), p->grad.size()});
  if (textured) buffers.push_back({texels_.grad.data(), texels_.grad.size()});
  if (request.apply_deformation) {
    buffers.push_back({grid_.grad.data(), grid_.grad.size()});
    buffers.push_back({mlp_.grad.data(), mlp_.grad.size()});
  }
  // The photometric loss (scalars_[0]) rides in the same grouped all-reduce: summing it on the host
  // instead cost a second collective and a host wait per step (BENCHMARKS.md, issue 25).
  buffers.push_back({scalars_.data(), 1});
  return comm_->AllReduceSumDevice(buffers, stream_);
}

Status CudaBackend::FlagNonFiniteGrads(const train::StepRequest& request, bool textured) {
  for (Param* p : {&positions_, &rotations_, &log_scales_, &opacity_, &sh_}) {
    ATEX_RETURN_IF_ERROR(FlagNonFinite(p->grad.data(), p->grad.size(), flag_.data(), stream_));
  }
  if (textured) ATEX_RETURN_IF_ERROR(FlagNonFinite(texels_.grad.data(), texels_.grad.size(), flag_.data(), stream_));
  if (request.apply_deformation) {
    ATEX_RETURN_IF_ERROR(FlagNonFinite(grid_.grad.data(), grid_.grad.size(), flag_.data(), stream_));
    ATEX_RETURN_IF_ERROR(FlagNonFinite(mlp_.grad.data(), mlp_.grad.size(), flag_.data(), stream_));
  }
  return Status::Ok();
}

Status CudaBackend::ApplyAdam(const train::StepRequest& request, bool textured) {
  ForgetHeldKeys();  // the values change (LoadKeyed copies every array again)
  const auto& lr = request.learning_rates;
  auto step = [&](Param& p, int group, float lr_first, float lr_rest, int period, int split) -> Status {
    if (lr_first == 0.0f && lr_rest == 0.0f) return Status::Ok();
    AdamLaunch a;
    a.params = p.value.data();
    a.grads = p.grad.data();
    a.m = p.m.data();
    a.v = p.v.data();
    a.count = p.value.size();
    a.lr_first = lr_first;
    a.lr_rest = lr_rest;
    a.period = period;
    a.split = split;
    a.beta1 = static_cast<float>(options_.adam.beta1);
    a.beta2 = static_cast<float>(options_.adam.beta2);
    a.epsilon = static_cast<float>(options_.adam.epsilon);
    a.step = ++adam_steps_[group];
    return AdamStep(a, stream_);
  };
  auto f = [](double x) { return static_cast<float>(x); };
  ATEX_RETURN_IF_ERROR(step(positions_, train::kGroupPositions, f(lr[train::kGroupPositions]),
                            f(lr[train::kGroupPositions]), 1, 1));
  ATEX_RETURN_IF_ERROR(step(rotations_, train::kGroupRotations, f(lr[train::kGroupRotations]),
                            f(lr[train::kGroupRotations]), 1, 1));
  ATEX_RETURN_IF_ERROR(step(log_scales_, train::kGroupLogScales, f(lr[train::kGroupLogScales]),
                            f(lr[train::kGroupLogScales]), 1, 1));
  ATEX_RETURN_IF_ERROR(step(opacity_, train::kGroupOpacity, f(lr[train::kGroupOpacity]), f(lr[train::kGroupOpacity]),
                            1, 1));
  // SH: the DC coefficient (first 3 values of each [K][3] row) has its own rate. Both groups share
  // one update count: they always step together.
  if (lr[train::kGroupShDc] != 0 || lr[train::kGroupShRest] != 0) {
    ++adam_steps_[train::kGroupShRest];
    ATEX_RETURN_IF_ERROR(step(sh_, train::kGroupShDc, f(lr[train::kGroupShDc]), f(lr[train::kGroupShRest]),
                              3 * sh_coeffs_, 3));
  }
  if (textured) {
    ATEX_RETURN_IF_ERROR(step(texels_, train::kGroupTexels, f(lr[train::kGroupTexels]), f(lr[train::kGroupTexels]),
                              1, 1));
  }
  if (request.apply_deformation) {
    ATEX_RETURN_IF_ERROR(step(grid_, train::kGroupGrid, f(lr[train::kGroupGrid]), f(lr[train::kGroupGrid]), 1, 1));
    ATEX_RETURN_IF_ERROR(step(mlp_, train::kGroupMlp, f(lr[train::kGroupMlp]), f(lr[train::kGroupMlp]), 1, 1));
  }
  return Status::Ok();
}

}  // namespace atex::cuda::internal
