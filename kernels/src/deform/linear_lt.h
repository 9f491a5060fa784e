// A linear layer with its bias and ReLU fused into the GEMM (cuBLASLt's RELU_BIAS
// epilogue), for the MLP's hidden layers: without it, a separate bias + ReLU pass reads
// and writes every [N][W] activation once more, which Nsight Compute measured at a third
// of an untextured frame (BENCHMARKS.md, issue 4).
#pragma once

#include <cstdint>
#include <vector>

#include <cublasLt.h>
#include <cuda_runtime.h>

#include "atex/status.h"
#include "device_buffer.h"

namespace atex::cuda::deform_detail {

class FusedLinearRelu {
 public:
  FusedLinearRelu() = default;
  ~FusedLinearRelu();
  FusedLinearRelu(const FusedLinearRelu&) = delete;
  FusedLinearRelu& operator=(const FusedLinearRelu&) = delete;

  // y[r][o] = max(0, sum_i x[r][i] * w[o][i] + bias[o]) for r < rows (row-major, x: row
  // stride ldx, y: row stride ldy; w [out][in], bias [out], all on the device), on `stream`,
  // in FP32 or with TF32 tensor cores when allow_tf32.
  // Sets *fused = false and does nothing when cuBLASLt offers no algorithm for this shape
  // and these pointer alignments: the caller then runs the GEMM and the bias + ReLU pass
  // itself. An error is a failure of cuBLASLt or CUDA, not a missing algorithm.
  Status Forward(const float* w, int in, int out, const float* x, int ldx, int rows, const float* bias, float* y,
                 int ldy, bool allow_tf32, cudaStream_t stream, bool* fused);

  size_t workspace_bytes() const { return workspace_.bytes(); }

 private:
  // One heuristic answer per problem shape, so that the heuristic query is not repeated on
  // every call (the shapes change only when densification changes N).
  struct Plan {
    int in, out, rows, ldx, ldy;
    bool tf32;
    uint32_t alignments;  // of w, x, y, bias (bytes, packed 8 bits each)
    bool found;
    cublasLtMatmulAlgo_t algo;
  };
  cublasLtHandle_t handle_ = nullptr;
  DeviceBuffer<uint8_t> workspace_;
  std::vector<Plan> plans_;
};

}  // namespace atex::cuda::deform_detail
