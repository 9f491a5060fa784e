// atex::train::Backend on one GPU: parameters, gradients and Adam moments live
// in device buffers; each Step runs, per view, deform → render → loss → backward
// (one view's activations alive at a time), then one fused Adam update per group.
#include "atex/cuda/cuda_backend.h"

#include <algorithm>
#include <cmath>
#include <list>
#include <map>
#include <numeric>
#include <unordered_map>

#include "deform/deform_cuda.h"
#include "device_buffer.h"
#include "loss/colour_affine.h"
#include "loss/loss_cuda.h"
#include "optim/adam_cuda.h"
#include "optim/gather_cuda.h"
#include "optim/texture_resize_cuda.h"
#include "render/render_cuda.h"

namespace atex::cuda {

bool DeviceAvailable(std::string* why) {
  int count = 0;
  const cudaError_t error = cudaGetDeviceCount(&count);
  if (error != cudaSuccess || count == 0) {
    if (why) {
      *why = error != cudaSuccess ? StrCat(cudaGetErrorName(error), ": ", cudaGetErrorString(error))
                                  : std::string("no CUDA device");
    }
    cudaGetLastError();  // clear the sticky error of the query
    return false;
  }
  return true;
}

std::string DeviceDescription() {
  std::string why;
  if (!DeviceAvailable(&why)) return "no CUDA device (" + why + ")";
  int device = 0;
  cudaGetDevice(&device);
  cudaDeviceProp prop{};
  cudaGetDeviceProperties(&prop, device);
  return StrCat(prop.name, " (sm_", prop.major, prop.minor, ", ",
                static_cast<double>(prop.totalGlobalMem) / (1ull << 30), " GiB)");
}

namespace {

using train::Backend;
using train::ModelState;

// One trainable tensor: value, gradient, Adam moments.
struct Param {
  DeviceBuffer<float> value, grad, m, v;
  Status Resize(size_t n) {
    ATEX_RETURN_IF_ERROR(value.Resize(n));
    ATEX_RETURN_IF_ERROR(grad.Resize(n));
    ATEX_RETURN_IF_ERROR(m.Resize(n));
    return v.Resize(n);
  }
  Status Upload(const std::vector<float>& values, const std::vector<float>& mm, const std::vector<float>& vv,
                cudaStream_t stream) {
    ATEX_RETURN_IF_ERROR(Resize(values.size()));
    ATEX_RETURN_IF_ERROR(value.Upload(values, stream));
    ATEX_RETURN_IF_ERROR(grad.Zero(stream));
    if (mm.size() == values.size()) {
      ATEX_RETURN_IF_ERROR(m.Upload(mm, stream));
    } else {
      ATEX_RETURN_IF_ERROR(m.Zero(stream));
    }
    if (vv.size() == values.size()) return v.Upload(vv, stream);
    return v.Zero(stream);
  }
};

class CudaBackend final : public Backend {
 public:
  explicit CudaBackend(const CudaBackendOptions& options) : options_(options) {}
  ~CudaBackend() override {
    if (mark_event_) cudaEventDestroy(mark_event_);
    if (next_event_) cudaEventDestroy(next_event_);
    deform_.reset();
    render_.reset();
    loss_.reset();
    if (cublas_) cublasDestroy(cublas_);
    if (stream_) cudaStreamDestroy(stream_);
  }

  Status Init() {
    ATEX_CUDA_RETURN_IF_ERROR(cudaSetDevice(options_.device));
    ATEX_CUDA_RETURN_IF_ERROR(cudaStreamCreateWithFlags(&stream_, cudaStreamNonBlocking));
    ATEX_CUBLAS_RETURN_IF_ERROR(cublasCreate(&cublas_));
    ATEX_CUBLAS_RETURN_IF_ERROR(cublasSetStream(cublas_, stream_));
    deform_ = std::make_unique<DeformEngine>(cublas_, stream_);
    deform_->set_allow_tf32(options_.tf32);
    render_ = std::make_unique<RenderEngine>(stream_);
    loss_ = std::make_unique<LossEngine>(stream_);
    ATEX_RETURN_IF_ERROR(scalars_.Resize(2 + kMaxBatch));
    ATEX_RETURN_IF_ERROR(flag_.Resize(1));
    return Status::Ok();
  }

  std::string name() const override { return "cuda"; }

  Status Load(const ModelState& state) override {
    const Gaussians& g = state.gaussians;
    count_ = g.size();
    sh_degree_ = g.sh_degree;
    sh_coeffs_ = g.sh_coeffs();
    ATEX_RETURN_IF_ERROR(positions_.Upload(g.positions, state.m_gaussians.positions, state.v_gaussians.positions,
                                           stream_));
    ATEX_RETURN_IF_ERROR(rotations_.Upload(g.rotations, state.m_gaussians.rotations, state.v_gaussians.rotations,
                                           stream_));
    ATEX_RETURN_IF_ERROR(log_scales_.Upload(g.log_scales, state.m_gaussians.log_scales,
                                            state.v_gaussians.log_scales, stream_));
    ATEX_RETURN_IF_ERROR(opacity_.Upload(g.opacity_logits, state.m_gaussians.opacity_logits,
                                         state.v_gaussians.opacity_logits, stream_));
    ATEX_RETURN_IF_ERROR(sh_.Upload(g.sh, state.m_gaussians.sh, state.v_gaussians.sh, stream_));

    has_textures_ = state.textures.has_value();
    if (has_textures_) {
      layout_ = *state.textures;
      layout_.texels.clear();
      ATEX_RETURN_IF_ERROR(UploadLayout());
      ATEX_RETURN_IF_ERROR(texels_.Upload(state.textures->texels, state.m_texels, state.v_texels, stream_));
    }
    has_deformation_ = state.deformation.has_value();
    if (has_deformation_) {
      deform_layout_ = DeformLayout::Make(state.deformation->config);
      ATEX_RETURN_IF_ERROR(grid_.Resize(deform_layout_.grid_size));
      ATEX_RETURN_IF_ERROR(mlp_.Resize(deform_layout_.mlp_size));
      ATEX_RETURN_IF_ERROR(UploadDeformation(*state.deformation, deform_layout_, grid_.value.data(),
                                             mlp_.value.data(), stream_));
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
    return TrackMemory();
  }

  Status Save(ModelState* state) override {
    ATEX_RETURN_IF_ERROR(DownloadGaussians(&Param::value, &state->gaussians));
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

  Status ReadGaussians(Gaussians* g) override { return DownloadGaussians(&Param::value, g); }

  // One of the per-Gaussian tensors of every group (values, gradients or an Adam moment),
  // shaped as Gaussians.
  Status DownloadGaussians(DeviceBuffer<float> Param::*which, Gaussians* out) {
    out->sh_degree = sh_degree_;
    ATEX_RETURN_IF_ERROR((positions_.*which).Download(&out->positions, stream_));
    ATEX_RETURN_IF_ERROR((rotations_.*which).Download(&out->rotations, stream_));
    ATEX_RETURN_IF_ERROR((log_scales_.*which).Download(&out->log_scales, stream_));
    ATEX_RETURN_IF_ERROR((opacity_.*which).Download(&out->opacity_logits, stream_));
    return (sh_.*which).Download(&out->sh, stream_);
  }

  StatusOr<train::StepResult> Step(const train::StepRequest& request,
                                   std::span<const train::TrainView> views) override {
    if (views.empty() || views.size() > kMaxBatch) {
      return MakeError(StatusCode::kInvalidArgument, "CUDA backend: batch of ", views.size(), " views (1..",
                       kMaxBatch, ")");
    }
    if (request.apply_deformation && !has_deformation_) {
      return MakeError(StatusCode::kInvalidArgument, "step asks for deformation but the model has none");
    }
    const bool textured = request.use_textures && has_textures_;
    const float batch = static_cast<float>(views.size());
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

  Status ReadGradients(ModelState* out) override {
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

  Status ReadStats(int kinds, train::TrainingStats* out) override {
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

  Status ResetStats(int kinds) override {
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

  Status ApplyEdit(const train::GaussianEdit& edit) override {
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

  Status AttachTextures(const TexturePool& layout) override {
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

  Status ResizeTextures(const train::TextureResize& resize) override {
    if (!has_textures_) return MakeError(StatusCode::kInvalidArgument, "resize of textures the model does not have");
    if (resize.heights.size() != count_ || resize.widths.size() != count_) {
      return MakeError(StatusCode::kInvalidArgument, "texture resize for ", resize.heights.size(), " Gaussians, model has ",
                       count_);
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

  StatusOr<Image> Render(const Camera& camera, const train::RenderRequest& request) override {
    train::StepRequest step;
    step.apply_deformation = request.apply_deformation && has_deformation_;
    step.active_sh_degree = std::min(request.active_sh_degree, sh_degree_);
    const bool textured = request.use_textures && has_textures_;
    RenderInputs inputs;
    RenderGradients unused;
    ATEX_RETURN_IF_ERROR(PrepareView(step, camera.time, textured, /*new_time=*/true, &inputs, &unused));
    for (int k = 0; k < 3; ++k) inputs.background[k] = request.background[k];
    const detail::CameraModel<float> cam = detail::MakeCameraModel<float>(camera, request.near_plane);
    const size_t pixels = size_t(camera.width) * camera.height;
    ATEX_RETURN_IF_ERROR(image_.Resize(pixels * 3));
    ATEX_RETURN_IF_ERROR(render_->Forward(cam, inputs, image_.data(), nullptr, nullptr));
    Image out(camera.width, camera.height, 3);
    ATEX_CUDA_RETURN_IF_ERROR(cudaMemcpyAsync(out.pixels.data(), image_.data(), pixels * 3 * sizeof(float),
                                              cudaMemcpyDeviceToHost, stream_));
    ATEX_CUDA_RETURN_IF_ERROR(cudaStreamSynchronize(stream_));
    return out;
  }

  uint64_t PeakMemoryBytes() const override { return peak_memory_; }

  nlohmann::json Profile() const override {
    nlohmann::json j = nlohmann::json::object();
    if (!options_.profile) return j;
    double total = 0;
    for (const auto& [stage, ms] : profile_ms_) {
      j[stage + "_ms"] = ms;
      total += ms;
    }
    j["total_ms"] = total;
    j["steps"] = profiled_steps_;
    j["deformation_passes"] = deform_passes_;
    return j;
  }

  // See TimeRender in cuda_backend.h.
  StatusOr<RenderTiming> Time(const Camera& camera, const train::RenderRequest& request, int repeats, int warmup) {
    train::StepRequest step;
    step.apply_deformation = request.apply_deformation && has_deformation_;
    step.active_sh_degree = std::min(request.active_sh_degree, sh_degree_);
    const bool textured = request.use_textures && has_textures_;
    const detail::CameraModel<float> cam = detail::MakeCameraModel<float>(camera, request.near_plane);
    ATEX_RETURN_IF_ERROR(image_.Resize(size_t(camera.width) * camera.height * 3));
    auto render_once = [&]() -> Status {
      RenderInputs inputs;
      RenderGradients unused;
      ATEX_RETURN_IF_ERROR(PrepareView(step, camera.time, textured, /*new_time=*/true, &inputs, &unused));
      for (int k = 0; k < 3; ++k) inputs.background[k] = request.background[k];
      return render_->Forward(cam, inputs, image_.data(), nullptr, nullptr);
    };
    for (int i = 0; i < warmup; ++i) ATEX_RETURN_IF_ERROR(render_once());
    cudaEvent_t start, stop;
    ATEX_CUDA_RETURN_IF_ERROR(cudaEventCreate(&start));
    ATEX_CUDA_RETURN_IF_ERROR(cudaEventCreate(&stop));
    std::vector<double> times;
    Status status;
    for (int i = 0; i < repeats && status.ok(); ++i) {
      cudaEventRecord(start, stream_);
      status = render_once();
      cudaEventRecord(stop, stream_);
      cudaEventSynchronize(stop);
      float ms = 0;
      cudaEventElapsedTime(&ms, start, stop);
      times.push_back(ms);
    }
    cudaEventDestroy(start);
    cudaEventDestroy(stop);
    ATEX_RETURN_IF_ERROR(status);
    std::sort(times.begin(), times.end());
    RenderTiming t;
    t.median_ms = times[times.size() / 2];
    t.min_ms = times.front();
    t.max_ms = times.back();
    ATEX_ASSIGN_OR_RETURN(t.visible, render_->VisibleCount());
    return t;
  }

 private:
  static constexpr size_t kMaxBatch = 64;

  GaussianTensors Canonical() {
    return {positions_.value.data(), log_scales_.value.data(), rotations_.value.data(), opacity_.value.data(),
            sh_.value.data()};
  }
  GaussianTensors CanonicalGrads() {
    return {positions_.grad.data(), log_scales_.grad.data(), rotations_.grad.data(), opacity_.grad.data(),
            sh_.grad.data()};
  }
  GaussianTensors Deformed() {
    return {d_positions_.data(), d_log_scales_.data(), d_rotations_.data(), d_opacity_.data(), d_sh_.data()};
  }
  GaussianTensors DeformedGrads() {
    return {g_positions_.data(), g_log_scales_.data(), g_rotations_.data(), g_opacity_.data(), g_sh_.data()};
  }

  // The order in which Step visits a batch's views: by time (stable), so that the views
  // of one time are adjacent and share a deformation pass.
  static std::vector<size_t> TimeGroupedOrder(std::span<const train::TrainView> views) {
    std::vector<size_t> order(views.size());
    std::iota(order.begin(), order.end(), size_t{0});
    std::stable_sort(order.begin(), order.end(),
                     [&](size_t a, size_t b) { return views[a].camera->time < views[b].camera->time; });
    return order;
  }

  // Deforms the canonical Gaussians to `time` into the d_* buffers and zeroes their
  // gradients (g_*), which the views of that time then accumulate.
  Status DeformAt(double time) {
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
    return deform_->Forward(deform_layout_, grid_.value.data(), mlp_.value.data(), static_cast<int>(count_),
                            sh_coeffs_, static_cast<float>(time), Canonical(), Deformed());
  }

  // Fills the render inputs of one view: the canonical Gaussians (coarse stage) or the
  // deformed ones at `time`, and where their gradients go. `new_time`: deform and zero
  // the deformed gradients; false: the previous view had the same time, so the deformed
  // Gaussians are current and their gradients keep accumulating.
  Status PrepareView(const train::StepRequest& request, double time, bool textured, bool new_time,
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

  RenderStats MakeStats(const train::StepRequest& request, const Camera& camera, float batch, bool textured) {
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

  Status ZeroGrads() {
    for (Param* p : {&positions_, &rotations_, &log_scales_, &opacity_, &sh_}) ATEX_RETURN_IF_ERROR(p->grad.Zero(stream_));
    if (has_textures_) ATEX_RETURN_IF_ERROR(texels_.grad.Zero(stream_));
    if (has_deformation_) {
      ATEX_RETURN_IF_ERROR(grid_.grad.Zero(stream_));
      ATEX_RETURN_IF_ERROR(mlp_.grad.Zero(stream_));
    }
    return Status::Ok();
  }

  Status FlagNonFiniteGrads(const train::StepRequest& request, bool textured) {
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

  Status ApplyAdam(const train::StepRequest& request, bool textured) {
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

  Status CapOpacity(float cap) {
    std::vector<float> opacity;
    ATEX_RETURN_IF_ERROR(opacity_.value.Download(&opacity, stream_));
    for (float& o : opacity) o = std::min(o, cap);
    ATEX_RETURN_IF_ERROR(opacity_.value.Upload(opacity, stream_));
    ATEX_RETURN_IF_ERROR(opacity_.m.Zero(stream_));
    return opacity_.v.Zero(stream_);
  }

  Status UploadLayout() {
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

  bool HasTarget(uint64_t image_key) const override { return targets_.count(image_key) != 0; }

  // Target images stay on the device (LRU, bounded), keyed by the view's image key.
  StatusOr<const float*> Target(const train::TrainView& view) {
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

  // Profiling: elapsed device time since the previous mark, added to `stage`.
  Status Mark(const char* stage) {
    if (!options_.profile) return Status::Ok();
    if (!mark_event_) {
      ATEX_CUDA_RETURN_IF_ERROR(cudaEventCreate(&mark_event_));
      ATEX_CUDA_RETURN_IF_ERROR(cudaEventCreate(&next_event_));
      ATEX_CUDA_RETURN_IF_ERROR(cudaEventRecord(mark_event_, stream_));
    }
    ATEX_CUDA_RETURN_IF_ERROR(cudaEventRecord(next_event_, stream_));
    ATEX_CUDA_RETURN_IF_ERROR(cudaEventSynchronize(next_event_));
    float ms = 0;
    ATEX_CUDA_RETURN_IF_ERROR(cudaEventElapsedTime(&ms, mark_event_, next_event_));
    profile_ms_[stage] += ms;
    std::swap(mark_event_, next_event_);
    return Status::Ok();
  }

  Status TrackMemory() {
    size_t free_bytes = 0, total_bytes = 0;
    ATEX_CUDA_RETURN_IF_ERROR(cudaMemGetInfo(&free_bytes, &total_bytes));
    peak_memory_ = std::max<uint64_t>(peak_memory_, total_bytes - free_bytes);
    return Status::Ok();
  }

  static constexpr size_t kTargetCacheBytes = size_t{8} << 30;

  CudaBackendOptions options_;
  cudaStream_t stream_ = nullptr;
  cublasHandle_t cublas_ = nullptr;
  std::unique_ptr<DeformEngine> deform_;
  std::unique_ptr<RenderEngine> render_;
  std::unique_ptr<LossEngine> loss_;

  size_t count_ = 0;
  int sh_degree_ = 0, sh_coeffs_ = 1;
  Param positions_, rotations_, log_scales_, opacity_, sh_;
  bool has_textures_ = false;
  TexturePool layout_;  // dims, axes and offsets (no texels) mirrored on the host
  DeviceBuffer<uint8_t> layout_device_;
  DeviceBuffer<uint32_t> offsets_;
  Param texels_;
  bool has_deformation_ = false;
  DeformLayout deform_layout_;
  Param grid_, mlp_;
  // Deformed Gaussians of the current view and their gradients.
  DeviceBuffer<float> d_positions_, d_log_scales_, d_rotations_, d_opacity_, d_sh_;
  DeviceBuffer<float> g_positions_, g_log_scales_, g_rotations_, g_opacity_, g_sh_;
  DeviceBuffer<float> image_, image_grad_;
  DeviceBuffer<float> corrected_;  // [H][W][3] the render after the view's colour correction
  DeviceBuffer<float> scalars_;  // [0] photometric loss, [1] regulariser, [2 + k] squared error of view k
  DeviceBuffer<int> flag_;
  // Statistics.
  int bins_ = 8;
  DeviceBuffer<float> grad_norm_sum_, visible_count_, max_radius_;
  DeviceBuffer<float> demand_sum_, bin_count_, scale_u_sum_, scale_v_sum_;
  DeviceBuffer<float> importance_;
  std::array<int64_t, train::kParamGroupCount> adam_steps_{};
  std::unordered_map<uint64_t, std::pair<DeviceBuffer<float>, std::list<uint64_t>::iterator>> targets_;
  std::list<uint64_t> lru_;
  size_t target_bytes_ = 0;
  uint64_t peak_memory_ = 0;
  // Profiling (options_.profile).
  cudaEvent_t mark_event_ = nullptr, next_event_ = nullptr;
  std::map<std::string, double> profile_ms_;
  int64_t profiled_steps_ = 0;
  int64_t deform_passes_ = 0;  // deformation backward passes (one per distinct time of a batch)
};

}  // namespace

StatusOr<RenderTiming> TimeRender(train::Backend& backend, const Camera& camera, const train::RenderRequest& request,
                                  int repeats, int warmup) {
  auto* cuda = dynamic_cast<CudaBackend*>(&backend);
  if (cuda == nullptr) return MakeError(StatusCode::kInvalidArgument, "TimeRender needs the CUDA backend");
  if (repeats < 1 || warmup < 0) return MakeError(StatusCode::kInvalidArgument, "TimeRender: bad repeat counts");
  return cuda->Time(camera, request, repeats, warmup);
}

StatusOr<std::unique_ptr<train::Backend>> MakeCudaBackend(const CudaBackendOptions& options) {
  std::string why;
  if (!DeviceAvailable(&why)) {
    return MakeError(StatusCode::kNoDevice, "no usable CUDA device (", why,
                     "); use --backend cpu for tiny scenes (the CPU reference engine is slow but complete)");
  }
  auto backend = std::make_unique<CudaBackend>(options);
  ATEX_RETURN_IF_ERROR(backend->Init());
  return std::unique_ptr<train::Backend>(std::move(backend));
}

}  // namespace atex::cuda
