#include "container/synthetic_asset.h"

#include <algorithm>
#include <cmath>

namespace atex::container {
namespace {

class Random {
 public:
  explicit Random(uint64_t seed) : state_(seed) {}
  uint64_t Next() {
    uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  // [0, 1) with 24 bits.
  float Uniform() { return static_cast<float>(Next() >> 40) * (1.0f / 16777216.0f); }
  float Uniform(float lo, float hi) { return lo + (hi - lo) * Uniform(); }
  // Irwin-Hall(4), centred and scaled to unit variance: close enough to normal,
  // and exactly reproducible (no log/cos).
  float Normal(float mean, float sigma) {
    const float s = Uniform() + Uniform() + Uniform() + Uniform() - 2.0f;
    return mean + sigma * s * 1.7320508f;  // variance of the sum is 1/3
  }
  uint32_t Below(uint32_t n) { return static_cast<uint32_t>(Next() % n); }

 private:
  uint64_t state_;
};

uint8_t DrawSide(Random& r) {
  const float u = r.Uniform();
  return u < 0.4f ? 1 : u < 0.7f ? 2 : 4;
}

void FillLinear(Random& r, Linear* layer, int in, int out) {
  layer->in = in;
  layer->out = out;
  const float bound = std::sqrt(6.0f / static_cast<float>(in + out));  // Xavier-uniform
  layer->weight.resize(static_cast<size_t>(in) * out);
  for (float& w : layer->weight) w = r.Uniform(-bound, bound);
  layer->bias.resize(out);
  for (float& b : layer->bias) b = r.Normal(0.0f, 0.01f);
}

// A random deformation field for the synthetic asset (`realistic_deformation`: D-NeRF's
// grid and MLP sizes), drawn from `r` after the Gaussians and textures.
DeformationField SyntheticDeformation(Random& r, const SyntheticAssetOptions& o, int sh_coeffs) {
  const int k = sh_coeffs;
  DeformationField d;
  DeformationConfig& c = d.config;
  if (o.realistic_deformation) {
    c.grid.channels = 32;
    c.grid.base_resolution = {64, 64, 64, 25};
    c.mlp_width = 64;
  } else {
    c.grid.channels = 4;
    c.grid.base_resolution = {8, 6, 5, 4};
    c.mlp_width = 16;
  }
  c.grid.multires = {1, 2};
  c.trunk_layers = 2;
  c.heads = {true, true, true, o.sh_head, o.sh_head};
  c.sh_coeffs = k;
  c.aabb_lo = {-2.0f, -2.0f, -2.0f};
  c.aabb_hi = {2.0f, 2.0f, 2.0f};
  d.planes.resize(c.grid.scales());
  for (int s = 0; s < c.grid.scales(); ++s) {
    for (int p = 0; p < kNumHexPlanes; ++p) {
      const bool time = kHexPlaneAxes[p][1] == 3;
      std::vector<float>& plane = d.planes[s][p];
      plane.resize(static_cast<size_t>(c.grid.channels) * c.grid.resolution(s, kHexPlaneAxes[p][0]) *
                   c.grid.resolution(s, kHexPlaneAxes[p][1]));
      for (float& v : plane) v = time ? 1.0f + r.Normal(0.0f, 0.01f) : r.Uniform(0.1f, 0.5f);
    }
  }
  d.trunk.resize(c.trunk_layers);
  for (int l = 0; l < c.trunk_layers; ++l)
    FillLinear(r, &d.trunk[l], l == 0 ? c.grid.feature_dim() : c.mlp_width, c.mlp_width);
  for (int h = 0; h < kNumDeformHeads; ++h) {
    if (!c.heads[h]) continue;
    FillLinear(r, &d.heads[h][0], c.mlp_width, c.mlp_width);
    FillLinear(r, &d.heads[h][1], c.mlp_width, c.head_outputs(h));
  }
  return d;
}

}  // namespace

Asset MakeSyntheticAsset(const SyntheticAssetOptions& o) {
  Random r(o.seed);
  Asset asset;
  Gaussians& g = asset.gaussians;
  g.sh_degree = std::clamp(o.sh_degree, 0, kMaxShDegree);
  const size_t n = o.gaussians;
  g.Resize(n);
  const int k = g.sh_coeffs();

  // Positions in a few clusters inside [-2, 2]^3, like surfaces of objects.
  constexpr int kClusters = 16;
  float centres[kClusters][3];
  for (auto& c : centres) {
    for (float& v : c) v = r.Uniform(-1.5f, 1.5f);
  }
  for (size_t i = 0; i < n; ++i) {
    const int c = static_cast<int>(r.Below(kClusters));
    for (int a = 0; a < 3; ++a) g.positions[i * 3 + a] = centres[c][a] + r.Normal(0.0f, 0.15f);
    for (int a = 0; a < 4; ++a) g.rotations[i * 4 + a] = r.Normal(0.0f, 1.0f);
    g.rotations[i * 4] += 0.5f;  // never all zero in practice
    for (int a = 0; a < 3; ++a) g.log_scales[i * 3 + a] = r.Normal(-4.0f, 0.6f);
    g.opacity_logits[i] = r.Normal(0.5f, 2.0f);
    for (int j = 0; j < k; ++j) {
      const float sigma = j == 0 ? 0.6f : 0.08f / static_cast<float>(j);
      for (int ch = 0; ch < 3; ++ch) g.sh[(i * k + j) * 3 + ch] = r.Normal(0.0f, sigma);
    }
  }

  if (o.textures != SyntheticTextures::kNone) {
    TexturePool t;
    t.heights.resize(n);
    t.widths.resize(n);
    t.axis_u.resize(n);
    t.axis_v.resize(n);
    for (size_t i = 0; i < n; ++i) {
      if (o.textures == SyntheticTextures::kUniform) {
        t.heights[i] = static_cast<uint8_t>(o.uniform_h);
        t.widths[i] = static_cast<uint8_t>(o.uniform_w);
      } else {
        t.heights[i] = DrawSide(r);
        t.widths[i] = DrawSide(r);
      }
      t.axis_u[i] = static_cast<uint8_t>(r.Below(3));
      t.axis_v[i] = static_cast<uint8_t>((t.axis_u[i] + 1 + r.Below(2)) % 3);
    }
    t.RebuildOffsets();
    t.texels.resize(t.texel_count() * kTexelChannels);
    for (float& v : t.texels) v = r.Normal(0.0f, 0.3f);
    asset.textures = std::move(t);
  }

  if (o.deformation) asset.deformation = SyntheticDeformation(r, o, k);

  if (o.stats) {
    GaussianStats s;
    s.texture_demand.resize(n);
    s.peak_scale_u.resize(n);
    s.peak_scale_v.resize(n);
    s.importance.resize(n);
    for (size_t i = 0; i < n; ++i) {
      s.texture_demand[i] = r.Uniform() * 1e-4f;
      s.peak_scale_u[i] = r.Uniform(0.001f, 0.05f);
      s.peak_scale_v[i] = r.Uniform(0.001f, 0.05f);
      s.importance[i] = r.Uniform(0.0f, 100.0f);
    }
    asset.stats = std::move(s);
  }

  Metadata& m = asset.metadata;
  if (n > 0) {
    for (int a = 0; a < 3; ++a) {
      m.bounds_min[a] = m.bounds_max[a] = g.positions[a];
      for (size_t i = 1; i < n; ++i) {
        m.bounds_min[a] = std::min(m.bounds_min[a], g.positions[i * 3 + a]);
        m.bounds_max[a] = std::max(m.bounds_max[a], g.positions[i * 3 + a]);
      }
    }
  }
  m.texture_mode = o.textures == SyntheticTextures::kNone      ? "none"
                   : o.textures == SyntheticTextures::kUniform ? "uniform"
                                                               : "adaptive";
  m.units = "meters";
  m.extra = {{"generator", "atex synthetic"}, {"seed", o.seed}};
  return asset;
}

}  // namespace atex::container
