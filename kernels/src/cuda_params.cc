// The CUDA backend's parameter store: loading and saving the model state, downloads,
// training statistics, the device cache of target images and the memory high-water mark.
#include <algorithm>
#include <cstring>

#include "cuda_backend_impl.h"
#include "optim/gather_cuda.h"

namespace atex::cuda::internal {

Status CudaBackend::Load(const ModelState& state) { return LoadWith(state, nullptr); }

Status CudaBackend::LoadKeyed(const ModelState& state, const train::StateKeys& keys) { return LoadWith(state, &keys); }

Status CudaBackend::LoadWith(const ModelState& state, const train::StateKeys* keys) {
  const train::StateKeys held = held_keys_;
  ForgetHeldKeys();  // until this load has finished
  // An array is kept when its key is known and equals the one held (then so are its length and
  // bytes: backend.h), and the device still holds such an array.
  const auto kept = [&](train::StateKeys::Key train::StateKeys::*array) {
    return keys != nullptr && (*keys).*array != train::StateKeys::Key{} && (*keys).*array == held.*array;
  };
  const Gaussians& g = state.gaussians;
  count_ = g.size();
  sh_degree_ = g.sh_degree;
  sh_coeffs_ = g.sh_coeffs();
  ATEX_RETURN_IF_ERROR(positions_.Upload(g.positions, state.m_gaussians.positions, state.v_gaussians.positions, stream_,
                                         kept(&train::StateKeys::positions)));
  ATEX_RETURN_IF_ERROR(rotations_.Upload(g.rotations, state.m_gaussians.rotations, state.v_gaussians.rotations, stream_,
                                         kept(&train::StateKeys::rotations)));
  ATEX_RETURN_IF_ERROR(log_scales_.Upload(g.log_scales, state.m_gaussians.log_scales, state.v_gaussians.log_scales,
                                          stream_, kept(&train::StateKeys::log_scales)));
  ATEX_RETURN_IF_ERROR(opacity_.Upload(g.opacity_logits, state.m_gaussians.opacity_logits,
                                       state.v_gaussians.opacity_logits, stream_, kept(&train::StateKeys::opacity)));
  ATEX_RETURN_IF_ERROR(
      sh_.Upload(g.sh, state.m_gaussians.sh, state.v_gaussians.sh, stream_, kept(&train::StateKeys::sh)));
  const bool had_time_windows = has_time_windows_;
  has_time_windows_ = g.has_time_windows();
  if (has_time_windows_) {
    if (g.time_windows.size() != 2 * count_) {
      return MakeError(StatusCode::kInvalidArgument, "time_windows has ", g.time_windows.size(), " values for ",
                       count_, " Gaussians");
    }
    if (!(had_time_windows && kept(&train::StateKeys::time_windows))) {
      ATEX_RETURN_IF_ERROR(time_windows_.Upload(g.time_windows, stream_));
    }
  } else {
    time_windows_ = DeviceBuffer<float>();
  }

  const bool had_textures = has_textures_;
  has_textures_ = state.textures.has_value();
  if (has_textures_) {
    const TexturePool& t = *state.textures;
    const bool keep = had_textures && kept(&train::StateKeys::texels);
    if (!keep) {
      // The layout alone: the texels go to the device, not into a host copy.
      layout_.heights = t.heights;
      layout_.widths = t.widths;
      layout_.axis_u = t.axis_u;
      layout_.axis_v = t.axis_v;
      layout_.offsets = t.offsets;
      layout_.texels.clear();
      ATEX_RETURN_IF_ERROR(UploadLayout());
    }
    ATEX_RETURN_IF_ERROR(texels_.Upload(t.texels, state.m_texels, state.v_texels, stream_, keep));
  }
  const bool had_deformation = has_deformation_;
  has_deformation_ = state.deformation.has_value();
  if (has_deformation_) {
    deform_layout_ = DeformLayout::Make(state.deformation->config);
    ATEX_RETURN_IF_ERROR(grid_.Resize(deform_layout_.grid_size));
    ATEX_RETURN_IF_ERROR(mlp_.Resize(deform_layout_.mlp_size));
    if (!(had_deformation && kept(&train::StateKeys::deformation))) {
      ATEX_RETURN_IF_ERROR(
          UploadDeformation(*state.deformation, deform_layout_, grid_.value.data(), mlp_.value.data(), stream_));
    }
    for (auto [moments, grid, mlp] : {std::tuple{&state.m_deformation, &grid_.m, &mlp_.m},
                                      std::tuple{&state.v_deformation, &grid_.v, &mlp_.v}}) {
      if (moments->has_value()) {
        ATEX_RETURN_IF_ERROR(UploadDeformation(**moments, deform_layout_, grid->data(), mlp->data(), stream_));
      } else {
        ATEX_RETURN_IF_ERROR(grid->Zero(stream_));
        ATEX_RETURN_IF_ERROR(mlp->Zero(stream_));
      }
    }
    ATEX_RETURN_IF_ERROR(grid_.grad.Zero(stream_));
    ATEX_RETURN_IF_ERROR(mlp_.grad.Zero(stream_));
  }
  adam_steps_ = state.adam_steps;
  ATEX_RETURN_IF_ERROR(ResetStats(train::kStatsAll));
  ATEX_CUDA_RETURN_IF_ERROR(cudaStreamSynchronize(stream_));
  ATEX_RETURN_IF_ERROR(TrackMemory());
  if (keys != nullptr) held_keys_ = *keys;
  return Status::Ok();
}

Status CudaBackend::Save(ModelState* state) {
  ATEX_RETURN_IF_ERROR(ReadGaussians(&state->gaussians));
  ATEX_RETURN_IF_ERROR(DownloadGaussians(&Param::m, &state->m_gaussians));
  ATEX_RETURN_IF_ERROR(DownloadGaussians(&Param::v, &state->v_gaussians));
  if (has_textures_) {
    TexturePool pool = layout_;
    ATEX_RETURN_IF_ERROR(texels_.value.Download(&pool.texels, stream_));
    state->textures = std::move(pool);
    ATEX_RETURN_IF_ERROR(texels_.m.Download(&state->m_texels, stream_));
    ATEX_RETURN_IF_ERROR(texels_.v.Download(&state->v_texels, stream_));
  } else {
    state->textures.reset();
    state->m_texels.clear();
    state->v_texels.clear();
  }
  if (has_deformation_) {
    DeformationField field, m, v;
    ATEX_RETURN_IF_ERROR(DownloadDeformation(grid_.value.data(), mlp_.value.data(), deform_layout_, &field, stream_));
    ATEX_RETURN_IF_ERROR(DownloadDeformation(grid_.m.data(), mlp_.m.data(), deform_layout_, &m, stream_));
    ATEX_RETURN_IF_ERROR(DownloadDeformation(grid_.v.data(), mlp_.v.data(), deform_layout_, &v, stream_));
    state->deformation = std::move(field);
    state->m_deformation = std::move(m);
    state->v_deformation = std::move(v);
  } else {
    state->deformation.reset();
    state->m_deformation.reset();
    state->v_deformation.reset();
  }
  state->adam_steps = adam_steps_;
  return Status::Ok();
}

// One of the per-Gaussian tensors of every group (values, gradients or an Adam moment),
// shaped as Gaussians.
Status CudaBackend::DownloadGaussians(DeviceBuffer<float> Param::*which, Gaussians* out) {
  out->sh_degree = sh_degree_;
  ATEX_RETURN_IF_ERROR((positions_.*which).Download(&out->positions, stream_));
  ATEX_RETURN_IF_ERROR((rotations_.*which).Download(&out->rotations, stream_));
  ATEX_RETURN_IF_ERROR((log_scales_.*which).Download(&out->log_scales, stream_));
  ATEX_RETURN_IF_ERROR((opacity_.*which).Download(&out->opacity_logits, stream_));
  return (sh_.*which).Download(&out->sh, stream_);
}

Status CudaBackend::ReadGradients(ModelState* out) {
  *out = ModelState{};
  ATEX_RETURN_IF_ERROR(DownloadGaussians(&Param::grad, &out->gaussians));
  if (has_textures_) {
    TexturePool pool = layout_;
    ATEX_RETURN_IF_ERROR(texels_.grad.Download(&pool.texels, stream_));
    out->textures = std::move(pool);
  }
  if (has_deformation_) {
    DeformationField grad;
    ATEX_RETURN_IF_ERROR(DownloadDeformation(grid_.grad.data(), mlp_.grad.data(), deform_layout_, &grad, stream_));
    out->deformation = std::move(grad);
  }
  return Status::Ok();
}

Status CudaBackend::ReadStats(int kinds, train::TrainingStats* out) {
  if (kinds & train::kStatsDensify) {
    ATEX_RETURN_IF_ERROR(grad_norm_sum_.Download(&out->densify.grad_norm_sum, stream_));
    ATEX_RETURN_IF_ERROR(visible_count_.Download(&out->densify.visible_count, stream_));
    ATEX_RETURN_IF_ERROR(max_radius_.Download(&out->densify.max_radius, stream_));
  }
  if (kinds & train::kStatsTexture) {
    out->texture.bins = bins_;
    ATEX_RETURN_IF_ERROR(demand_sum_.Download(&out->texture.demand_sum, stream_));
    ATEX_RETURN_IF_ERROR(bin_count_.Download(&out->texture.visible_count, stream_));
    ATEX_RETURN_IF_ERROR(scale_u_sum_.Download(&out->texture.scale_u_sum, stream_));
    ATEX_RETURN_IF_ERROR(scale_v_sum_.Download(&out->texture.scale_v_sum, stream_));
  }
  if (kinds & train::kStatsImportance) ATEX_RETURN_IF_ERROR(importance_.Download(&out->importance, stream_));
  return Status::Ok();
}

Status CudaBackend::ResetStats(int kinds) {
  if (kinds & train::kStatsDensify) {
    for (auto* b : {&grad_norm_sum_, &visible_count_, &max_radius_}) {
      ATEX_RETURN_IF_ERROR(b->Resize(count_));
      ATEX_RETURN_IF_ERROR(b->Zero(stream_));
    }
  }
  if (kinds & train::kStatsTexture) {
    for (auto* b : {&demand_sum_, &bin_count_, &scale_u_sum_, &scale_v_sum_}) {
      ATEX_RETURN_IF_ERROR(b->Resize(count_ * bins_));
      ATEX_RETURN_IF_ERROR(b->Zero(stream_));
    }
  }
  if (kinds & train::kStatsImportance) {
    ATEX_RETURN_IF_ERROR(importance_.Resize(count_));
    ATEX_RETURN_IF_ERROR(importance_.Zero(stream_));
  }
  return Status::Ok();
}

Status CudaBackend::UploadLayout() {
  std::vector<uint8_t> packed(layout_.size() * 4);
  for (size_t i = 0; i < layout_.size(); ++i) {
    packed[4 * i] = layout_.heights[i];
    packed[4 * i + 1] = layout_.widths[i];
    packed[4 * i + 2] = layout_.axis_u[i];
    packed[4 * i + 3] = layout_.axis_v[i];
  }
  if (layout_.offsets.size() != layout_.size() + 1) layout_.RebuildOffsets();
  if (layout_.texel_count() > 0xFFFFFFFFull) {
    return MakeError(StatusCode::kLimitExceeded, "texture pool of ", layout_.texel_count(),
                     " texels exceeds the CUDA backend's 32-bit offsets");
  }
  std::vector<uint32_t> offsets(layout_.offsets.begin(), layout_.offsets.end());
  ATEX_RETURN_IF_ERROR(layout_device_.Upload(packed, stream_));
  return offsets_.Upload(offsets, stream_);
}

// Target images stay on the device (LRU, bounded), keyed by the view's image key, unless the view
// says another device keeps them.
StatusOr<const float*> CudaBackend::Target(const train::TrainView& view) {
  auto it = targets_.find(view.image_key);
  if (it != targets_.end()) {
    lru_.splice(lru_.begin(), lru_, it->second.second);
    return static_cast<const float*>(it->second.first.data());
  }
  if (view.target == nullptr) {
    return MakeError(StatusCode::kInternal, "CUDA backend: view ", view.camera->name,
                     " came without its image, but its device copy is gone");
  }
  const Image& image = *view.target;
  if (image.channels != 3 || image.width != view.camera->width || image.height != view.camera->height) {
    return MakeError(StatusCode::kInvalidArgument, "target image ", image.width, "x", image.height, "x",
                     image.channels, " does not match camera ", view.camera->width, "x", view.camera->height);
  }
  if (!view.keep_on_device) return TransientTargetOf(image);
  while (target_bytes_ + image.pixels.size() * sizeof(float) > kTargetCacheBytes && !lru_.empty()) {
    auto victim = targets_.find(lru_.back());
    target_bytes_ -= victim->second.first.bytes();
    targets_.erase(victim);
    lru_.pop_back();
  }
  lru_.push_front(view.image_key);
  auto& entry = targets_[view.image_key];
  entry.second = lru_.begin();
  ATEX_RETURN_IF_ERROR(entry.first.Upload(image.pixels, stream_));
  target_bytes_ += entry.first.bytes();
  return static_cast<const float*>(entry.first.data());
}

// Another device keeps this image: a copy for this use only, in the next transient slot. The
// slot's device copy is overwritten two such views later, after the kernels that read it (both
// are ordered on stream_); its pinned copy once the slot's last upload has completed.
StatusOr<const float*> CudaBackend::TransientTargetOf(const Image& image) {
  TransientTarget& slot = transient_[next_transient_];
  next_transient_ = (next_transient_ + 1) % transient_.size();
  const size_t n = image.pixels.size();
  if (slot.uploaded == nullptr) {
    ATEX_CUDA_RETURN_IF_ERROR(cudaEventCreateWithFlags(&slot.uploaded, cudaEventDisableTiming));
  } else {
    ATEX_CUDA_RETURN_IF_ERROR(cudaEventSynchronize(slot.uploaded));
  }
  if (slot.capacity < n) {
    if (slot.pinned) ATEX_CUDA_RETURN_IF_ERROR(cudaFreeHost(slot.pinned));
    slot.pinned = nullptr, slot.capacity = 0;
    ATEX_CUDA_RETURN_IF_ERROR(cudaMallocHost(&slot.pinned, n * sizeof(float)));
    slot.capacity = n;
  }
  std::memcpy(slot.pinned, image.pixels.data(), n * sizeof(float));
  ATEX_RETURN_IF_ERROR(slot.device.Upload(slot.pinned, n, stream_));
  ATEX_CUDA_RETURN_IF_ERROR(cudaEventRecord(slot.uploaded, stream_));
  return static_cast<const float*>(slot.device.data());
}

Status CudaBackend::TrackMemory() {
  size_t free_bytes = 0, total_bytes = 0;
  ATEX_CUDA_RETURN_IF_ERROR(cudaMemGetInfo(&free_bytes, &total_bytes));
  peak_memory_ = std::max<uint64_t>(peak_memory_, total_bytes - free_bytes);
  return Status::Ok();
}

}  // namespace atex::cuda::internal
