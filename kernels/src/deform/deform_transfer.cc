// Host <-> device copies of a DeformationField in the engine's layout: planes are
// transposed between the asset's [C][res_b][res_a] and the device's channel-last
// [res_b][res_a][C]; linear layers are copied as they are (weight [out][in], bias [out]).
#include <cstring>
#include <vector>

#include "cuda_check.h"
#include "deform/deform_internal.h"

namespace atex::cuda {
namespace {

Status CheckLinear(const Linear& linear, const DeformLayout::Layer& layer, const char* what, int index) {
  if (linear.in != layer.in || linear.out != layer.out ||
      linear.weight.size() != static_cast<size_t>(layer.in) * static_cast<size_t>(layer.out) ||
      linear.bias.size() != static_cast<size_t>(layer.out)) {
    return MakeError(StatusCode::kInvalidArgument, "UploadDeformation: ", what, " ", index, " is ", linear.in, "->",
                     linear.out, " with ", linear.weight.size(), " weights and ", linear.bias.size(),
                     " biases; the config needs ", layer.in, "->", layer.out);
  }
  return Status::Ok();
}

void CopyLinearIn(const Linear& linear, const DeformLayout::Layer& layer, std::vector<float>* mlp) {
  std::memcpy(mlp->data() + layer.weight, linear.weight.data(), linear.weight.size() * sizeof(float));
  std::memcpy(mlp->data() + layer.bias, linear.bias.data(), linear.bias.size() * sizeof(float));
}

Linear CopyLinearOut(const std::vector<float>& mlp, const DeformLayout::Layer& layer) {
  Linear linear;
  linear.in = layer.in;
  linear.out = layer.out;
  const size_t weights = static_cast<size_t>(layer.in) * static_cast<size_t>(layer.out);
  linear.weight.assign(mlp.begin() + layer.weight, mlp.begin() + layer.weight + weights);
  linear.bias.assign(mlp.begin() + layer.bias, mlp.begin() + layer.bias + layer.out);
  return linear;
}

}  // namespace

Status UploadDeformation(const DeformationField& field, const DeformLayout& layout, float* grid, float* mlp,
                         cudaStream_t stream) {
  ATEX_RETURN_IF_ERROR(CheckDeformLayout(layout));
  if ((grid == nullptr && layout.grid_size > 0) || (mlp == nullptr && layout.mlp_size > 0)) {
    return MakeError(StatusCode::kInvalidArgument, "UploadDeformation: null device buffer");
  }
  const DeformationConfig& config = layout.config;
  const HexPlaneConfig& grid_config = config.grid;
  const int scales = grid_config.scales();
  const int channels = grid_config.channels;
  if (field.planes.size() != static_cast<size_t>(scales)) {
    return MakeError(StatusCode::kInvalidArgument, "UploadDeformation: field has ", field.planes.size(),
                     " scales, the layout ", scales);
  }
  std::vector<float> host_grid(layout.grid_size);
  for (int s = 0; s < scales; ++s) {
    for (int p = 0; p < kNumHexPlanes; ++p) {
      const int res_a = grid_config.resolution(s, kHexPlaneAxes[p][0]);
      const int res_b = grid_config.resolution(s, kHexPlaneAxes[p][1]);
      const size_t cells = static_cast<size_t>(res_a) * static_cast<size_t>(res_b);
      const std::vector<float>& plane = field.planes[s][p];  // [C][res_b][res_a]
      if (plane.size() != cells * static_cast<size_t>(channels)) {
        return MakeError(StatusCode::kInvalidArgument, "UploadDeformation: plane (scale ", s, ", plane ", p,
                         ") has ", plane.size(), " values, the config needs ", cells * channels);
      }
      float* out = host_grid.data() + layout.plane_offset[static_cast<size_t>(s) * kNumHexPlanes + p];
      for (int c = 0; c < channels; ++c) {
        const float* in = plane.data() + static_cast<size_t>(c) * cells;
        for (size_t cell = 0; cell < cells; ++cell) out[cell * channels + c] = in[cell];
      }
    }
  }
  if (field.trunk.size() != layout.trunk.size()) {
    return MakeError(StatusCode::kInvalidArgument, "UploadDeformation: field has ", field.trunk.size(),
                     " trunk layers, the config ", layout.trunk.size());
  }
  std::vector<float> host_mlp(layout.mlp_size);
  for (size_t l = 0; l < layout.trunk.size(); ++l) {
    ATEX_RETURN_IF_ERROR(CheckLinear(field.trunk[l], layout.trunk[l], "trunk layer", static_cast<int>(l)));
    CopyLinearIn(field.trunk[l], layout.trunk[l], &host_mlp);
  }
  for (int h = 0; h < kNumDeformHeads; ++h) {
    if (!config.heads[h]) continue;
    ATEX_RETURN_IF_ERROR(CheckLinear(field.heads[h][0], layout.head_hidden[h], "hidden layer of head", h));
    ATEX_RETURN_IF_ERROR(CheckLinear(field.heads[h][1], layout.head_output[h], "output layer of head", h));
    CopyLinearIn(field.heads[h][0], layout.head_hidden[h], &host_mlp);
    CopyLinearIn(field.heads[h][1], layout.head_output[h], &host_mlp);
  }
  if (!host_grid.empty()) {
    ATEX_CUDA_RETURN_IF_ERROR(
        cudaMemcpyAsync(grid, host_grid.data(), host_grid.size() * sizeof(float), cudaMemcpyHostToDevice, stream));
  }
  if (!host_mlp.empty()) {
    ATEX_CUDA_RETURN_IF_ERROR(
        cudaMemcpyAsync(mlp, host_mlp.data(), host_mlp.size() * sizeof(float), cudaMemcpyHostToDevice, stream));
  }
  // The staging vectors die here: wait for the copies.
  ATEX_CUDA_RETURN_IF_ERROR(cudaStreamSynchronize(stream));
  return Status::Ok();
}

Status DownloadDeformation(const float* grid, const float* mlp, const DeformLayout& layout, DeformationField* field,
                           cudaStream_t stream) {
  if (field == nullptr) return MakeError(StatusCode::kInvalidArgument, "DownloadDeformation: null field");
  ATEX_RETURN_IF_ERROR(CheckDeformLayout(layout));
  if ((grid == nullptr && layout.grid_size > 0) || (mlp == nullptr && layout.mlp_size > 0)) {
    return MakeError(StatusCode::kInvalidArgument, "DownloadDeformation: null device buffer");
  }
  std::vector<float> host_grid(layout.grid_size);
  std::vector<float> host_mlp(layout.mlp_size);
  if (!host_grid.empty()) {
    ATEX_CUDA_RETURN_IF_ERROR(
        cudaMemcpyAsync(host_grid.data(), grid, host_grid.size() * sizeof(float), cudaMemcpyDeviceToHost, stream));
  }
  if (!host_mlp.empty()) {
    ATEX_CUDA_RETURN_IF_ERROR(
        cudaMemcpyAsync(host_mlp.data(), mlp, host_mlp.size() * sizeof(float), cudaMemcpyDeviceToHost, stream));
  }
  ATEX_CUDA_RETURN_IF_ERROR(cudaStreamSynchronize(stream));

  const DeformationConfig& config = layout.config;
  const HexPlaneConfig& grid_config = config.grid;
  const int channels = grid_config.channels;
  DeformationField out;
  out.config = config;
  out.planes.resize(static_cast<size_t>(grid_config.scales()));
  for (int s = 0; s < grid_config.scales(); ++s) {
    for (int p = 0; p < kNumHexPlanes; ++p) {
      const size_t cells = static_cast<size_t>(grid_config.resolution(s, kHexPlaneAxes[p][0])) *
                           static_cast<size_t>(grid_config.resolution(s, kHexPlaneAxes[p][1]));
      std::vector<float>& plane = out.planes[s][p];
      plane.resize(cells * static_cast<size_t>(channels));
      const float* in = host_grid.data() + layout.plane_offset[static_cast<size_t>(s) * kNumHexPlanes + p];
      for (int c = 0; c < channels; ++c) {
        float* channel = plane.data() + static_cast<size_t>(c) * cells;
        for (size_t cell = 0; cell < cells; ++cell) channel[cell] = in[cell * channels + c];
      }
    }
  }
  for (const DeformLayout::Layer& layer : layout.trunk) out.trunk.push_back(CopyLinearOut(host_mlp, layer));
  for (int h = 0; h < kNumDeformHeads; ++h) {
    if (!config.heads[h]) continue;  // disabled heads stay empty
    out.heads[h][0] = CopyLinearOut(host_mlp, layout.head_hidden[h]);
    out.heads[h][1] = CopyLinearOut(host_mlp, layout.head_output[h]);
  }
  *field = std::move(out);
  return Status::Ok();
}

}  // namespace atex::cuda
