// The CUDA training backend: implements atex::train::Backend on one GPU.
#pragma once

#include <memory>
#include <string>

#include "atex/status.h"
#include "atex/train/backend.h"

namespace atex::cuda {

// True when a CUDA device can be used; otherwise `why` says what is missing
// (no device, driver too old, ...).
bool DeviceAvailable(std::string* why);
// "NVIDIA H100 80GB HBM3 (sm_90, 79.2 GiB)" for the current device, or the reason there is none.
std::string DeviceDescription();

struct CudaBackendOptions {
  int device = 0;
  train::AdamSettings adam;
  // TF32 tensor cores for the deformation MLP's GEMMs (10-bit mantissa products,
  // FP32 accumulation): several times faster; training tolerates it. Parity tests
  // use FP32 (tf32 = false) to compare with the CPU reference at 1e-4.
  bool tf32 = true;
  // Time every stage of Step with CUDA events (one synchronisation per stage);
  // the totals come back from Backend::Profile().
  bool profile = false;
};

// Fails with kNoDevice (and a hint to use the CPU backend for tiny scenes) when no GPU is usable.
StatusOr<std::unique_ptr<train::Backend>> MakeCudaBackend(const CudaBackendOptions& options = {});

// Render timing on the device: deformation + projection + tile sort + rasterisation of
// one frame, measured with CUDA events around `repeats` renders after `warmup` ones
// (the image stays on the device). `backend` must come from MakeCudaBackend.
struct RenderTiming {
  double median_ms = 0, min_ms = 0, max_ms = 0;
  int visible = 0;  // Gaussians with a positive radius in the frame
};
StatusOr<RenderTiming> TimeRender(train::Backend& backend, const Camera& camera, const train::RenderRequest& request,
                                  int repeats = 100, int warmup = 10);

// A render left in device memory, for consumers on the same GPU (DLPack: PyTorch, CuPy):
// `pixels` is [height][width][3] float32 RGB (unclamped, as Backend::Render) on CUDA device
// `device`, valid while `owner` lives (owner's destructor frees it, on any thread). The
// render is complete when RenderOnDevice returns (the backend's stream is synchronised),
// so a consumer on another stream may read it at once. The backend reuses one buffer for
// its renders while no caller holds it, so a caller that drops each render before asking
// for the next pays no allocation. `backend` must come from MakeCudaBackend
// (kInvalidArgument otherwise); render errors as Backend::Render.
struct DeviceImage {
  std::shared_ptr<const void> owner;
  const float* pixels = nullptr;
  int width = 0, height = 0, device = 0;
};
StatusOr<DeviceImage> RenderOnDevice(train::Backend& backend, const Camera& camera,
                                     const train::RenderRequest& request);

}  // namespace atex::cuda
