// DeformEngine: schedules one deformation pass on the GPU.
//
// Forward:  sample features [N][F] -> trunk (SGEMM + bias/ReLU per layer) -> the hidden
//           layers of all enabled heads as ONE packed GEMM ([He*W][W] weights copied
//           together) + bias/ReLU -> per head: deformed = canonical + bias (one pass),
//           then deformed += hidden_h * W2^T (SGEMM with beta = 1).
// Backward: per head: dW2 (SGEMM), db2 (column sums), and the masked hidden gradient
//           fused with db1 (one pass, NarrowLinearBackward) -> packed dW1 (one SGEMM)
//           and the trunk-output gradient (one SGEMM, k = He*W) -> trunk layers in
//           reverse -> feature gradient -> plane and position gradients (atomics).
// Stored for backward: features, the ReLU outputs of every trunk layer and of every
// head's hidden layer (ReLU'(z) = [ReLU(z) > 0], so pre-activations are not kept).
#include <algorithm>
#include <cmath>
#include <cstdint>

#include "cuda_check.h"
#include "deform/deform_cuda.h"
#include "deform/deform_internal.h"
#include "deform/linear_gemm.h"
#include "deform/linear_lt.h"
#include "device_buffer.h"

namespace atex::cuda {
namespace {

using deform_detail::LinearBackwardData;
using deform_detail::LinearBackwardWeight;
using deform_detail::LinearForward;

// The per-Gaussian tensor that head h deforms, and its row width.
float* HeadTensor(const GaussianTensors& t, int head) {
  switch (head) {
    case kHeadPosition: return t.positions;
    case kHeadScale: return t.log_scales;
    case kHeadRotation: return t.rotations;
    case kHeadOpacity: return t.opacity;
    default: return t.sh;
  }
}
int TensorWidth(int head, int sh_coeffs) {
  switch (head) {
    case kHeadPosition: return 3;
    case kHeadScale: return 3;
    case kHeadRotation: return 4;
    case kHeadOpacity: return 1;
    default: return 3 * sh_coeffs;
  }
}
const char* TensorName(int head) {
  static constexpr const char* kNames[kNumDeformHeads] = {"positions", "log_scales", "rotations", "opacity", "sh"};
  return kNames[head];
}

Status CheckCommon(const char* what, const DeformLayout& layout, const float* grid, const float* mlp, int n,
                   int sh_coeffs, float time, const GaussianTensors& canonical) {
  ATEX_RETURN_IF_ERROR(CheckDeformLayout(layout).WithContext(what));
  if (n < 0) return MakeError(StatusCode::kInvalidArgument, what, ": negative Gaussian count ", n);
  if (sh_coeffs < 0 || sh_coeffs > ShCoeffCount(kMaxShDegree)) {
    return MakeError(StatusCode::kInvalidArgument, what, ": ", sh_coeffs, " SH coefficients per channel");
  }
  if (layout.config.heads[kHeadSH] && layout.config.sh_coeffs != sh_coeffs) {
    return MakeError(StatusCode::kInvalidArgument, what, ": the SH head is configured for ", layout.config.sh_coeffs,
                     " coefficients but the Gaussians have ", sh_coeffs);
  }
  if (!std::isfinite(time)) return MakeError(StatusCode::kInvalidArgument, what, ": non-finite time");
  if (n > 0 && (grid == nullptr || mlp == nullptr || canonical.positions == nullptr)) {
    return MakeError(StatusCode::kInvalidArgument, what, ": null grid, mlp or canonical positions");
  }
  return Status::Ok();
}

}  // namespace

struct DeformEngine::Impl {
  cublasHandle_t cublas = nullptr;
  cudaStream_t stream = nullptr;
  bool allow_tf32 = false;
  bool fuse_bias_relu = true;
  deform_detail::FusedLinearRelu fused_linear_relu;
  int fused_layers = 0, unfused_layers = 0;  // of the last Forward

  // Kept from Forward for Backward.
  DeviceBuffer<float> features;        // [N][F]
  DeviceBuffer<float> trunk_act;       // [L][N][W] ReLU(trunk layer output)
  DeviceBuffer<float> hidden;          // [N][He*W] ReLU(head hidden layer), enabled heads side by side
  DeviceBuffer<float> packed_weight;   // [He*W][W] hidden-layer weights of the enabled heads
  DeviceBuffer<float> packed_bias;     // [He*W]
  DeviceBuffer<float> trunk_bias;      // [L][W] the trunk biases, 16-byte aligned for the fused epilogue
  // Backward scratch.
  DeviceBuffer<float> d_hidden;        // [N][He*W]
  DeviceBuffer<float> d_act;           // [N][W]
  DeviceBuffer<float> d_act_next;      // [N][W]
  DeviceBuffer<float> d_features;      // [N][F]
  DeviceBuffer<float> d_packed_weight; // [He*W][W]
  DeviceBuffer<float> d_packed_bias;   // [He*W]
  DeviceBuffer<double> accumulator;    // [1] regulariser value

  // What the cached activations belong to.
  bool cached = false;
  int cached_n = 0;
  float cached_time = 0;
  const float* cached_grid = nullptr;
  const float* cached_mlp = nullptr;
  const float* cached_positions = nullptr;
  size_t cached_grid_size = 0, cached_mlp_size = 0;

  Status Forward(const DeformLayout& layout, const float* grid, const float* mlp, int n, int sh_coeffs, float time,
                 const GaussianTensors& canonical, const GaussianTensors& deformed);
  Status Backward(const DeformLayout& layout, const float* grid, const float* mlp, int n, int sh_coeffs, float time,
                  const GaussianTensors& canonical, const GaussianTensors& grad_deformed, float* grad_grid,
                  float* grad_mlp, const GaussianTensors& grad_canonical);
};

namespace {
// Every requested deformed tensor has its canonical input and does not alias it.
Status CheckForwardTensors(const GaussianTensors& canonical, const GaussianTensors& deformed, int n, int sh_coeffs) {
  for (int h = 0; h < kNumDeformHeads; ++h) {
    const float* in = HeadTensor(canonical, h);
    const float* out = HeadTensor(deformed, h);
    if (out == nullptr || n == 0 || TensorWidth(h, sh_coeffs) == 0) continue;
    if (in == nullptr) {
      return MakeError(StatusCode::kInvalidArgument, "DeformEngine::Forward: deformed ", TensorName(h),
                       " requested without canonical ", TensorName(h));
    }
    if (in == out) {
      return MakeError(StatusCode::kInvalidArgument, "DeformEngine::Forward: deformed ", TensorName(h),
                       " aliases the canonical tensor");
    }
  }
  return Status::Ok();
}
}  // namespace

Status DeformEngine::Impl::Forward(const DeformLayout& layout, const float* grid, const float* mlp, int n,
                                   int sh_coeffs, float time, const GaussianTensors& canonical,
                                   const GaussianTensors& deformed) {
  cached = false;
  ATEX_RETURN_IF_ERROR(CheckCommon("DeformEngine::Forward", layout, grid, mlp, n, sh_coeffs, time, canonical));
  ATEX_RETURN_IF_ERROR(CheckForwardTensors(canonical, deformed, n, sh_coeffs));
  const DeformationConfig& config = layout.config;
  const int width = config.mlp_width;
  const int feature_dim = config.grid.feature_dim();
  const int trunk_layers = config.trunk_layers;
  const int heads = EnabledHeadCount(config);
  const size_t rows = static_cast<size_t>(n);

  if (n > 0) {
    ATEX_RETURN_IF_ERROR(features.Resize(rows * feature_dim));
    ATEX_RETURN_IF_ERROR(trunk_act.Resize(static_cast<size_t>(trunk_layers) * rows * width));
    ATEX_RETURN_IF_ERROR(hidden.Resize(rows * static_cast<size_t>(heads) * width));
    ATEX_RETURN_IF_ERROR(packed_weight.Resize(static_cast<size_t>(heads) * width * width));
    ATEX_RETURN_IF_ERROR(packed_bias.Resize(static_cast<size_t>(heads) * width));

    ATEX_RETURN_IF_ERROR(trunk_bias.Resize(static_cast<size_t>(trunk_layers) * width));

    deform_detail::ScopedCublasSettings settings(cublas, stream, allow_tf32);
    ATEX_RETURN_IF_ERROR(settings.status());
    fused_layers = unfused_layers = 0;
    // y = ReLU(x W^T + b) over n rows (y: row stride `out`): one cuBLASLt GEMM with the bias
    // and ReLU in its epilogue where cuBLASLt has an algorithm, else GEMM + a bias/ReLU pass.
    auto linear_relu = [&](const float* w, int in, int out, const float* x, int ldx, const float* bias,
                           float* y) -> Status {
      bool fused = false;
      if (fuse_bias_relu) {
        ATEX_RETURN_IF_ERROR(
            fused_linear_relu.Forward(w, in, out, x, ldx, n, bias, y, out, allow_tf32, stream, &fused));
      }
      if (fused) {
        ++fused_layers;
        return Status::Ok();
      }
      ++unfused_layers;
      ATEX_RETURN_IF_ERROR(LinearForward(cublas, w, in, out, x, ldx, n, 0.0f, y, out));
      return deform_detail::LaunchBiasRelu(y, bias, n, out, stream);
    };

    const deform_detail::GridGeometry geometry = deform_detail::MakeGridGeometry(layout, time);
    ATEX_RETURN_IF_ERROR(
        deform_detail::LaunchSampleFeatures(geometry, grid, canonical.positions, n, features.data(), stream));

    // Trunk: act_l = ReLU(L_l(input_l)), input_0 = features.
    for (int l = 0; l < trunk_layers; ++l) {
      const DeformLayout::Layer& layer = layout.trunk[l];
      const float* input = l == 0 ? features.data() : trunk_act.data() + (l - 1) * rows * width;
      float* output = trunk_act.data() + l * rows * width;
      float* bias = trunk_bias.data() + static_cast<size_t>(l) * width;
      ATEX_CUDA_RETURN_IF_ERROR(
          cudaMemcpyAsync(bias, mlp + layer.bias, sizeof(float) * width, cudaMemcpyDeviceToDevice, stream));
      ATEX_RETURN_IF_ERROR(linear_relu(mlp + layer.weight, layer.in, width, input, layer.in, bias, output));
    }
    const float* head_input = trunk_act.data() + (trunk_layers - 1) * rows * width;

    if (heads > 0) {
      const int packed = heads * width;
      int e = 0;
      for (int h = 0; h < kNumDeformHeads; ++h) {
        if (!config.heads[h]) continue;
        const DeformLayout::Layer& layer = layout.head_hidden[h];
        ATEX_CUDA_RETURN_IF_ERROR(cudaMemcpyAsync(packed_weight.data() + static_cast<size_t>(e) * width * width,
                                                  mlp + layer.weight, sizeof(float) * width * width,
                                                  cudaMemcpyDeviceToDevice, stream));
        ATEX_CUDA_RETURN_IF_ERROR(cudaMemcpyAsync(packed_bias.data() + static_cast<size_t>(e) * width,
                                                  mlp + layer.bias, sizeof(float) * width, cudaMemcpyDeviceToDevice,
                                                  stream));
        ++e;
      }
      ATEX_RETURN_IF_ERROR(
          linear_relu(packed_weight.data(), width, packed, head_input, width, packed_bias.data(), hidden.data()));
    }

    // Outputs: enabled heads add their residual, disabled ones copy.
    int e = 0;
    for (int h = 0; h < kNumDeformHeads; ++h) {
      const int cols = TensorWidth(h, sh_coeffs);
      const float* in = HeadTensor(canonical, h);
      float* out = HeadTensor(deformed, h);
      const bool enabled = config.heads[h];
      if (out != nullptr && cols > 0) {
        if (enabled) {
          const DeformLayout::Layer& layer = layout.head_output[h];
          ATEX_RETURN_IF_ERROR(deform_detail::LaunchAddBias(in, mlp + layer.bias, n, cols, out, stream));
          ATEX_RETURN_IF_ERROR(LinearForward(cublas, mlp + layer.weight, width, cols,
                                             hidden.data() + static_cast<size_t>(e) * width, heads * width, n, 1.0f,
                                             out, cols));
        } else {
          ATEX_CUDA_RETURN_IF_ERROR(
              cudaMemcpyAsync(out, in, sizeof(float) * rows * cols, cudaMemcpyDeviceToDevice, stream));
        }
      }
      if (enabled) ++e;
    }
  }
  cached = true;
  cached_n = n;
  cached_time = time;
  cached_grid = grid;
  cached_mlp = mlp;
  cached_positions = canonical.positions;
  cached_grid_size = layout.grid_size;
  cached_mlp_size = layout.mlp_size;
  return Status::Ok();
}

Status DeformEngine::Impl::Backward(const DeformLayout& layout, const float* grid, const float* mlp, int n,
                                    int sh_coeffs, float time, const GaussianTensors& canonical,
                                    const GaussianTensors& grad_deformed, float* grad_grid, float* grad_mlp,
                                    const GaussianTensors& grad_canonical) {
  ATEX_RETURN_IF_ERROR(CheckCommon("DeformEngine::Backward", layout, grid, mlp, n, sh_coeffs, time, canonical));
  if (!cached || cached_n != n || !(cached_time == time) || cached_grid != grid || cached_mlp != mlp ||
      cached_positions != canonical.positions || cached_grid_size != layout.grid_size ||
      cached_mlp_size != layout.mlp_size) {
    return MakeError(StatusCode::kInvalidArgument,
                     "DeformEngine::Backward: no matching Forward (same n, time, grid, mlp and canonical positions) "
                     "before it");
  }
  if (n == 0) return Status::Ok();
  const DeformationConfig& config = layout.config;
  const int width = config.mlp_width;
  const int feature_dim = config.grid.feature_dim();
  const int trunk_layers = config.trunk_layers;
  const int heads = EnabledHeadCount(config);
  const int packed = heads * width;
  const size_t rows = static_cast<size_t>(n);

  // deformed = canonical + residual: the canonical tensors receive dL/d(deformed) unchanged.
  for (int h = 0; h < kNumDeformHeads; ++h) {
    float* dst = HeadTensor(grad_canonical, h);
    const float* src = HeadTensor(grad_deformed, h);
    if (dst && src) {
      ATEX_RETURN_IF_ERROR(
          deform_detail::LaunchAccumulate(dst, src, static_cast<int64_t>(rows) * TensorWidth(h, sh_coeffs), stream));
    }
  }
  bool any_head_gradient = false;
  for (int h = 0; h < kNumDeformHeads; ++h) {
    any_head_gradient |= config.heads[h] && HeadTensor(grad_deformed, h) != nullptr;
  }
  const bool want_field_path = grad_grid != nullptr || grad_mlp != nullptr || grad_canonical.positions != nullptr;
  if (!any_head_gradient || !want_field_path) return Status::Ok();

  ATEX_RETURN_IF_ERROR(d_hidden.Resize(rows * packed));
  ATEX_RETURN_IF_ERROR(d_act.Resize(rows * width));
  ATEX_RETURN_IF_ERROR(d_act_next.Resize(rows * width));
  ATEX_RETURN_IF_ERROR(d_features.Resize(rows * feature_dim));
  ATEX_RETURN_IF_ERROR(d_packed_weight.Resize(static_cast<size_t>(packed) * width));
  ATEX_RETURN_IF_ERROR(d_packed_bias.Resize(static_cast<size_t>(packed)));
  ATEX_RETURN_IF_ERROR(d_packed_bias.Zero(stream));

  deform_detail::ScopedCublasSettings settings(cublas, stream, allow_tf32);
  ATEX_RETURN_IF_ERROR(settings.status());

  // Heads: output layer, then the hidden layer's pre-activation gradient into d_hidden.
  int e = 0;
  for (int h = 0; h < kNumDeformHeads; ++h) {
    if (!config.heads[h]) continue;
    const float* g = HeadTensor(grad_deformed, h);  // [N][out]
    const int out = config.head_outputs(h);
    const DeformLayout::Layer& layer = layout.head_output[h];
    const float* hidden_h = hidden.data() + static_cast<size_t>(e) * width;  // row stride `packed`
    float* d_hidden_h = d_hidden.data() + static_cast<size_t>(e) * width;
    if (g == nullptr) {
      ATEX_CUDA_RETURN_IF_ERROR(cudaMemset2DAsync(d_hidden_h, sizeof(float) * packed, 0, sizeof(float) * width, rows,
                                                  stream));
    } else {
      if (grad_mlp) {
        ATEX_RETURN_IF_ERROR(LinearBackwardWeight(cublas, hidden_h, packed, g, out, width, out, n, 1.0f,
                                                  grad_mlp + layer.weight));
        ATEX_RETURN_IF_ERROR(deform_detail::LaunchColumnSumAdd(g, n, out, out, grad_mlp + layer.bias, stream));
      }
      ATEX_RETURN_IF_ERROR(deform_detail::LaunchNarrowLinearBackward(
          g, out, mlp + layer.weight, hidden_h, n, width, packed, d_hidden_h,
          grad_mlp ? d_packed_bias.data() + static_cast<size_t>(e) * width : nullptr, stream));
    }
    ++e;
  }
  const float* head_input = trunk_act.data() + (trunk_layers - 1) * rows * width;
  if (grad_mlp) {
    ATEX_RETURN_IF_ERROR(LinearBackwardWeight(cublas, head_input, width, d_hidden.data(), packed, width, packed, n,
                                              0.0f, d_packed_weight.data()));
    e = 0;
    for (int h = 0; h < kNumDeformHeads; ++h) {
      if (!config.heads[h]) continue;
      const DeformLayout::Layer& layer = layout.head_hidden[h];
      ATEX_RETURN_IF_ERROR(deform_detail::LaunchAccumulate(
          grad_mlp + layer.weight, d_packed_weight.data() + static_cast<size_t>(e) * width * width,
          static_cast<int64_t>(width) * width, stream));
      ATEX_RETURN_IF_ERROR(deform_detail::LaunchAccumulate(
          grad_mlp + layer.bias, d_packed_bias.data() + static_cast<size_t>(e) * width, width, stream));
      ++e;
    }
  }
  // dL/d(ReLU(trunk output)) = d_hidden * packed hidden weights.
  ATEX_RETURN_IF_ERROR(LinearBackwardData(cublas, packed_weight.data(), width, packed, d_hidden.data(), packed, n,
                                          0.0f, d_act.data(), width));

  // Trunk in reverse; d_act holds dL/d(act_l) on entry of each iteration.
  for (int l = trunk_layers - 1; l >= 0; --l) {
    const DeformLayout::Layer& layer = layout.trunk[l];
    const float* act = trunk_act.data() + l * rows * width;
    ATEX_RETURN_IF_ERROR(deform_detail::LaunchReluBackward(d_act.data(), act, n, width, width,
                                                           grad_mlp ? grad_mlp + layer.bias : nullptr, stream));
    const float* input = l == 0 ? features.data() : trunk_act.data() + (l - 1) * rows * width;
    if (grad_mlp) {
      ATEX_RETURN_IF_ERROR(LinearBackwardWeight(cublas, input, layer.in, d_act.data(), width, layer.in, width, n,
                                                1.0f, grad_mlp + layer.weight));
    }
    if (l > 0) {
      ATEX_RETURN_IF_ERROR(LinearBackwardData(cublas, mlp + layer.weight, layer.in, width, d_act.data(), width, n,
                                              0.0f, d_act_next.data(), width));
      std::swap(d_act, d_act_next);
    } else if (grad_grid || grad_canonical.positions) {
      ATEX_RETURN_IF_ERROR(LinearBackwardData(cublas, mlp + layer.weight, layer.in, width, d_act.data(), width, n,
                                              0.0f, d_features.data(), feature_dim));
    }
  }
  if (grad_grid || grad_canonical.positions) {
    const deform_detail::GridGeometry geometry = deform_detail::MakeGridGeometry(layout, time);
    ATEX_RETURN_IF_ERROR(deform_detail::LaunchSampleFeaturesBackward(
        geometry, grid, canonical.positions, n, d_features.data(), grad_grid, grad_canonical.positions, stream));
  }
  return Status::Ok();
}

DeformEngine::DeformEngine(cublasHandle_t cublas, cudaStream_t stream) : impl_(std::make_unique<Impl>()) {
  impl_->cublas = cublas;
  impl_->stream = stream;
}

DeformEngine::~DeformEngine() = default;

void DeformEngine::set_allow_tf32(bool allow) { impl_->allow_tf32 = allow; }

void DeformEngine::set_fuse_bias_relu(bool fuse) { impl_->fuse_bias_relu = fuse; }

int DeformEngine::last_forward_fused_layers() const { return impl_->fused_layers; }
int DeformEngine::last_forward_unfused_layers() const { return impl_->unfused_layers; }

Status DeformEngine::Forward(const DeformLayout& layout, const float* grid, const float* mlp, int n, int sh_coeffs,
                             float time, const GaussianTensors& canonical, const GaussianTensors& deformed) {
  return impl_->Forward(layout, grid, mlp, n, sh_coeffs, time, canonical, deformed);
}

Status DeformEngine::Backward(const DeformLayout& layout, const float* grid, const float* mlp, int n, int sh_coeffs,
                              float time, const GaussianTensors& canonical, const GaussianTensors& grad_deformed,
                              float* grad_grid, float* grad_mlp, const GaussianTensors& grad_canonical) {
  return impl_->Backward(layout, grid, mlp, n, sh_coeffs, time, canonical, grad_deformed, grad_grid, grad_mlp,
                         grad_canonical);
}

Status DeformEngine::Regularizer(const DeformLayout& layout, const float* grid, float plane_tv, float time_smoothness,
                                 float time_l1, float* grad_grid, float* loss_device) {
  ATEX_RETURN_IF_ERROR(CheckDeformLayout(layout).WithContext("DeformEngine::Regularizer"));
  if (grid == nullptr) return MakeError(StatusCode::kInvalidArgument, "DeformEngine::Regularizer: null grid");
  if (!std::isfinite(plane_tv) || !std::isfinite(time_smoothness) || !std::isfinite(time_l1)) {
    return MakeError(StatusCode::kInvalidArgument, "DeformEngine::Regularizer: non-finite weight");
  }
  if (grad_grid == nullptr && loss_device == nullptr) return Status::Ok();
  double* accumulator = nullptr;
  if (loss_device) {
    ATEX_RETURN_IF_ERROR(impl_->accumulator.Resize(1));
    ATEX_RETURN_IF_ERROR(impl_->accumulator.Zero(impl_->stream));
    accumulator = impl_->accumulator.data();
  }
  ATEX_RETURN_IF_ERROR(deform_detail::LaunchPlaneRegularizer(layout, grid, plane_tv, time_smoothness, time_l1,
                                                             grad_grid, accumulator, impl_->stream));
  if (loss_device) ATEX_RETURN_IF_ERROR(deform_detail::LaunchAddScalar(accumulator, loss_device, impl_->stream));
  return Status::Ok();
}

size_t DeformEngine::workspace_bytes() const {
  const Impl& i = *impl_;
  return i.features.bytes() + i.trunk_act.bytes() + i.hidden.bytes() + i.packed_weight.bytes() +
         i.packed_bias.bytes() + i.trunk_bias.bytes() + i.d_hidden.bytes() + i.d_act.bytes() + i.d_act_next.bytes() +
         i.d_features.bytes() + i.d_packed_weight.bytes() + i.d_packed_bias.bytes() + i.accumulator.bytes() +
         i.fused_linear_relu.workspace_bytes();
}

}  // namespace atex::cuda
