#include "container/asset_compare.h"

#include <cmath>
#include <string>

namespace atex::testing {
namespace {

::testing::AssertionResult Arrays(const char* what, const std::vector<float>& a, const std::vector<float>& b,
                                  float tol) {
  if (a.size() != b.size()) {
    return ::testing::AssertionFailure() << what << ": sizes " << a.size() << " vs " << b.size();
  }
  for (size_t i = 0; i < a.size(); ++i) {
    const bool ok = tol == 0 ? a[i] == b[i] : std::fabs(a[i] - b[i]) <= tol;
    if (!ok) {
      return ::testing::AssertionFailure()
             << what << "[" << i << "]: " << a[i] << " vs " << b[i] << " (tolerance " << tol << ")";
    }
  }
  return ::testing::AssertionSuccess();
}

template <typename T>
::testing::AssertionResult Same(const char* what, const T& a, const T& b) {
  if (a == b) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << what << " differs";
}

#define ATEX_CHECK(expr)                 \
  do {                                   \
    ::testing::AssertionResult r_ = (expr); \
    if (!r_) return r_;                  \
  } while (0)

::testing::AssertionResult Compare(const Asset& a, const Asset& b, const Tolerances& t) {
  const Gaussians& ga = a.gaussians;
  const Gaussians& gb = b.gaussians;
  ATEX_CHECK(Same("sh_degree", ga.sh_degree, gb.sh_degree));
  ATEX_CHECK(Arrays("positions", ga.positions, gb.positions, t.positions));
  ATEX_CHECK(Arrays("rotations", ga.rotations, gb.rotations, t.rotations));
  ATEX_CHECK(Arrays("log_scales", ga.log_scales, gb.log_scales, t.log_scales));
  ATEX_CHECK(Arrays("opacity_logits", ga.opacity_logits, gb.opacity_logits, t.opacities));
  ATEX_CHECK(Arrays("time_windows", ga.time_windows, gb.time_windows, 0.0));
  ATEX_CHECK(Arrays("sh", ga.sh, gb.sh, t.sh));
  ATEX_CHECK(Same("has textures", a.textures.has_value(), b.textures.has_value()));
  if (a.textures) {
    ATEX_CHECK(Same("texture heights", a.textures->heights, b.textures->heights));
    ATEX_CHECK(Same("texture widths", a.textures->widths, b.textures->widths));
    ATEX_CHECK(Same("texture axis_u", a.textures->axis_u, b.textures->axis_u));
    ATEX_CHECK(Same("texture axis_v", a.textures->axis_v, b.textures->axis_v));
    ATEX_CHECK(Same("texture offsets", a.textures->offsets, b.textures->offsets));
    ATEX_CHECK(Arrays("texels", a.textures->texels, b.textures->texels, t.texels));
  }
  ATEX_CHECK(Same("has deformation", a.deformation.has_value(), b.deformation.has_value()));
  if (a.deformation) {
    const DeformationConfig& ca = a.deformation->config;
    const DeformationConfig& cb = b.deformation->config;
    ATEX_CHECK(Same("channels", ca.grid.channels, cb.grid.channels));
    ATEX_CHECK(Same("base_resolution", ca.grid.base_resolution, cb.grid.base_resolution));
    ATEX_CHECK(Same("multires", ca.grid.multires, cb.grid.multires));
    ATEX_CHECK(Same("mlp_width", ca.mlp_width, cb.mlp_width));
    ATEX_CHECK(Same("trunk_layers", ca.trunk_layers, cb.trunk_layers));
    ATEX_CHECK(Same("heads", ca.heads, cb.heads));
    ATEX_CHECK(Same("sh_coeffs", ca.sh_coeffs, cb.sh_coeffs));
    ATEX_CHECK(Same("aabb_lo", ca.aabb_lo, cb.aabb_lo));
    ATEX_CHECK(Same("aabb_hi", ca.aabb_hi, cb.aabb_hi));
    ATEX_CHECK(Same("time_scale", ca.time_scale, cb.time_scale));
    ATEX_CHECK(Same("time_offset", ca.time_offset, cb.time_offset));
    ATEX_CHECK(Same("plane sets", a.deformation->planes.size(), b.deformation->planes.size()));
    for (size_t s = 0; s < a.deformation->planes.size(); ++s) {
      for (int p = 0; p < kNumHexPlanes; ++p) {
        ATEX_CHECK(Arrays("plane", a.deformation->planes[s][p], b.deformation->planes[s][p], t.grids));
      }
    }
    ATEX_CHECK(Same("trunk layers", a.deformation->trunk.size(), b.deformation->trunk.size()));
    for (size_t l = 0; l < a.deformation->trunk.size(); ++l) {
      ATEX_CHECK(Same("trunk in", a.deformation->trunk[l].in, b.deformation->trunk[l].in));
      ATEX_CHECK(Same("trunk out", a.deformation->trunk[l].out, b.deformation->trunk[l].out));
      ATEX_CHECK(Arrays("trunk weight", a.deformation->trunk[l].weight, b.deformation->trunk[l].weight, t.mlp));
      ATEX_CHECK(Arrays("trunk bias", a.deformation->trunk[l].bias, b.deformation->trunk[l].bias, t.mlp));
    }
    for (int h = 0; h < kNumDeformHeads; ++h) {
      for (int k = 0; k < 2; ++k) {
        const Linear& la = a.deformation->heads[h][k];
        const Linear& lb = b.deformation->heads[h][k];
        ATEX_CHECK(Same("head in", la.in, lb.in));
        ATEX_CHECK(Same("head out", la.out, lb.out));
        ATEX_CHECK(Arrays("head weight", la.weight, lb.weight, t.mlp));
        ATEX_CHECK(Arrays("head bias", la.bias, lb.bias, t.mlp));
      }
    }
  }
  ATEX_CHECK(Same("has stats", a.stats.has_value(), b.stats.has_value()));
  if (a.stats) {
    ATEX_CHECK(Arrays("texture_demand", a.stats->texture_demand, b.stats->texture_demand, t.stats));
    ATEX_CHECK(Arrays("peak_scale_u", a.stats->peak_scale_u, b.stats->peak_scale_u, t.stats));
    ATEX_CHECK(Arrays("peak_scale_v", a.stats->peak_scale_v, b.stats->peak_scale_v, t.stats));
    ATEX_CHECK(Arrays("importance", a.stats->importance, b.stats->importance, t.stats));
  }
  const Metadata& ma = a.metadata;
  const Metadata& mb = b.metadata;
  ATEX_CHECK(Same("bounds_min", ma.bounds_min, mb.bounds_min));
  ATEX_CHECK(Same("bounds_max", ma.bounds_max, mb.bounds_max));
  ATEX_CHECK(Same("time_min", ma.time_min, mb.time_min));
  ATEX_CHECK(Same("time_max", ma.time_max, mb.time_max));
  ATEX_CHECK(Same("background", ma.background, mb.background));
  ATEX_CHECK(Same("texture_mode", ma.texture_mode, mb.texture_mode));
  ATEX_CHECK(Same("axes", ma.axes, mb.axes));
  ATEX_CHECK(Same("units", ma.units, mb.units));
  if (ma.extra != mb.extra) {
    return ::testing::AssertionFailure() << "extra differs: " << ma.extra.dump() << " vs " << mb.extra.dump();
  }
  return ::testing::AssertionSuccess();
}

}  // namespace

::testing::AssertionResult AssetsEqual(const Asset& a, const Asset& b) { return Compare(a, b, Tolerances{}); }

::testing::AssertionResult AssetsNear(const Asset& a, const Asset& b, const Tolerances& tolerances) {
  return Compare(a, b, tolerances);
}

}  // namespace atex::testing
