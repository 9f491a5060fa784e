#include "deform/deform_test_util.h"

namespace atex::testing {

BasicDeformationField<double> RandomField(const DeformationConfig& config, uint64_t seed, double plane_lo,
                                          double plane_hi, double weight_scale) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> plane(plane_lo, plane_hi);
  std::uniform_real_distribution<double> weight(-weight_scale, weight_scale);
  BasicDeformationField<double> f;
  f.config = config;
  const HexPlaneConfig& grid = config.grid;
  f.planes.resize(grid.scales());
  for (int s = 0; s < grid.scales(); ++s) {
    for (int p = 0; p < kNumHexPlanes; ++p) {
      f.planes[s][p].resize(static_cast<size_t>(grid.channels) * grid.resolution(s, kHexPlaneAxes[p][0]) *
                            grid.resolution(s, kHexPlaneAxes[p][1]));
      for (double& v : f.planes[s][p]) v = plane(rng);
    }
  }
  auto linear = [&](int in, int out) {
    BasicLinear<double> l;
    l.in = in;
    l.out = out;
    l.weight.resize(static_cast<size_t>(in) * out);
    l.bias.resize(out);
    for (double& v : l.weight) v = weight(rng);
    for (double& v : l.bias) v = weight(rng);
    return l;
  };
  const int w = config.mlp_width;
  for (int i = 0; i < config.trunk_layers; ++i) f.trunk.push_back(linear(i == 0 ? grid.feature_dim() : w, w));
  for (int h = 0; h < kNumDeformHeads; ++h) {
    if (!config.heads[h]) continue;
    f.heads[h][0] = linear(w, w);
    f.heads[h][1] = linear(w, config.head_outputs(h));
  }
  return f;
}

BasicGaussians<double> RandomGaussians(size_t n, int sh_degree, uint64_t seed, double lo, double hi) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> pos(lo, hi);
  std::uniform_real_distribution<double> other(-1.0, 1.0);
  BasicGaussians<double> g;
  g.sh_degree = sh_degree;
  g.Resize(n);
  for (double& v : g.positions) v = pos(rng);
  for (double& v : g.rotations) v = other(rng);
  for (double& v : g.log_scales) v = other(rng) - 3.0;
  for (double& v : g.opacity_logits) v = other(rng);
  for (double& v : g.sh) v = other(rng);
  return g;
}

DeformationConfig SmallConfig() {
  DeformationConfig c;
  c.grid.channels = 3;
  c.grid.base_resolution = {3, 4, 5, 4};
  c.grid.multires = {1, 2};
  c.mlp_width = 5;
  c.trunk_layers = 2;
  c.heads = {true, true, true, true, true};
  c.sh_coeffs = 4;
  c.aabb_lo = {-1.2f, -0.9f, 1.1f};  // z axis flipped (4DGaussians stores (max, min))
  c.aabb_hi = {1.3f, 1.0f, -1.0f};
  c.time_scale = 1.7f;
  c.time_offset = -0.8f;
  return c;
}

}  // namespace atex::testing
