// The rendezvous of a multi-process (multi-node) training run: rank 0 hands one blob (the NCCL
// unique id, 128 bytes) to every other rank over TCP, at MASTER_ADDR:MASTER_PORT, as torchrun
// and Slurm set them (docs/multi_gpu.md). POSIX sockets; no GPU needed, so CI tests it.
#pragma once

#include <chrono>
#include <cstdint>
#include <string>
#include <vector>

#include "atex/status.h"

namespace atex::train {

// RANK, WORLD_SIZE, LOCAL_RANK, MASTER_ADDR, MASTER_PORT of the environment.
struct LaunchEnvironment {
  int rank = 0, world_size = 1, local_rank = 0;
  std::string master_addr = "127.0.0.1";
  int master_port = 29500;
};
// Reads the variables above; `present` is set when RANK and WORLD_SIZE are both set (a launcher
// started this process as one rank). kInvalidArgument naming the variable when one is not a
// number in range (RANK in [0, WORLD_SIZE), WORLD_SIZE >= 1, MASTER_PORT in 1..65535).
StatusOr<LaunchEnvironment> ReadLaunchEnvironment(bool* present);

// Rank 0 (`rank` == 0): listens on port `port` of all interfaces, accepts world_size - 1
// connections, reads each peer's rank and sends it `blob`. Other ranks: connect to
// `host`:`port` (retrying until `timeout`, since rank 0 may start later), send their rank and
// receive the blob into `blob` (resized). Each rank returns once it has its copy; rank 0 once
// every peer has one. kIoError naming the host, port and system error on a socket failure or
// when `timeout` passes; kInvalidArgument for a rank outside [0, world_size) or a repeated rank.
Status ExchangeBlob(const std::string& host, int port, int rank, int world_size, std::vector<uint8_t>* blob,
                    std::chrono::milliseconds timeout = std::chrono::minutes(5));

}  // namespace atex::train
