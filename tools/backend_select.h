// Choosing the compute backend for train/eval/render: "cuda", "cpu" or "auto"
// (CUDA when this build has it and a device is present, else the CPU reference).
#pragma once

#include <memory>
#include <string>

#include "atex/status.h"
#include "atex/train/backend.h"

namespace atex::cli {

struct SelectedBackend {
  std::unique_ptr<train::Backend> backend;
  std::string description;  // e.g. "cuda: NVIDIA H100 80GB HBM3 (sm_90, 79.1 GiB)"
  std::string note;         // why "auto" fell back to the CPU, if it did
};

struct BackendChoice {
  bool tf32 = true;      // CUDA: TF32 tensor cores for the deformation MLP
  bool profile = false;  // CUDA: per-stage timing (Backend::Profile)
  int device = 0;        // CUDA: the device index (among the visible ones)
};
StatusOr<SelectedBackend> SelectBackend(const std::string& name, const BackendChoice& choice = {});

}  // namespace atex::cli
