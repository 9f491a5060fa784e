// The CUDA backend's edits: Gaussians gathered, cloned or removed (ApplyEdit) and
// texture pools attached or resampled (AttachTextures, ResizeTextures).
#include <algorithm>
#include <cmath>

#include "cuda_backend_impl.h"
#include "optim/gather_cuda.h"
#include "optim/texture_resize_cuda.h"

namespace atex::cuda::internal {

Status CudaBackend::ApplyEdit(const train::GaussianEdit& edit) {
  ForgetHeldKeys();  // the values change
  const size_t m = edit.source.size();
  for (uint32_t s : edit.source) {
    if (s >= count_) return MakeError(StatusCode::kInvalidArgument, "edit source ", s, " of ", count_, " Gaussians");
  }
  if ((!edit.positions.empty() && edit.positions.size() != m * 3) ||
      (!edit.log_scales.empty() && edit.log_scales.size() != m * 3) ||
      (!edit.reset_moments.empty() && edit.reset_moments.size() != m)) {
    return MakeError(StatusCode::kInvalidArgument, "edit override arrays do not match ", m, " Gaussians");
  }
  DeviceBuffer<uint32_t> source;
  DeviceBuffer<uint8_t> reset;
  ATEX_RETURN_IF_ERROR(source.Upload(edit.source, stream_));
  if (!edit.reset_moments.empty()) ATEX_RETURN_IF_ERROR(reset.Upload(edit.reset_moments, stream_));
  const uint8_t* reset_ptr = edit.reset_moments.empty() ? nullptr : reset.data();
  auto gather = [&](Param& p, int width, const std::vector<float>* override_values) -> Status {
    Param fresh;
    ATEX_RETURN_IF_ERROR(fresh.Resize(m * width));
    if (override_values && !override_values->empty()) {
      ATEX_RETURN_IF_ERROR(fresh.value.Upload(*override_values, stream_));
    } else {
      ATEX_RETURN_IF_ERROR(GatherRows(p.value.data(), fresh.value.data(), width, source.data(), nullptr, m, stream_));
    }
    ATEX_RETURN_IF_ERROR(GatherRows(p.m.data(), fresh.m.data(), width, source.data(), reset_ptr, m, stream_));
    ATEX_RETURN_IF_ERROR(GatherRows(p.v.data(), fresh.v.data(), width, source.data(), reset_ptr, m, stream_));
    ATEX_RETURN_IF_ERROR(fresh.grad.Zero(stream_));
    p = std::move(fresh);
    return Status::Ok();
  };
  ATEX_RETURN_IF_ERROR(gather(positions_, 3, &edit.positions));
  ATEX_RETURN_IF_ERROR(gather(rotations_, 4, nullptr));
  ATEX_RETURN_IF_ERROR(gather(log_scales_, 3, &edit.log_scales));
  ATEX_RETURN_IF_ERROR(gather(opacity_, 1, nullptr));
  ATEX_RETURN_IF_ERROR(gather(sh_, 3 * sh_coeffs_, nullptr));
  if (has_time_windows_) {  // constants of each Gaussian: clones and splits inherit their source's window
    DeviceBuffer<float> windows;
    ATEX_RETURN_IF_ERROR(windows.Resize(m * 2));
    ATEX_RETURN_IF_ERROR(GatherRows(time_windows_.data(), windows.data(), 2, source.data(), nullptr, m, stream_));
    time_windows_ = std::move(windows);
  }
  if (has_textures_) {
    TexturePool layout;
    for (uint32_t s : edit.source) {
      layout.heights.push_back(layout_.heights[s]);
      layout.widths.push_back(layout_.widths[s]);
      layout.axis_u.push_back(layout_.axis_u[s]);
      layout.axis_v.push_back(layout_.axis_v[s]);
    }
    layout.RebuildOffsets();
    DeviceBuffer<uint32_t> old_offsets = std::move(offsets_);
    layout_ = std::move(layout);
    ATEX_RETURN_IF_ERROR(UploadLayout());
    Param fresh;
    ATEX_RETURN_IF_ERROR(fresh.Resize(layout_.texel_count() * 4));
    for (auto [src, dst] : {std::pair{&texels_.value, &fresh.value}, std::pair{&texels_.m, &fresh.m},
                            std::pair{&texels_.v, &fresh.v}}) {
      ATEX_RETURN_IF_ERROR(GatherTexelBlocks(src->data(), old_offsets.data(), dst->data(), offsets_.data(),
                                             source.data(), m, stream_));
    }
    ATEX_RETURN_IF_ERROR(fresh.grad.Zero(stream_));
    texels_ = std::move(fresh);
  }
  count_ = m;
  if (!std::isnan(edit.cap_opacity_logit)) ATEX_RETURN_IF_ERROR(CapOpacity(edit.cap_opacity_logit));
  ATEX_RETURN_IF_ERROR(ResetStats(train::kStatsAll));
  ATEX_CUDA_RETURN_IF_ERROR(cudaStreamSynchronize(stream_));
  return TrackMemory();
}

Status CudaBackend::AttachTextures(const TexturePool& layout) {
  ForgetHeldKeys();  // the values change
  if (layout.size() != count_) {
    return MakeError(StatusCode::kInvalidArgument, "texture layout for ", layout.size(), " Gaussians, model has ",
                     count_);
  }
  layout_ = layout;
  layout_.RebuildOffsets();
  layout_.texels.clear();
  ATEX_RETURN_IF_ERROR(UploadLayout());
  ATEX_RETURN_IF_ERROR(texels_.Resize(layout_.texel_count() * 4));
  if (layout.texels.size() == layout_.texel_count() * 4) {
    ATEX_RETURN_IF_ERROR(texels_.value.Upload(layout.texels, stream_));
  } else {
    ATEX_RETURN_IF_ERROR(texels_.value.Zero(stream_));
  }
  for (auto* b : {&texels_.grad, &texels_.m, &texels_.v}) ATEX_RETURN_IF_ERROR(b->Zero(stream_));
  adam_steps_[train::kGroupTexels] = 0;
  has_textures_ = true;
  ATEX_RETURN_IF_ERROR(ResetStats(train::kStatsTexture));
  return Status::Ok();
}

Status CudaBackend::ResizeTextures(const train::TextureResize& resize) {
  ForgetHeldKeys();  // the values change
  if (!has_textures_) return MakeError(StatusCode::kInvalidArgument, "resize of textures the model does not have");
  if (resize.heights.size() != count_ || resize.widths.size() != count_) {
    return MakeError(StatusCode::kInvalidArgument, "texture resize for ", resize.heights.size(),
                     " Gaussians, model has ", count_);
  }
  TexturePool grown = layout_;
  grown.heights = resize.heights;
  grown.widths = resize.widths;
  for (size_t i = 0; i < count_; ++i) {
    const int h = grown.heights[i], w = grown.widths[i];
    if ((h != 1 && h != 2 && h != 4) || (w != 1 && w != 2 && w != 4)) {
      return MakeError(StatusCode::kOutOfRange, "texture ", i, " resized to ", h, "x", w, " (sides 1, 2 or 4)");
    }
  }
  grown.RebuildOffsets();
  DeviceBuffer<uint8_t> old_layout = std::move(layout_device_);
  DeviceBuffer<uint32_t> old_offsets = std::move(offsets_);
  layout_ = std::move(grown);
  ATEX_RETURN_IF_ERROR(UploadLayout());
  Param fresh;
  ATEX_RETURN_IF_ERROR(fresh.Resize(layout_.texel_count() * 4));
  const int m_power = resize.rescale_moments ? 1 : 0, v_power = resize.rescale_moments ? 2 : 0;
  for (auto [src, dst, power] : {std::tuple{&texels_.value, &fresh.value, 0},
                                 std::tuple{&texels_.m, &fresh.m, m_power},
                                 std::tuple{&texels_.v, &fresh.v, v_power}}) {
    ATEX_RETURN_IF_ERROR(ResampleTexels(src->data(), old_layout.data(), old_offsets.data(), dst->data(),
                                        layout_device_.data(), offsets_.data(), static_cast<int>(count_), power,
                                        stream_));
  }
  ATEX_RETURN_IF_ERROR(fresh.grad.Zero(stream_));
  texels_ = std::move(fresh);
  ATEX_CUDA_RETURN_IF_ERROR(cudaStreamSynchronize(stream_));
  return TrackMemory();
}

Status CudaBackend::CapOpacity(float cap) {
  std::vector<float> opacity;
  ATEX_RETURN_IF_ERROR(opacity_.value.Download(&opacity, stream_));
  for (float& o : opacity) o = std::min(o, cap);
  ATEX_RETURN_IF_ERROR(opacity_.value.Upload(opacity, stream_));
  ATEX_RETURN_IF_ERROR(opacity_.m.Zero(stream_));
  return opacity_.v.Zero(stream_);
}

}  // namespace atex::cuda::internal
