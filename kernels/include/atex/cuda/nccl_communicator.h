// Data parallelism across GPUs and machines through NCCL (docs/multi_gpu.md). Built when CMake
// finds nccl.h and libnccl (ATEX_NCCL=AUTO|ON|OFF); without it the functions below say so.
#pragma once

#include <memory>

#include "atex/status.h"
#include "atex/train/communicator.h"
#include "atex/train/tcp_rendezvous.h"

namespace atex::cuda {

// True when this build has NCCL.
bool NcclAvailable();

// This rank's communicator of the group that `env` describes (RANK, WORLD_SIZE, MASTER_ADDR,
// MASTER_PORT): rank 0 creates the NCCL unique id and hands it to the others over TCP
// (train::ExchangeBlob), then every rank joins the NCCL communicator on CUDA device `device`
// (made current for this thread). Collective across the processes of the group. Host
// collectives go through a device scratch buffer; AllReduceSumDevice reduces device buffers in
// one grouped NCCL call on the caller's stream. kUnsupported without NCCL; kNoDevice /
// kIoError / kInternal naming NCCL's error otherwise.
StatusOr<std::unique_ptr<train::Communicator>> MakeNcclCommunicator(const train::LaunchEnvironment& env,
                                                                    int device);

}  // namespace atex::cuda
