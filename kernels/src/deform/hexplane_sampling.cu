// HexPlane sampling on the GPU, forward and backward.
//
// Thread mapping: one thread per (Gaussian, scale, chunk of V channels), V = 4 when
// the channel count and the buffers allow 16-byte accesses, else 1. The threads of one
// Gaussian are consecutive, so feature rows are written and read fully coalesced and the
// channel-last planes give each thread V contiguous channels per corner. The per-axis
// tap (knots, weights, clamping) is atex/detail/hexplane.h's, and the normalisation is
// evaluated without fused multiply-adds so that the knots are bit-identical to the CPU
// engine's.
//
// Backward: plane gradients by atomics (float4 atomics on sm_90); the coordinate
// gradient of a Gaussian is reduced over its threads by warp shuffles when their
// number is a power of two up to 32 (then one thread adds it, no atomics), else by
// atomics.
#include <cstdint>

#include "atex/detail/hexplane.h"
#include "cuda_check.h"
#include "deform/deform_internal.h"

namespace atex::cuda::deform_detail {
namespace {

constexpr int kThreads = 256;

template <int V>
struct Chunk {
  float v[V];
};

template <int V>
__device__ __forceinline__ Chunk<V> Fill(float value) {
  Chunk<V> c;
#pragma unroll
  for (int i = 0; i < V; ++i) c.v[i] = value;
  return c;
}

template <int V>
__device__ __forceinline__ Chunk<V> Load(const float* p) {
  Chunk<V> c;
  if constexpr (V == 4) {
    const float4 f = __ldg(reinterpret_cast<const float4*>(p));
    c.v[0] = f.x;
    c.v[1] = f.y;
    c.v[2] = f.z;
    c.v[3] = f.w;
  } else {
#pragma unroll
    for (int i = 0; i < V; ++i) c.v[i] = __ldg(p + i);
  }
  return c;
}

template <int V>
__device__ __forceinline__ void Store(float* p, const Chunk<V>& c) {
  if constexpr (V == 4) {
    *reinterpret_cast<float4*>(p) = make_float4(c.v[0], c.v[1], c.v[2], c.v[3]);
  } else {
#pragma unroll
    for (int i = 0; i < V; ++i) p[i] = c.v[i];
  }
}

// p[i] += scale * c[i] atomically, in the order the CPU writes the product (weight * grad).
template <int V>
__device__ __forceinline__ void AtomicAddScaled(float* p, float weight, const Chunk<V>& c) {
#if defined(__CUDA_ARCH__) && __CUDA_ARCH__ >= 900
  constexpr bool kVectorAtomics = V == 4;  // 16-byte atomicAdd exists on sm_90 and newer
#else
  constexpr bool kVectorAtomics = false;
#endif
  if constexpr (kVectorAtomics) {
    atomicAdd(reinterpret_cast<float4*>(p),
              make_float4(weight * c.v[0], weight * c.v[1], weight * c.v[2], weight * c.v[3]));
  } else {
#pragma unroll
    for (int i = 0; i < V; ++i) atomicAdd(p + i, weight * c.v[i]);
  }
}

// (x - lo) * scale - 1 in exactly that order, rounded after every operation (no FMA
// contraction), as atex::detail::NormalizeCoordinate evaluates it on the host.
__device__ __forceinline__ float NormalizeExact(float x, float lo, float scale) {
  return __fsub_rn(__fmul_rn(__fsub_rn(x, lo), scale), 1.0f);
}

struct ThreadSlot {
  int gaussian;
  int scale;
  int chunk;  // within the scale
};

__device__ __forceinline__ ThreadSlot Decompose(long long t, int chunks, int group) {
  ThreadSlot slot;
  slot.gaussian = static_cast<int>(t / group);
  const int r = static_cast<int>(t - static_cast<long long>(slot.gaussian) * group);
  slot.scale = r / chunks;
  slot.chunk = r - slot.scale * chunks;
  return slot;
}

__device__ __forceinline__ void NormalisedCoordinate(const GridGeometry& g, const float* positions, int gaussian,
                                                     float* coord) {
#pragma unroll
  for (int a = 0; a < 3; ++a) {
    coord[a] = NormalizeExact(__ldg(positions + 3 * static_cast<long long>(gaussian) + a), g.aabb_lo[a],
                              g.aabb_scale[a]);
  }
  coord[3] = g.time_norm;
}

// Bilinear sample of V channels: sum_k weight(k) * corner_k, in the CPU's order.
template <int V>
__device__ __forceinline__ Chunk<V> SampleChunk(const float* plane, int channels,
                                                const detail::PlaneTap<float>& tap) {
  Chunk<V> sample = Fill<V>(0.0f);
#pragma unroll
  for (int k = 0; k < 4; ++k) {
    const float w = tap.weight(k);
    const Chunk<V> corner = Load<V>(plane + static_cast<long long>(tap.corner(k)) * channels);
#pragma unroll
    for (int i = 0; i < V; ++i) sample.v[i] += w * corner.v[i];
  }
  return sample;
}

template <int V>
__global__ void __launch_bounds__(kThreads) SampleFeaturesKernel(GridGeometry g, const float* __restrict__ grid,
                                                                 const float* __restrict__ positions, int n,
                                                                 float* __restrict__ features) {
  const int chunks = g.channels / V;
  const int group = g.scales * chunks;
  const long long t = static_cast<long long>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (t >= static_cast<long long>(n) * group) return;
  const ThreadSlot slot = Decompose(t, chunks, group);
  float coord[4];
  NormalisedCoordinate(g, positions, slot.gaussian, coord);
  const int* res = g.resolution[slot.scale];
  Chunk<V> feature = Fill<V>(1.0f);
#pragma unroll
  for (int p = 0; p < detail::kHexPlanes; ++p) {
    const int a = detail::HexPlaneAxis(p, 0);
    const int b = detail::HexPlaneAxis(p, 1);
    const detail::PlaneTap<float> tap = detail::MakePlaneTap(coord[a], coord[b], res[a], res[b]);
    const float* plane = grid + g.plane_offset[slot.scale][p] + slot.chunk * V;
    const Chunk<V> sample = SampleChunk<V>(plane, g.channels, tap);
#pragma unroll
    for (int i = 0; i < V; ++i) feature.v[i] *= sample.v[i];
  }
  Store<V>(features + t * V, feature);
}

// kShuffle: the group size is a power of two <= 32, so a Gaussian's threads form an
// aligned segment of one warp.
template <int V, bool kShuffle>
__global__ void __launch_bounds__(kThreads, 2)
    SampleFeaturesBackwardKernel(GridGeometry g, const float* __restrict__ grid, const float* __restrict__ positions,
                                 int n, const float* __restrict__ grad_features, float* grad_grid,
                                 float* grad_positions) {
  const int chunks = g.channels / V;
  const int group = g.scales * chunks;
  const long long total = static_cast<long long>(n) * group;
  const long long t_raw = static_cast<long long>(blockIdx.x) * blockDim.x + threadIdx.x;
  // Every lane of a warp must reach the shuffles: out-of-range lanes compute on the last
  // valid slot and contribute nothing.
  const bool valid = t_raw < total;
  if (!kShuffle && !valid) return;
  const long long t = valid ? t_raw : total - 1;
  const ThreadSlot slot = Decompose(t, chunks, group);
  float coord[4];
  NormalisedCoordinate(g, positions, slot.gaussian, coord);
  const int* res = g.resolution[slot.scale];
  const float* scale_grid = grid + slot.chunk * V;
  // Product rule without division (samples may be zero): grad_sample[p] = grad_feature *
  // prefix[p] * suffix[p]. Suffix products first (the samples are not needed after that),
  // then one forward sweep with a running prefix; taps are recomputed (a few flops) rather
  // than kept, to stay within 128 registers.
  Chunk<V> suffix[detail::kHexPlanes];
  {
    Chunk<V> samples[detail::kHexPlanes];
#pragma unroll
    for (int p = 0; p < detail::kHexPlanes; ++p) {
      const int a = detail::HexPlaneAxis(p, 0);
      const int b = detail::HexPlaneAxis(p, 1);
      const detail::PlaneTap<float> tap = detail::MakePlaneTap(coord[a], coord[b], res[a], res[b]);
      samples[p] = SampleChunk<V>(scale_grid + g.plane_offset[slot.scale][p], g.channels, tap);
    }
    suffix[detail::kHexPlanes - 1] = Fill<V>(1.0f);
#pragma unroll
    for (int p = detail::kHexPlanes - 2; p >= 0; --p) {
#pragma unroll
      for (int i = 0; i < V; ++i) suffix[p].v[i] = suffix[p + 1].v[i] * samples[p + 1].v[i];
    }
  }
  const Chunk<V> grad_feature = valid ? Load<V>(grad_features + t * V) : Fill<V>(0.0f);
  float grad_coord[4] = {0.0f, 0.0f, 0.0f, 0.0f};
  Chunk<V> prefix = Fill<V>(1.0f);
  const long long stride = g.channels;
#pragma unroll
  for (int p = 0; p < detail::kHexPlanes; ++p) {
    const int a = detail::HexPlaneAxis(p, 0);
    const int b = detail::HexPlaneAxis(p, 1);
    const detail::PlaneTap<float> tap = detail::MakePlaneTap(coord[a], coord[b], res[a], res[b]);
    const float* plane = scale_grid + g.plane_offset[slot.scale][p];
    const Chunk<V> v00 = Load<V>(plane + tap.corner(0) * stride);
    const Chunk<V> v10 = Load<V>(plane + tap.corner(1) * stride);
    const Chunk<V> v01 = Load<V>(plane + tap.corner(2) * stride);
    const Chunk<V> v11 = Load<V>(plane + tap.corner(3) * stride);
    Chunk<V> grad_sample;
#pragma unroll
    for (int i = 0; i < V; ++i) grad_sample.v[i] = grad_feature.v[i] * prefix.v[i] * suffix[p].v[i];
    // The sample itself (same arithmetic as SampleChunk) continues the prefix product.
    const float w0 = tap.weight(0), w1 = tap.weight(1), w2 = tap.weight(2), w3 = tap.weight(3);
#pragma unroll
    for (int i = 0; i < V; ++i) {
      float sample = 0.0f;
      sample += w0 * v00.v[i];
      sample += w1 * v10.v[i];
      sample += w2 * v01.v[i];
      sample += w3 * v11.v[i];
      prefix.v[i] *= sample;
    }
    // d(sample)/d(continuous index) of the bilinear form, per channel.
    const float wa = tap.a.w1;
    const float wb = tap.b.w1;
    float ga = 0.0f, gb = 0.0f;
#pragma unroll
    for (int i = 0; i < V; ++i) {
      const float dga = (1.0f - wb) * (v10.v[i] - v00.v[i]) + wb * (v11.v[i] - v01.v[i]);
      const float dgb = (1.0f - wa) * (v01.v[i] - v00.v[i]) + wa * (v11.v[i] - v10.v[i]);
      ga += grad_sample.v[i] * dga * tap.a.dg_dc;
      gb += grad_sample.v[i] * dgb * tap.b.dg_dc;
    }
    grad_coord[a] += ga;
    grad_coord[b] += gb;
    if (grad_grid != nullptr && valid) {
      float* plane_grad = grad_grid + g.plane_offset[slot.scale][p] + slot.chunk * V;
      if (w0 != 0.0f) AtomicAddScaled<V>(plane_grad + tap.corner(0) * stride, w0, grad_sample);
      if (w1 != 0.0f) AtomicAddScaled<V>(plane_grad + tap.corner(1) * stride, w1, grad_sample);
      if (w2 != 0.0f) AtomicAddScaled<V>(plane_grad + tap.corner(2) * stride, w2, grad_sample);
      if (w3 != 0.0f) AtomicAddScaled<V>(plane_grad + tap.corner(3) * stride, w3, grad_sample);
    }
  }
  if (!grad_positions) return;  // uniform across the launch: no lane is left waiting in a shuffle
  float grad_position[3];
#pragma unroll
  for (int a = 0; a < 3; ++a) grad_position[a] = valid ? grad_coord[a] * g.aabb_scale[a] : 0.0f;
  float* out = grad_positions + 3 * static_cast<long long>(slot.gaussian);
  if constexpr (kShuffle) {
    for (int offset = group / 2; offset > 0; offset /= 2) {
#pragma unroll
      for (int a = 0; a < 3; ++a) grad_position[a] += __shfl_xor_sync(0xffffffffu, grad_position[a], offset);
    }
    if (valid && slot.scale == 0 && slot.chunk == 0) {
#pragma unroll
      for (int a = 0; a < 3; ++a) out[a] += grad_position[a];
    }
  } else {
#pragma unroll
    for (int a = 0; a < 3; ++a) atomicAdd(out + a, grad_position[a]);
  }
}

bool Aligned16(const void* p) { return reinterpret_cast<uintptr_t>(p) % 16 == 0; }

long long Blocks(long long threads) { return (threads + kThreads - 1) / kThreads; }

}  // namespace

GridGeometry MakeGridGeometry(const DeformLayout& layout, float time) {
  const DeformationConfig& config = layout.config;
  GridGeometry g;
  g.scales = config.grid.scales();
  g.channels = config.grid.channels;
  for (int s = 0; s < g.scales && s < kMaxScales; ++s) {
    for (int axis = 0; axis < 4; ++axis) g.resolution[s][axis] = config.grid.resolution(s, axis);
    for (int p = 0; p < 6; ++p) {
      g.plane_offset[s][p] = static_cast<long long>(layout.plane_offset[static_cast<size_t>(s) * 6 + p]);
    }
  }
  for (int a = 0; a < 3; ++a) {
    g.aabb_lo[a] = config.aabb_lo[a];
    g.aabb_scale[a] = detail::AabbScale(config.aabb_lo[a], config.aabb_hi[a]);
  }
  g.time_norm = NormalizedTime(config, time);
  return g;
}

Status LaunchSampleFeatures(const GridGeometry& geometry, const float* grid, const float* positions, int n,
                            float* features, cudaStream_t stream) {
  if (n <= 0) return Status::Ok();
  const bool vec4 = geometry.channels % 4 == 0 && Aligned16(grid) && Aligned16(features);
  const long long threads =
      static_cast<long long>(n) * geometry.scales * (vec4 ? geometry.channels / 4 : geometry.channels);
  const long long blocks = Blocks(threads);
  if (blocks > 0x7fffffffLL) return MakeError(StatusCode::kLimitExceeded, "CUDA deformation: too many Gaussians");
  if (vec4) {
    SampleFeaturesKernel<4><<<static_cast<unsigned>(blocks), kThreads, 0, stream>>>(geometry, grid, positions, n,
                                                                                     features);
  } else {
    SampleFeaturesKernel<1><<<static_cast<unsigned>(blocks), kThreads, 0, stream>>>(geometry, grid, positions, n,
                                                                                     features);
  }
  ATEX_CUDA_CHECK_LAUNCH("SampleFeaturesKernel");
  return Status::Ok();
}

Status LaunchSampleFeaturesBackward(const GridGeometry& geometry, const float* grid, const float* positions, int n,
                                    const float* grad_features, float* grad_grid, float* grad_positions,
                                    cudaStream_t stream) {
  if (n <= 0 || (!grad_grid && !grad_positions)) return Status::Ok();
  const bool vec4 = geometry.channels % 4 == 0 && Aligned16(grid) && Aligned16(grad_features) &&
                    (grad_grid == nullptr || Aligned16(grad_grid));
  const int group = geometry.scales * (vec4 ? geometry.channels / 4 : geometry.channels);
  const bool shuffle = group <= 32 && (group & (group - 1)) == 0;
  const long long blocks = Blocks(static_cast<long long>(n) * group);
  if (blocks > 0x7fffffffLL) return MakeError(StatusCode::kLimitExceeded, "CUDA deformation: too many Gaussians");
  const unsigned grid_blocks = static_cast<unsigned>(blocks);
  if (vec4 && shuffle) {
    SampleFeaturesBackwardKernel<4, true><<<grid_blocks, kThreads, 0, stream>>>(geometry, grid, positions, n,
                                                                                grad_features, grad_grid,
                                                                                grad_positions);
  } else if (vec4) {
    SampleFeaturesBackwardKernel<4, false><<<grid_blocks, kThreads, 0, stream>>>(geometry, grid, positions, n,
                                                                                 grad_features, grad_grid,
                                                                                 grad_positions);
  } else if (shuffle) {
    SampleFeaturesBackwardKernel<1, true><<<grid_blocks, kThreads, 0, stream>>>(geometry, grid, positions, n,
                                                                                grad_features, grad_grid,
                                                                                grad_positions);
  } else {
    SampleFeaturesBackwardKernel<1, false><<<grid_blocks, kThreads, 0, stream>>>(geometry, grid, positions, n,
                                                                                 grad_features, grad_grid,
                                                                                 grad_positions);
  }
  ATEX_CUDA_CHECK_LAUNCH("SampleFeaturesBackwardKernel");
  return Status::Ok();
}

}  // namespace atex::cuda::deform_detail
