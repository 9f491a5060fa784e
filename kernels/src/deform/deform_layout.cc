// DeformLayout: where every plane and linear layer lives in the flat device buffers,
// and the checks that a layout can be run by the kernels.
#include "deform/deform_internal.h"

#include <cmath>
#include <limits>

#include "atex/deform.h"

namespace atex::cuda {

DeformLayout DeformLayout::Make(const DeformationConfig& config) {
  DeformLayout layout;
  layout.config = config;
  const HexPlaneConfig& grid = config.grid;
  const int scales = grid.scales();
  // Negative sizes (an invalid config) are treated as 0 here; CheckDeformLayout rejects them.
  auto dim = [](long long v) { return v > 0 ? static_cast<size_t>(v) : size_t{0}; };
  layout.plane_offset.assign(static_cast<size_t>(scales > 0 ? scales : 0) * kNumHexPlanes, 0);
  size_t offset = 0;
  for (int s = 0; s < scales; ++s) {
    for (int p = 0; p < kNumHexPlanes; ++p) {
      layout.plane_offset[static_cast<size_t>(s) * kNumHexPlanes + p] = offset;
      offset += dim(grid.channels) * dim(grid.resolution(s, kHexPlaneAxes[p][1])) *
                dim(grid.resolution(s, kHexPlaneAxes[p][0]));
    }
  }
  layout.grid_size = offset;

  size_t mlp = 0;
  auto add_layer = [&](int in, int out) {
    Layer layer;
    layer.in = in;
    layer.out = out;
    layer.weight = mlp;
    mlp += dim(in) * dim(out);
    layer.bias = mlp;
    mlp += dim(out);
    return layer;
  };
  const int width = config.mlp_width;
  for (int l = 0; l < config.trunk_layers; ++l) {
    layout.trunk.push_back(add_layer(l == 0 ? grid.feature_dim() : width, width));
  }
  for (int h = 0; h < kNumDeformHeads; ++h) {
    if (!config.heads[h]) continue;
    layout.head_hidden[h] = add_layer(width, width);
    layout.head_output[h] = add_layer(width, config.head_outputs(h));
  }
  layout.mlp_size = mlp;
  return layout;
}

Status CheckDeformLayout(const DeformLayout& layout) {
  const DeformationConfig& config = layout.config;
  ATEX_RETURN_IF_ERROR(CheckDeformationConfig(config).WithContext("CUDA deformation layout"));
  const int scales = config.grid.scales();
  if (scales > deform_detail::kMaxScales) {
    return MakeError(StatusCode::kUnsupported, "CUDA deformation: ", scales, " grid scales (multires entries); the ",
                     "kernels support at most ", deform_detail::kMaxScales);
  }
  for (int h = 0; h < kNumDeformHeads; ++h) {
    if (config.heads[h] && config.head_outputs(h) > deform_detail::kMaxHeadOutputs) {
      return MakeError(StatusCode::kUnsupported, "CUDA deformation: head ", h, " has ", config.head_outputs(h),
                       " outputs; the kernels support at most ", deform_detail::kMaxHeadOutputs);
    }
  }
  // The layout must be the one Make builds for this config (callers may have edited it).
  const DeformLayout expected = DeformLayout::Make(config);
  bool same = expected.grid_size == layout.grid_size && expected.mlp_size == layout.mlp_size &&
              expected.plane_offset == layout.plane_offset && expected.trunk.size() == layout.trunk.size();
  auto same_layer = [](const DeformLayout::Layer& a, const DeformLayout::Layer& b) {
    return a.weight == b.weight && a.bias == b.bias && a.in == b.in && a.out == b.out;
  };
  for (size_t l = 0; same && l < layout.trunk.size(); ++l) same = same_layer(expected.trunk[l], layout.trunk[l]);
  for (int h = 0; same && h < kNumDeformHeads; ++h) {
    same = same_layer(expected.head_hidden[h], layout.head_hidden[h]) &&
           same_layer(expected.head_output[h], layout.head_output[h]);
  }
  if (!same) {
    return MakeError(StatusCode::kInvalidArgument,
                     "CUDA deformation: the layout does not match DeformLayout::Make(config)");
  }
  // Kernels index with 32-bit ints inside a plane and for matrix dimensions.
  constexpr size_t kIntMax = static_cast<size_t>(std::numeric_limits<int>::max());
  for (int s = 0; s < scales; ++s) {
    for (int p = 0; p < kNumHexPlanes; ++p) {
      const size_t cells = static_cast<size_t>(config.grid.resolution(s, kHexPlaneAxes[p][0])) *
                           static_cast<size_t>(config.grid.resolution(s, kHexPlaneAxes[p][1]));
      if (cells * static_cast<size_t>(config.grid.channels) > kIntMax) {
        return MakeError(StatusCode::kLimitExceeded, "CUDA deformation: plane (scale ", s, ", plane ", p,
                         ") has more than 2^31 values");
      }
    }
  }
  for (int a = 0; a < 3; ++a) {
    const float scale = detail::AabbScale(config.aabb_lo[a], config.aabb_hi[a]);
    if (!std::isfinite(scale) || !std::isfinite(config.aabb_lo[a])) {
      return MakeError(StatusCode::kInvalidArgument, "CUDA deformation: degenerate AABB on axis ", a);
    }
  }
  if (!std::isfinite(config.time_scale) || !std::isfinite(config.time_offset)) {
    return MakeError(StatusCode::kInvalidArgument, "CUDA deformation: non-finite time mapping");
  }
  return Status::Ok();
}

namespace deform_detail {
float NormalizedTime(const DeformationConfig& config, float time) {
  // In double, rounded once: atex::deform_internal::CoordinateMap's formula, so that the
  // time knots agree bit for bit with the CPU engine.
  return static_cast<float>(static_cast<double>(config.time_scale) * static_cast<double>(time) +
                            static_cast<double>(config.time_offset));
}
}  // namespace deform_detail

int EnabledHeadCount(const DeformationConfig& config) {
  int count = 0;
  for (int h = 0; h < kNumDeformHeads; ++h) count += config.heads[h] ? 1 : 0;
  return count;
}

}  // namespace atex::cuda
