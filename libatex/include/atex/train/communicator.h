// Collectives between the ranks of a data-parallel training run (docs/multi_gpu.md).
//
// Every rank holds one Communicator of the same group. Every call below is COLLECTIVE:
// all ranks of the group make the same calls in the same order with the same sizes
// (and the same root); a rank that skips one leaves the others waiting. The results
// are deterministic: a sum is reduced in rank order, so every rank gets bit-identical
// values and a rerun with the same inputs gets the same bits.
//
// Implementations: SingleRankCommunicator (one rank, every collective a no-op), the
// in-process group below (ranks as threads: CI and `atex train --backend cpu --ranks N`),
// and NcclCommunicator in kernels/ (one process per GPU).
#pragma once

#include <chrono>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "atex/status.h"

namespace atex::train {

class Communicator {
 public:
  virtual ~Communicator() = default;
  // This rank's index in [0, world_size()).
  virtual int rank() const = 0;
  // The number of ranks in the group (>= 1).
  virtual int world_size() const = 0;
  // A short name for reports ("single", "in-process", "nccl").
  virtual std::string name() const = 0;

  // Replaces data[0..count) (host memory) on every rank with the element-wise sum over the
  // ranks, added in rank order. kInvalidArgument when the ranks disagree on count;
  // kNoDevice / kIoError / kInternal when the transport fails (the group is then unusable).
  virtual Status AllReduceSum(float* data, size_t count) = 0;
  virtual Status AllReduceSum(double* data, size_t count) = 0;
  // As AllReduceSum, with the element-wise maximum (max screen radii).
  virtual Status AllReduceMax(float* data, size_t count) = 0;
  // Copies bytes[0..n) of rank `root` into bytes[0..n) of every other rank (host memory).
  // kInvalidArgument when the ranks disagree on n or root, or root is not a rank.
  virtual Status Broadcast(void* bytes, size_t n, int root) = 0;
  // Returns once every rank has called it.
  virtual Status Barrier() = 0;
  // NOT collective: breaks the group after this rank failed, so that the other ranks' pending
  // and later collectives fail at once instead of waiting for it (the trainer calls it when a
  // run ends with an error). The group is unusable afterwards.
  virtual void Abort(const std::string& why) {}

  // Device memory (a GPU backend's gradients). A float buffer on this rank's device.
  struct DeviceBuffer {
    float* data = nullptr;
    size_t count = 0;
  };
  // Sums every buffer of `buffers` across the ranks in place, as ONE grouped operation
  // enqueued on `stream` (a cudaStream_t; the call returns once it is enqueued, the stream
  // orders it after the backward pass that wrote the buffers and before the Adam update).
  // Every rank passes the same list of counts. Host-only communicators: kUnsupported.
  virtual Status AllReduceSumDevice(const std::vector<DeviceBuffer>& buffers, void* stream) {
    return MakeError(StatusCode::kUnsupported, "the ", name(), " communicator reduces host memory only");
  }
};

// One rank, no peers: every collective leaves the data as it is. The trainer's default.
class SingleRankCommunicator final : public Communicator {
 public:
  int rank() const override { return 0; }
  int world_size() const override { return 1; }
  std::string name() const override { return "single"; }
  Status AllReduceSum(float*, size_t) override { return Status::Ok(); }
  Status AllReduceSum(double*, size_t) override { return Status::Ok(); }
  Status AllReduceMax(float*, size_t) override { return Status::Ok(); }
  Status Broadcast(void*, size_t, int root) override;
  Status Barrier() override { return Status::Ok(); }
};

// `ranks` communicators of one group whose collectives meet between threads of this process
// (one thread per rank; a rank's communicator is used by one thread at a time). A rank that
// waits longer than `timeout` for the others fails with kInternal naming the collective, and
// the group is broken from then on (every later call fails at once), so a mismatched
// schedule is an error, never a hang. kInvalidArgument when ranks < 1.
StatusOr<std::vector<std::unique_ptr<Communicator>>> MakeInProcessGroup(
    int ranks, std::chrono::milliseconds timeout = std::chrono::minutes(10));

// Helpers built on the collectives (all collective themselves).

// Broadcasts a string of any length from `root` (its length first, then its bytes).
Status BroadcastString(Communicator& comm, std::string* text, int root);

}  // namespace atex::train
