// RenderEngine: sequences the stages and owns their workspace (grown on demand).
#include <cub/device/device_radix_sort.cuh>
#include <cub/device/device_scan.cuh>

#include "cuda_check.h"
#include "device_buffer.h"
#include "render/render_kernels.h"

namespace atex::cuda {

using render::Projected;

namespace {

// total += sum of counts[0, n) in 64 bits (the tile lists' 32-bit prefix sum wraps silently
// past 2^32 entries: 8 M screen-sized Gaussians at 1352x1014 make 43 billion).
__global__ void SumTilesTouched(const uint32_t* __restrict__ counts,  // [n]
                                int n, unsigned long long* __restrict__ total) {
  unsigned long long sum = 0;
  for (int i = blockIdx.x * blockDim.x + threadIdx.x; i < n; i += gridDim.x * blockDim.x) sum += counts[i];
  for (int offset = 16; offset > 0; offset /= 2) sum += __shfl_down_sync(0xffffffffu, sum, offset);
  if ((threadIdx.x & 31) == 0 && sum > 0) atomicAdd(total, sum);
}

// Bytes of tile-list workspace per (tile, Gaussian) entry: keys and sorted keys (8 + 8), ids
// and sorted ids (4 + 4).
constexpr uint64_t kBytesPerEntry = 24;

}  // namespace

struct RenderEngine::Impl {
  cudaStream_t stream;
  // Per Gaussian.
  DeviceBuffer<int32_t> radius;
  DeviceBuffer<float> mean2d, depth, conic, opacity, color;
  DeviceBuffer<detail::TextureFrame<float>> frames;
  DeviceBuffer<int4> rects;
  DeviceBuffer<uint32_t> tiles_touched, tile_ends;
  DeviceBuffer<float> splat_grads;
  // Per (tile, Gaussian) entry.
  DeviceBuffer<uint64_t> keys, keys_sorted;
  DeviceBuffer<uint32_t> ids, ids_sorted;
  DeviceBuffer<uint8_t> cub_temp;
  DeviceBuffer<unsigned long long> entry_total;  // [1]: the 64-bit entry count
  // Per tile / pixel.
  DeviceBuffer<uint2> ranges;
  DeviceBuffer<float> final_transmittance;
  DeviceBuffer<uint32_t> contributor_end;
  uint32_t entries = 0;
  int last_count = 0;

  Projected View() {
    Projected p;
    p.radius = radius.data();
    p.mean2d = mean2d.data();
    p.depth = depth.data();
    p.conic = conic.data();
    p.opacity = opacity.data();
    p.color = color.data();
    p.frames = frames.data();
    p.rects = rects.data();
    p.tiles_touched = tiles_touched.data();
    return p;
  }

  Status Reserve(int n, bool textured) {
    const size_t count = static_cast<size_t>(n);
    ATEX_RETURN_IF_ERROR(radius.Resize(count));
    ATEX_RETURN_IF_ERROR(mean2d.Resize(count * 2));
    ATEX_RETURN_IF_ERROR(depth.Resize(count));
    ATEX_RETURN_IF_ERROR(conic.Resize(count * 3));
    ATEX_RETURN_IF_ERROR(opacity.Resize(count));
    ATEX_RETURN_IF_ERROR(color.Resize(count * 3));
    ATEX_RETURN_IF_ERROR(frames.Resize(textured ? count : 1));
    ATEX_RETURN_IF_ERROR(rects.Resize(count));
    ATEX_RETURN_IF_ERROR(tiles_touched.Resize(count));
    ATEX_RETURN_IF_ERROR(tile_ends.Resize(count));
    return Status::Ok();
  }
};

RenderEngine::RenderEngine(cudaStream_t stream) : impl_(std::make_unique<Impl>()) { impl_->stream = stream; }
RenderEngine::~RenderEngine() = default;

Status RenderEngine::Forward(const detail::CameraModel<float>& cam, const RenderInputs& in, float* color, float* alpha,
                             float* importance) {
  Impl& s = *impl_;
  cudaStream_t stream = s.stream;
  const int n = in.count;
  s.last_count = -1;  // set to n once the view is complete: a failed Forward leaves nothing to Backward
  ATEX_RETURN_IF_ERROR(s.Reserve(n, in.textured()));
  const Projected p = s.View();
  ATEX_RETURN_IF_ERROR(render::LaunchProject(cam, in, p, stream));

  // Inclusive prefix sum of the tile counts; its last value is the number of entries. The
  // lists index entries with 32 bits: more is a limit of this renderer, refused before the
  // sum wraps (the exact count, and the memory it would take, in the message).
  s.entries = 0;
  if (n > 0) {
    ATEX_RETURN_IF_ERROR(s.entry_total.Resize(1));
    ATEX_RETURN_IF_ERROR(s.entry_total.Zero(stream));
    SumTilesTouched<<<std::min(1024, (n + 255) / 256), 256, 0, stream>>>(s.tiles_touched.data(), n,
                                                                        s.entry_total.data());
    ATEX_CUDA_RETURN_IF_ERROR(cudaGetLastError());
    unsigned long long total = 0;
    ATEX_CUDA_RETURN_IF_ERROR(
        cudaMemcpyAsync(&total, s.entry_total.data(), sizeof(total), cudaMemcpyDeviceToHost, stream));
    ATEX_CUDA_RETURN_IF_ERROR(cudaStreamSynchronize(stream));
    if (total > kMaxTileEntries) {
      return MakeError(StatusCode::kLimitExceeded, "a ", cam.width, "x", cam.height, " view of ", n,
                       " Gaussians has ", total, " (tile, Gaussian) pairs, more than the renderer's limit of ",
                       kMaxTileEntries, "; ", double(total) * kBytesPerEntry / double(1ull << 30),
                       " GiB of tile lists asked; ", DeviceMemoryNote(),
                       ". Use fewer or smaller Gaussians, or a smaller image");
    }
    size_t temp_bytes = 0;
    ATEX_CUDA_RETURN_IF_ERROR(
        cub::DeviceScan::InclusiveSum(nullptr, temp_bytes, s.tiles_touched.data(), s.tile_ends.data(), n, stream));
    ATEX_RETURN_IF_ERROR(s.cub_temp.Resize(temp_bytes));
    ATEX_CUDA_RETURN_IF_ERROR(cub::DeviceScan::InclusiveSum(s.cub_temp.data(), temp_bytes, s.tiles_touched.data(),
                                                            s.tile_ends.data(), n, stream));
    ATEX_CUDA_RETURN_IF_ERROR(cudaMemcpyAsync(&s.entries, s.tile_ends.data() + n - 1, sizeof(uint32_t),
                                              cudaMemcpyDeviceToHost, stream));
    ATEX_CUDA_RETURN_IF_ERROR(cudaStreamSynchronize(stream));
  }
  const int tiles = cam.tiles_x * cam.tiles_y;
  ATEX_RETURN_IF_ERROR(s.ranges.Resize(static_cast<size_t>(tiles)));
  ATEX_RETURN_IF_ERROR(s.ranges.Zero(stream));
  if (s.entries > 0) {
    ATEX_RETURN_IF_ERROR(s.keys.Resize(s.entries));
    ATEX_RETURN_IF_ERROR(s.keys_sorted.Resize(s.entries));
    ATEX_RETURN_IF_ERROR(s.ids.Resize(s.entries));
    ATEX_RETURN_IF_ERROR(s.ids_sorted.Resize(s.entries));
    ATEX_RETURN_IF_ERROR(
        render::LaunchEmitKeys(in, p, s.tile_ends.data(), cam.tiles_x, s.keys.data(), s.ids.data(), stream));
    int tile_bits = 1;
    while ((1 << tile_bits) < tiles) ++tile_bits;
    size_t temp_bytes = 0;
    ATEX_CUDA_RETURN_IF_ERROR(cub::DeviceRadixSort::SortPairs(nullptr, temp_bytes, s.keys.data(),
                                                              s.keys_sorted.data(), s.ids.data(), s.ids_sorted.data(),
                                                              s.entries, 0, 32 + tile_bits, stream));
    ATEX_RETURN_IF_ERROR(s.cub_temp.Resize(temp_bytes));
    ATEX_CUDA_RETURN_IF_ERROR(cub::DeviceRadixSort::SortPairs(s.cub_temp.data(), temp_bytes, s.keys.data(),
                                                              s.keys_sorted.data(), s.ids.data(), s.ids_sorted.data(),
                                                              s.entries, 0, 32 + tile_bits, stream));
    ATEX_RETURN_IF_ERROR(render::LaunchTileRanges(s.keys_sorted.data(), s.entries, s.ranges.data(), stream));
  }
  const size_t pixels = size_t(cam.width) * cam.height;
  ATEX_RETURN_IF_ERROR(s.final_transmittance.Resize(pixels));
  ATEX_RETURN_IF_ERROR(s.contributor_end.Resize(pixels));
  ATEX_RETURN_IF_ERROR(render::LaunchRasterForward(cam, in, p, s.ranges.data(), s.ids_sorted.data(), color, alpha,
                                                   s.final_transmittance.data(), s.contributor_end.data(), importance,
                                                   stream));
  s.last_count = n;
  return Status::Ok();
}

Status RenderEngine::Backward(const detail::CameraModel<float>& cam, const RenderInputs& in, const float* grad_color,
                              const float* grad_alpha, const RenderGradients& grads, const RenderStats* stats) {
  Impl& s = *impl_;
  if (in.count != s.last_count) {
    return MakeError(StatusCode::kInternal, "RenderEngine::Backward for ", in.count, " Gaussians after a Forward of ",
                     s.last_count);
  }
  const size_t n = static_cast<size_t>(in.count);
  ATEX_RETURN_IF_ERROR(s.splat_grads.Resize(n * render::kSplatGradWidth));
  ATEX_RETURN_IF_ERROR(s.splat_grads.Zero(s.stream));
  const render::SplatGrads splat{s.splat_grads.data()};
  const Projected p = s.View();
  ATEX_RETURN_IF_ERROR(render::LaunchRasterBackward(cam, in, p, s.ranges.data(), s.ids_sorted.data(),
                                                    s.final_transmittance.data(), s.contributor_end.data(),
                                                    grad_color, grad_alpha, splat, grads.texels, s.stream));
  return render::LaunchProjectBackward(cam, in, p, splat, grads, stats, s.stream);
}

StatusOr<int> RenderEngine::VisibleCount() {
  // Visible Gaussians are those with at least one tile; count them from the tile counts.
  Impl& s = *impl_;
  if (s.last_count <= 0) return 0;  // none, or the last Forward failed
  std::vector<uint32_t> touched;
  ATEX_RETURN_IF_ERROR(s.tiles_touched.Download(&touched, s.stream));
  int visible = 0;
  for (uint32_t t : touched) visible += t > 0 ? 1 : 0;
  return visible;
}

size_t RenderEngine::workspace_bytes() const {
  const Impl& s = *impl_;
  return s.radius.bytes() + s.mean2d.bytes() + s.depth.bytes() + s.conic.bytes() + s.opacity.bytes() +
         s.color.bytes() + s.frames.bytes() + s.rects.bytes() + s.tiles_touched.bytes() + s.tile_ends.bytes() +
         s.splat_grads.bytes() + s.keys.bytes() + s.keys_sorted.bytes() + s.ids.bytes() + s.ids_sorted.bytes() +
         s.cub_temp.bytes() + s.ranges.bytes() + s.final_transmittance.bytes() + s.contributor_end.bytes();
}

}  // namespace atex::cuda
