// The CUDA backend's profiling: per-stage device times of Step (Mark, Profile) and
// render timing (Time, behind TimeRender).
#include <algorithm>

#include "cuda_backend_impl.h"

namespace atex::cuda::internal {

nlohmann::json CudaBackend::Profile() const {
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
StatusOr<RenderTiming> CudaBackend::Time(const Camera& camera, const train::RenderRequest& request, int repeats,
                                         int warmup) {
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

// Profiling: elapsed device time since the previous mark, added to `stage`.
Status CudaBackend::Mark(const char* stage) {
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

}  // namespace atex::cuda::internal
