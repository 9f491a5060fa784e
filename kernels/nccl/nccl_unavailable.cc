// This build has no NCCL (CMake did not find nccl.h and libnccl, or ATEX_NCCL=OFF).
#include "atex/cuda/nccl_communicator.h"

namespace atex::cuda {

bool NcclAvailable() { return false; }

StatusOr<std::unique_ptr<train::Communicator>> MakeNcclCommunicator(const train::LaunchEnvironment& env, int) {
  return MakeError(StatusCode::kUnsupported, "this build has no NCCL (configure with the NCCL headers and library "
                   "of the CUDA toolkit or libnccl-dev, ATEX_NCCL=ON): cannot train with ", env.world_size,
                   " GPUs");
}

}  // namespace atex::cuda
