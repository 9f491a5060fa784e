// atex::train::Backend on one GPU: parameters, gradients and Adam moments live
// in device buffers; each Step runs, per view, deform → render → loss → backward
// (one view's activations alive at a time), then one fused Adam update per group.
// This file: device queries, construction and Render; the other seams are listed in
// cuda_backend_impl.h.
#include <algorithm>

#include "cuda_backend_impl.h"

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

namespace internal {

CudaBackend::~CudaBackend() {
  if (stream_) cudaStreamSynchronize(stream_);  // no upload from a pinned copy in flight
  for (TransientTarget& slot : transient_) {
    if (slot.pinned) cudaFreeHost(slot.pinned);
    if (slot.uploaded) cudaEventDestroy(slot.uploaded);
  }
  if (mark_event_) cudaEventDestroy(mark_event_);
  if (next_event_) cudaEventDestroy(next_event_);
  deform_.reset();
  render_.reset();
  loss_.reset();
  if (cublas_) cublasDestroy(cublas_);
  if (stream_) cudaStreamDestroy(stream_);
}

Status CudaBackend::Init() {
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

Status CudaBackend::RenderInto(const Camera& camera, const train::RenderRequest& request, float* out) {
  train::StepRequest step;
  step.apply_deformation = request.apply_deformation && has_deformation_;
  step.active_sh_degree = std::min(request.active_sh_degree, sh_degree_);
  const bool textured = request.use_textures && has_textures_;
  RenderInputs inputs;
  RenderGradients unused;
  ATEX_RETURN_IF_ERROR(PrepareView(step, camera.time, textured, /*new_time=*/true, &inputs, &unused));
  for (int k = 0; k < 3; ++k) inputs.background[k] = request.background[k];
  const detail::CameraModel<float> cam = detail::MakeCameraModel<float>(camera, request.near_plane);
  return render_->Forward(cam, inputs, out, nullptr, nullptr);
}

StatusOr<Image> CudaBackend::Render(const Camera& camera, const train::RenderRequest& request) {
  const size_t pixels = size_t(camera.width) * camera.height;
  ATEX_RETURN_IF_ERROR(image_.Resize(pixels * 3));
  ATEX_RETURN_IF_ERROR(RenderInto(camera, request, image_.data()));
  Image out(camera.width, camera.height, 3);
  ATEX_CUDA_RETURN_IF_ERROR(cudaMemcpyAsync(out.pixels.data(), image_.data(), pixels * 3 * sizeof(float),
                                            cudaMemcpyDeviceToHost, stream_));
  ATEX_CUDA_RETURN_IF_ERROR(cudaStreamSynchronize(stream_));
  return out;
}

StatusOr<DeviceImage> CudaBackend::RenderToDevice(const Camera& camera, const train::RenderRequest& request) {
  // A caller that still holds the last render keeps it: render into a new buffer then.
  if (device_render_ == nullptr || device_render_.use_count() > 1) {
    device_render_ = std::make_shared<DeviceBuffer<float>>();
  }
  const size_t pixels = size_t(camera.width) * camera.height;
  ATEX_RETURN_IF_ERROR(device_render_->Resize(pixels * 3));
  ATEX_RETURN_IF_ERROR(RenderInto(camera, request, device_render_->data()));
  ATEX_CUDA_RETURN_IF_ERROR(cudaStreamSynchronize(stream_));
  DeviceImage out;
  out.owner = device_render_;
  out.pixels = device_render_->data();
  out.width = camera.width;
  out.height = camera.height;
  out.device = options_.device;
  return out;
}

}  // namespace internal

using internal::CudaBackend;

StatusOr<RenderTiming> TimeRender(train::Backend& backend, const Camera& camera, const train::RenderRequest& request,
                                  int repeats, int warmup) {
  auto* cuda = dynamic_cast<CudaBackend*>(&backend);
  if (cuda == nullptr) return MakeError(StatusCode::kInvalidArgument, "TimeRender needs the CUDA backend");
  if (repeats < 1 || warmup < 0) return MakeError(StatusCode::kInvalidArgument, "TimeRender: bad repeat counts");
  return cuda->Time(camera, request, repeats, warmup);
}

StatusOr<DeviceImage> RenderOnDevice(train::Backend& backend, const Camera& camera,
                                     const train::RenderRequest& request) {
  auto* cuda = dynamic_cast<CudaBackend*>(&backend);
  if (cuda == nullptr) return MakeError(StatusCode::kInvalidArgument, "RenderOnDevice needs the CUDA backend");
  return cuda->RenderToDevice(camera, request);
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
