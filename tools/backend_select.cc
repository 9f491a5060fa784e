#include "backend_select.h"

#ifdef ATEX_HAVE_CUDA
#include "atex/cuda/cuda_backend.h"
#endif

namespace atex::cli {

StatusOr<SelectedBackend> SelectBackend(const std::string& name, const BackendChoice& choice) {
  SelectedBackend selected;
  if (name == "cpu") {
    selected.backend = train::MakeCpuBackend();
    selected.description = "cpu (reference engine)";
    return selected;
  }
  if (name != "cuda" && name != "auto") {
    return MakeError(StatusCode::kInvalidArgument, "unknown backend '", name, "' (auto, cuda, cpu)");
  }
#ifdef ATEX_HAVE_CUDA
  std::string why;
  if (cuda::DeviceAvailable(&why)) {
    cuda::CudaBackendOptions options;
    options.tf32 = choice.tf32;
    options.profile = choice.profile;
    options.device = choice.device;
    ATEX_ASSIGN_OR_RETURN(selected.backend, cuda::MakeCudaBackend(options));
    selected.description = "cuda: " + cuda::DeviceDescription() + (choice.tf32 ? ", TF32 MLP" : ", FP32 MLP");
    return selected;
  }
  if (name == "cuda") {
    return MakeError(StatusCode::kNoDevice, "no usable CUDA device (", why,
                     "); the CPU reference backend (--backend cpu) trains tiny scenes such as the 100x100 lego");
  }
  selected.note = "no CUDA device (" + why + "): using the CPU reference backend, which is only practical for tiny "
                  "scenes";
#else
  if (name == "cuda") {
    return MakeError(
        StatusCode::kNoDevice,
        "this build has no CUDA backend (configured with ATEX_CUDA=OFF or without nvcc); use --backend cpu");
  }
  selected.note = "this build has no CUDA backend: using the CPU reference backend";
#endif
  selected.backend = train::MakeCpuBackend();
  selected.description = "cpu (reference engine)";
  return selected;
}

}  // namespace atex::cli
