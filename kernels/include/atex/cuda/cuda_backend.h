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
};

// Fails with kNoDevice (and a hint to use the CPU backend for tiny scenes) when no GPU is usable.
StatusOr<std::unique_ptr<train::Backend>> MakeCudaBackend(const CudaBackendOptions& options = {});

}  // namespace atex::cuda
