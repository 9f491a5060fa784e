// The NCCL communicator (atex/cuda/nccl_communicator.h): one process per GPU, the unique id
// exchanged over TCP by rank 0. Compiled only when CMake found NCCL.
#include "atex/cuda/nccl_communicator.h"

#include <cuda_runtime.h>
#include <nccl.h>

#include <cstring>
#include <string>
#include <vector>

namespace atex::cuda {
namespace {

Status CudaError(cudaError_t e, const char* what) {
  const bool no_device = e == cudaErrorNoDevice || e == cudaErrorInvalidDevice || e == cudaErrorInsufficientDriver;
  return MakeError(no_device ? StatusCode::kNoDevice : StatusCode::kInternal,
                   "NCCL communicator: ", what, ": ", cudaGetErrorString(e));
}

Status NcclError(ncclResult_t r, const char* what) {
  const StatusCode code = r == ncclSystemError || r == ncclRemoteError ? StatusCode::kIoError : StatusCode::kInternal;
  return MakeError(code, "NCCL: ", what, ": ", ncclGetErrorString(r));
}

#define ATEX_CUDA_OK(expr, what)                   \
  do {                                             \
    const cudaError_t atex_e = (expr);             \
    if (atex_e != cudaSuccess) return CudaError(atex_e, what); \
  } while (0)
#define ATEX_NCCL_OK(expr, what)                   \
  do {                                             \
    const ncclResult_t atex_r = (expr);            \
    if (atex_r != ncclSuccess) return NcclError(atex_r, what); \
  } while (0)

class NcclCommunicator final : public train::Communicator {
 public:
  NcclCommunicator(int rank, int ranks, int device) : rank_(rank), ranks_(ranks), device_(device) {}
  ~NcclCommunicator() override {
    if (comm_ != nullptr) ncclCommDestroy(comm_);
    if (scratch_ != nullptr) cudaFree(scratch_);
    if (stream_ != nullptr) cudaStreamDestroy(stream_);
  }

  Status Init(const ncclUniqueId& id) {
    ATEX_CUDA_OK(cudaSetDevice(device_), "cudaSetDevice");
    ATEX_CUDA_OK(cudaStreamCreateWithFlags(&stream_, cudaStreamNonBlocking), "cudaStreamCreate");
    ATEX_NCCL_OK(ncclCommInitRank(&comm_, ranks_, id, rank_), "ncclCommInitRank");
    return Status::Ok();
  }

  int rank() const override { return rank_; }
  int world_size() const override { return ranks_; }
  std::string name() const override { return "nccl"; }

  Status AllReduceSum(float* data, size_t count) override { return Host(data, count, ncclFloat32, ncclSum, 4); }
  Status AllReduceSum(double* data, size_t count) override { return Host(data, count, ncclFloat64, ncclSum, 8); }
  Status AllReduceMax(float* data, size_t count) override { return Host(data, count, ncclFloat32, ncclMax, 4); }

  Status Broadcast(void* bytes, size_t n, int root) override {
    if (root < 0 || root >= ranks_) {
      return MakeError(StatusCode::kInvalidArgument, "broadcast root ", root, " is not a rank of ", ranks_);
    }
    if (n == 0) return Status::Ok();
    ATEX_RETURN_IF_ERROR(Reserve(n));
    ATEX_CUDA_OK(cudaMemcpyAsync(scratch_, bytes, n, cudaMemcpyHostToDevice, stream_), "upload");
    ATEX_NCCL_OK(ncclBroadcast(scratch_, scratch_, n, ncclChar, root, comm_, stream_), "ncclBroadcast");
    ATEX_CUDA_OK(cudaMemcpyAsync(bytes, scratch_, n, cudaMemcpyDeviceToHost, stream_), "download");
    ATEX_CUDA_OK(cudaStreamSynchronize(stream_), "broadcast");
    return Status::Ok();
  }

  // ncclCommAbort ends this rank's pending NCCL work; the peers' calls fail or hang until the
  // launcher (atex --gpus, torchrun) stops them after this process exits.
  void Abort(const std::string&) override {
    if (comm_ != nullptr) ncclCommAbort(comm_);
    comm_ = nullptr;
  }

  Status Barrier() override {
    float one = 1.0f;
    return AllReduceSum(&one, 1);
  }

  // One NCCL group: the launches fuse, and the stream orders them after the backward pass.
  Status AllReduceSumDevice(const std::vector<DeviceBuffer>& buffers, void* stream) override {
    if (buffers.empty()) return Status::Ok();
    auto s = static_cast<cudaStream_t>(stream);
    ATEX_NCCL_OK(ncclGroupStart(), "ncclGroupStart");
    for (const DeviceBuffer& b : buffers) {
      if (b.count == 0) continue;
      const ncclResult_t r = ncclAllReduce(b.data, b.data, b.count, ncclFloat32, ncclSum, comm_, s);
      if (r != ncclSuccess) {
        ncclGroupEnd();
        return NcclError(r, "ncclAllReduce (gradients)");
      }
    }
    ATEX_NCCL_OK(ncclGroupEnd(), "ncclGroupEnd (gradients)");
    return Status::Ok();
  }

 private:
  Status Reserve(size_t bytes) {
    if (bytes <= scratch_bytes_) return Status::Ok();
    if (scratch_ != nullptr) cudaFree(scratch_);
    scratch_ = nullptr;
    scratch_bytes_ = 0;
    ATEX_CUDA_OK(cudaMalloc(&scratch_, bytes), "scratch buffer");
    scratch_bytes_ = bytes;
    return Status::Ok();
  }

  // Host memory through the device scratch buffer (statistics, scalars: small and rare).
  Status Host(void* data, size_t count, ncclDataType_t type, ncclRedOp_t op, size_t element) {
    if (count == 0) return Status::Ok();
    const size_t bytes = count * element;
    ATEX_RETURN_IF_ERROR(Reserve(bytes));
    ATEX_CUDA_OK(cudaMemcpyAsync(scratch_, data, bytes, cudaMemcpyHostToDevice, stream_), "upload");
    ATEX_NCCL_OK(ncclAllReduce(scratch_, scratch_, count, type, op, comm_, stream_), "ncclAllReduce");
    ATEX_CUDA_OK(cudaMemcpyAsync(data, scratch_, bytes, cudaMemcpyDeviceToHost, stream_), "download");
    ATEX_CUDA_OK(cudaStreamSynchronize(stream_), "all-reduce");
    return Status::Ok();
  }

  int rank_, ranks_, device_;
  ncclComm_t comm_ = nullptr;
  cudaStream_t stream_ = nullptr;
  void* scratch_ = nullptr;
  size_t scratch_bytes_ = 0;
};

}  // namespace

bool NcclAvailable() { return true; }

StatusOr<std::unique_ptr<train::Communicator>> MakeNcclCommunicator(const train::LaunchEnvironment& env,
                                                                    int device) {
  ATEX_CUDA_OK(cudaSetDevice(device), "cudaSetDevice");
  ncclUniqueId id;
  std::vector<uint8_t> blob(sizeof(id));
  if (env.rank == 0) {
    ATEX_NCCL_OK(ncclGetUniqueId(&id), "ncclGetUniqueId");
    std::memcpy(blob.data(), &id, sizeof(id));
  }
  ATEX_RETURN_IF_ERROR(train::ExchangeBlob(env.master_addr, env.master_port, env.rank, env.world_size, &blob));
  if (blob.size() != sizeof(id)) {
    return MakeError(StatusCode::kCorrupt, "NCCL rendezvous: rank 0 sent ", blob.size(), " bytes, not the ",
                     sizeof(id), " of an ncclUniqueId");
  }
  std::memcpy(&id, blob.data(), sizeof(id));
  auto comm = std::make_unique<NcclCommunicator>(env.rank, env.world_size, device);
  ATEX_RETURN_IF_ERROR(comm->Init(id));
  return std::unique_ptr<train::Communicator>(std::move(comm));
}

}  // namespace atex::cuda
