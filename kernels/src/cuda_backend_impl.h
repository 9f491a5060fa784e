// The CUDA backend's class, shared by its translation units (one per seam):
//   cuda_backend.cc  construction, device queries, Render;
//   cuda_params.cc   the parameter store: Load/Save, downloads, statistics, the target cache, memory;
//   cuda_edits.cc    topology and texture edits (ApplyEdit, AttachTextures, ResizeTextures);
//   cuda_profile.cc  profiling (Profile, Mark, Time);
//   cuda_step.cc     the training step (deform → render → loss → backward → Adam).
// Private to kernels/src: the public face is atex/cuda/cuda_backend.h.
#pragma once

#include <array>
#include <list>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <unordered_map>
#include <vector>

#include "atex/cuda/cuda_backend.h"
#include "deform/deform_cuda.h"
#include "device_buffer.h"
#include "loss/loss_cuda.h"
#include "render/render_cuda.h"

namespace atex::cuda::internal {

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
  // `keep_value`: the device holds `values` already (a keyed load): only the rest is set.
  Status Upload(const std::vector<float>& values, const std::vector<float>& mm, const std::vector<float>& vv,
                cudaStream_t stream, bool keep_value = false) {
    ATEX_RETURN_IF_ERROR(Resize(values.size()));
    if (!keep_value) ATEX_RETURN_IF_ERROR(value.Upload(values, stream));
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
  ~CudaBackend() override;

  Status Init();

  std::string name() const override { return "cuda"; }
  int MaxBatchViews() const override { return static_cast<int>(kMaxBatch); }

  Status Load(const ModelState& state) override;
  Status LoadKeyed(const ModelState& state, const train::StateKeys& keys) override;

  Status Save(ModelState* state) override;

  Status ReadGaussians(Gaussians* g) override {
    ATEX_RETURN_IF_ERROR(DownloadGaussians(&Param::value, g));
    g->time_windows.clear();  // as the CPU backend: the canonical Gaussians with their windows
    return has_time_windows_ ? time_windows_.Download(&g->time_windows, stream_) : Status::Ok();
  }

  // One of the per-Gaussian tensors of every group (values, gradients or an Adam moment),
  // shaped as Gaussians.
  Status DownloadGaussians(DeviceBuffer<float> Param::*which, Gaussians* out);

  StatusOr<train::StepResult> Step(const train::StepRequest& request,
                                   std::span<const train::TrainView> views) override;

  Status ReadGradients(ModelState* out) override;

  Status ReadStats(int kinds, train::TrainingStats* out) override;

  Status ResetStats(int kinds) override;

  Status ApplyEdit(const train::GaussianEdit& edit) override;

  Status AttachTextures(const TexturePool& layout) override;

  Status ResizeTextures(const train::TextureResize& resize) override;

  StatusOr<Image> Render(const Camera& camera, const train::RenderRequest& request) override;
  // See RenderOnDevice in cuda_backend.h.
  StatusOr<DeviceImage> RenderToDevice(const Camera& camera, const train::RenderRequest& request);

  uint64_t PeakMemoryBytes() const override { return peak_memory_; }

  // Data parallelism: Step sums the gradients on the device through comm's
  // AllReduceSumDevice (NCCL), the loss on the host (backend.h's contract).
  Status SetCommunicator(train::Communicator* comm) override;

  nlohmann::json Profile() const override;

  // See TimeRender in cuda_backend.h.
  StatusOr<RenderTiming> Time(const Camera& camera, const train::RenderRequest& request, int repeats, int warmup);

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
  static std::vector<size_t> TimeGroupedOrder(std::span<const train::TrainView> views);

  // Deforms the canonical Gaussians to `time` into the d_* buffers and zeroes their
  // gradients (g_*), which the views of that time then accumulate.
  Status DeformAt(double time);

  // Fills the render inputs of one view: the canonical Gaussians (coarse stage) or the
  // deformed ones at `time`, and where their gradients go. `new_time`: deform and zero
  // the deformed gradients; false: the previous view had the same time, so the deformed
  // Gaussians are current and their gradients keep accumulating.
  Status PrepareView(const train::StepRequest& request, double time, bool textured, bool new_time,
                     RenderInputs* in, RenderGradients* grads);

  // Renders `camera` into `out` ([H][W][3] on the device, sized by the caller); not synchronised.
  Status RenderInto(const Camera& camera, const train::RenderRequest& request, float* out);
  RenderStats MakeStats(const train::StepRequest& request, const Camera& camera, float batch, bool textured);

  Status ZeroGrads();

  Status FlagNonFiniteGrads(const train::StepRequest& request, bool textured);

  // Sums the gradients of the step's groups across the ranks (one grouped device all-reduce).
  Status ReduceGradients(const train::StepRequest& request, bool textured);

  Status ApplyAdam(const train::StepRequest& request, bool textured);

  Status CapOpacity(float cap);

  Status UploadLayout();

  // Load and LoadKeyed (`keys` null: every array is copied).
  Status LoadWith(const ModelState& state, const train::StateKeys* keys);
  // The values changed (a step, an edit): no array is known by its key any more.
  void ForgetHeldKeys() { held_keys_ = {}; }

  bool HasTarget(uint64_t image_key) const override { return targets_.count(image_key) != 0; }

  // Target images stay on the device (LRU, bounded), keyed by the view's image key.
  StatusOr<const float*> Target(const train::TrainView& view);

  // Profiling: elapsed device time since the previous mark, added to `stage`.
  Status Mark(const char* stage);

  Status TrackMemory();

  static constexpr size_t kTargetCacheBytes = size_t{8} << 30;

  CudaBackendOptions options_;
  train::Communicator* comm_ = nullptr;  // SetCommunicator; null or one rank: no reduction
  cudaStream_t stream_ = nullptr;
  cublasHandle_t cublas_ = nullptr;
  std::unique_ptr<DeformEngine> deform_;
  std::unique_ptr<RenderEngine> render_;
  std::unique_ptr<LossEngine> loss_;

  size_t count_ = 0;
  int sh_degree_ = 0, sh_coeffs_ = 1;
  Param positions_, rotations_, log_scales_, opacity_, sh_;
  // [N][2] time windows of time-local Gaussians (model.h), not trained; empty when the model has none.
  bool has_time_windows_ = false;
  DeviceBuffer<float> time_windows_;
  bool has_textures_ = false;
  TexturePool layout_;  // dims, axes and offsets (no texels) mirrored on the host
  DeviceBuffer<uint8_t> layout_device_;
  DeviceBuffer<uint32_t> offsets_;
  Param texels_;
  bool has_deformation_ = false;
  DeformLayout deform_layout_;
  Param grid_, mlp_;
  // The keys of the value arrays held, from the last LoadKeyed (zero: unknown; see ForgetHeldKeys).
  train::StateKeys held_keys_;
  // Deformed Gaussians of the current view and their gradients.
  DeviceBuffer<float> d_positions_, d_log_scales_, d_rotations_, d_opacity_, d_sh_;
  DeviceBuffer<float> g_positions_, g_log_scales_, g_rotations_, g_opacity_, g_sh_;
  DeviceBuffer<float> image_, image_grad_;
  std::shared_ptr<DeviceBuffer<float>> device_render_;  // RenderToDevice's buffer, reused while no caller holds it
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
  // A view's image kept on another device (Target): two slots used in turn, each a pinned host
  // copy, a device copy [H][W][3] and an event at the end of its upload. The pinned copy makes the
  // upload asynchronous (a pageable one waits for the stream's queued work), and with two slots
  // staging an image waits only for the upload before last.
  struct TransientTarget {
    float* pinned = nullptr;  // cudaMallocHost, `capacity` floats
    size_t capacity = 0;
    DeviceBuffer<float> device;
    cudaEvent_t uploaded = nullptr;
  };
  std::array<TransientTarget, 2> transient_;
  size_t next_transient_ = 0;
  StatusOr<const float*> TransientTargetOf(const Image& image);
  uint64_t peak_memory_ = 0;
  // Profiling (options_.profile).
  cudaEvent_t mark_event_ = nullptr, next_event_ = nullptr;
  std::map<std::string, double> profile_ms_;
  int64_t profiled_steps_ = 0;
  int64_t deform_passes_ = 0;  // deformation backward passes (one per distinct time of a batch)
};

}  // namespace atex::cuda::internal
