// Deformation field on the GPU: HexPlane sampling + MLP trunk + heads, forward and
// backward, computing exactly docs/conventions.md §3 (parity with libatex/src/deform).
//
// Device layouts (differ from the asset where that makes access coalesced):
// - grid: every plane of every scale concatenated, scale-major then plane order
//   xy, xz, xt, yz, yt, zt; each plane stored CHANNEL-LAST [res_b][res_a][C]
//   (the asset stores [C][res_b][res_a]; Upload/Download transpose).
// - mlp: every linear layer concatenated: trunk layers in order, then for each ENABLED
//   head in order position, scale, rotation, opacity, SH: hidden layer, output layer;
//   each layer is weight [out][in] row-major followed by bias [out].
// Gradient and Adam-moment buffers use the same layouts.
#pragma once

#include <array>
#include <cstddef>
#include <memory>
#include <vector>

#include <cublas_v2.h>
#include <cuda_runtime.h>

#include "atex/model.h"
#include "atex/status.h"

namespace atex::cuda {

struct DeformLayout {
  DeformationConfig config;
  size_t grid_size = 0;                // floats
  size_t mlp_size = 0;                 // floats
  std::vector<size_t> plane_offset;    // [scales*6] into grid
  struct Layer { size_t weight = 0, bias = 0; int in = 0, out = 0; };
  std::vector<Layer> trunk;            // into mlp
  std::array<Layer, kNumDeformHeads> head_hidden{}, head_output{};  // in == 0 when the head is off
  static DeformLayout Make(const DeformationConfig& config);
};

// Host <-> device (transposing the planes). `grid`/`mlp` are device pointers of the layout's sizes.
Status UploadDeformation(const DeformationField& field, const DeformLayout& layout, float* grid, float* mlp,
                         cudaStream_t stream);
Status DownloadDeformation(const float* grid, const float* mlp, const DeformLayout& layout, DeformationField* field,
                           cudaStream_t stream);

// Per-Gaussian tensors on the device (canonical inputs or deformed outputs or their gradients).
struct GaussianTensors {
  float* positions = nullptr;   // [N][3]
  float* log_scales = nullptr;  // [N][3]
  float* rotations = nullptr;   // [N][4] (w, x, y, z)
  float* opacity = nullptr;     // [N]   logits
  float* sh = nullptr;          // [N][K][3]
};

// Pointer conventions of the engine: every per-Gaussian tensor is row-major and densely packed with the
// shapes of GaussianTensors; a null OUTPUT tensor (deformed or grad_canonical) is not written; a null
// grad_deformed tensor counts as zero. `deformed` must not alias `canonical` (Backward re-reads the
// canonical positions). All work is enqueued on the engine's stream; nothing synchronises except
// where a result goes to the host. Parameters are validated (kInvalidArgument / kUnsupported) before
// anything is launched.
class DeformEngine {
 public:
  // The engine uses (and restores after each call) the handle's stream, math mode and pointer mode.
  DeformEngine(cublasHandle_t cublas, cudaStream_t stream);
  ~DeformEngine();
  DeformEngine(const DeformEngine&) = delete;
  DeformEngine& operator=(const DeformEngine&) = delete;

  // FP32 GEMMs by default (parity with the CPU engine). Allowing TF32 tensor cores makes the MLP several
  // times faster at about 1e-3 relative precision (training only; parity tests keep it off).
  void set_allow_tf32(bool allow);
  // Hidden layers run as one cuBLASLt GEMM with bias + ReLU in its epilogue (default), or
  // as a cuBLAS GEMM followed by a bias + ReLU pass (the A/B and the fallback where
  // cuBLASLt has no algorithm). Both compute the same function.
  void set_fuse_bias_relu(bool fuse);
  // How many hidden layers the last Forward ran fused and unfused.
  int last_forward_fused_layers() const;
  int last_forward_unfused_layers() const;

  // Deforms n canonical Gaussians to scene time `time` (mapped by the config's time_scale/offset).
  // Keeps what Backward needs in the engine's workspace (valid until the next Forward; Backward may be
  // called several times for one Forward). canonical.positions is required; the other canonical tensors
  // only where the matching deformed tensor is requested. Disabled heads copy canonical to deformed.
  // The workspace grows with n and is never shrunk: about 4·n·(S·C + (trunk_layers + heads)·W) bytes
  // after Forward, twice that after Backward.
  Status Forward(const DeformLayout& layout, const float* grid, const float* mlp, int n, int sh_coeffs, float time,
                 const GaussianTensors& canonical, const GaussianTensors& deformed);
  // Given d(loss)/d(deformed) (null pointers = zero), ACCUMULATES (+=) into grad_grid, grad_mlp and
  // d(loss)/d(canonical) (positions receive both the residual path and the sampling-coordinate path).
  // A null grad_grid / grad_mlp / grad_canonical tensor is skipped (and work only it needs is not done).
  // The arguments must be those of the last Forward (same n, time, grid, mlp, canonical positions),
  // else kInvalidArgument. Plane gradients are summed with float atomics: not bit-reproducible.
  Status Backward(const DeformLayout& layout, const float* grid, const float* mlp, int n, int sh_coeffs, float time,
                  const GaussianTensors& canonical, const GaussianTensors& grad_deformed, float* grad_grid,
                  float* grad_mlp, const GaussianTensors& grad_canonical);
  // 4DGaussians' regularisers on the planes (atex::DeformRegularizer's definition); adds the loss to
  // *loss_device (device scalar; null = value not wanted) and the gradient (+=) to grad_grid (null = not
  // wanted).
  Status Regularizer(const DeformLayout& layout, const float* grid, float plane_tv, float time_smoothness,
                     float time_l1, float* grad_grid, float* loss_device);

  size_t workspace_bytes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace atex::cuda
