// `atex train` with several ranks (docs/multi_gpu.md): one process per GPU started by atex
// itself (--gpus), one rank of a group started by a launcher (RANK/WORLD_SIZE/... set), or
// ranks as threads on the CPU backend (--ranks).
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "atex/status.h"
#include "atex/train/communicator.h"
#include "atex/train/tcp_rendezvous.h"

namespace atex::cli {

// "0,1,3" -> {0, 1, 3}; kInvalidArgument naming the item that is not a device index, or a
// repeated one.
StatusOr<std::vector<int>> ParseGpuList(const std::string& text);

// Whether this build can train on several GPUs (CUDA and NCCL).
bool MultiGpuAvailable();

// Runs this program again once per GPU of `gpus` (the same command line, read from
// /proc/self/cmdline), each child with RANK, WORLD_SIZE, LOCAL_RANK = its index,
// MASTER_ADDR=127.0.0.1, MASTER_PORT (the environment's, else a free port) and
// CUDA_VISIBLE_DEVICES=<its GPU>, and waits for them. When one fails, the others are stopped.
// Returns the first failing child's exit code, or 0.
StatusOr<int> LaunchGpuRanks(const std::vector<int>& gpus);

// This process as one rank of a launched group: the NCCL communicator (rank 0 hands out the id
// over TCP) on the device of LOCAL_RANK, or device 0 when CUDA_VISIBLE_DEVICES names one GPU.
// `device` receives the device index for the CUDA backend.
StatusOr<std::unique_ptr<train::Communicator>> JoinLaunchedGroup(const train::LaunchEnvironment& env, int* device);

// Runs body(rank, communicator) on `ranks` threads of an in-process group and returns rank 0's
// status (or the first failure of another rank when rank 0 succeeded).
Status RunThreadRanks(int ranks, const std::function<Status(int, train::Communicator&)>& body);

}  // namespace atex::cli
