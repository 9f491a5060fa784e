#include "texture_shrink.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <queue>
#include <tuple>
#include <vector>

#include "atex/detail/texture.h"
#include "container/fingerprint.h"
#include "container/row_blocks.h"

namespace atex::fit {
namespace {

constexpr double kScale = detail::kTextureColorScale;  // colour and alpha use the same 0.1·tanh
static_assert(detail::kTextureColorScale == detail::kTextureAlphaScale);

int Log2Side(int side) { return side == 4 ? 2 : side == 2 ? 1 : 0; }

// Value at u ∈ [0, 1] (corner-aligned) of the hat function of sample j among n.
double Hat(int n, int j, double u) {
  if (n == 1) return 1.0;
  const double x = u * (n - 1);
  return std::max(0.0, 1.0 - std::abs(x - j));
}

// P[n'][n]: the L2 projection of a piecewise-linear field on n corner-aligned samples
// onto the fields on n' samples. Computed once by dense quadrature (the integrands are
// piecewise linear/quadratic, so 4096 midpoint samples are exact to ~1e-7).
struct Projections {
  // [log2 n][log2 n'] → row-major n' × n.
  std::array<std::array<std::vector<double>, 3>, 3> p;
  Projections() {
    constexpr int kSamples = 4096;
    for (int ln = 0; ln < 3; ++ln) {
      for (int lm = 0; lm <= ln; ++lm) {
        const int n = 1 << ln, m = 1 << lm;
        std::vector<double> ata(m * m, 0.0), atb(m * n, 0.0);
        for (int s = 0; s < kSamples; ++s) {
          const double u = (s + 0.5) / kSamples;
          for (int a = 0; a < m; ++a) {
            const double ha = Hat(m, a, u);
            for (int b = 0; b < m; ++b) ata[a * m + b] += ha * Hat(m, b, u);
            for (int j = 0; j < n; ++j) atb[a * n + j] += ha * Hat(n, j, u);
          }
        }
        // Solve ata · P = atb (m ≤ 4; Gauss–Jordan, the matrix is SPD and tiny).
        std::vector<double> a = ata, b = atb;
        for (int c = 0; c < m; ++c) {
          const double pivot = a[c * m + c];
          for (int k = 0; k < m; ++k) a[c * m + k] /= pivot;
          for (int k = 0; k < n; ++k) b[c * n + k] /= pivot;
          for (int r = 0; r < m; ++r) {
            if (r == c) continue;
            const double f = a[r * m + c];
            for (int k = 0; k < m; ++k) a[r * m + k] -= f * a[c * m + k];
            for (int k = 0; k < n; ++k) b[r * n + k] -= f * b[c * n + k];
          }
        }
        p[ln][lm] = std::move(b);
      }
    }
  }
};

const Projections& GetProjections() {
  static const Projections projections;
  return projections;
}

// Separable projection of values [h][w][4] to [h'][w'][4] (sides at most 4: fixed-size arrays, no allocation).
using TexelBlock = std::array<double, 4 * 4 * kTexelChannels>;
TexelBlock Project(const TexelBlock& act, int h, int w, int nh, int nw) {
  const auto& pw = GetProjections().p[Log2Side(w)][Log2Side(nw)];
  const auto& ph = GetProjections().p[Log2Side(h)][Log2Side(nh)];
  TexelBlock rows{}, out{};
  for (int y = 0; y < h; ++y)
    for (int x2 = 0; x2 < nw; ++x2)
      for (int x = 0; x < w; ++x)
        for (int c = 0; c < 4; ++c) rows[(y * nw + x2) * 4 + c] += pw[x2 * w + x] * act[(y * w + x) * 4 + c];
  for (int y2 = 0; y2 < nh; ++y2)
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < nw; ++x)
        for (int c = 0; c < 4; ++c) out[(y2 * nw + x) * 4 + c] += ph[y2 * h + y] * rows[(y * nw + x) * 4 + c];
  return out;
}

}  // namespace

void ShrinkTexture(const float* src, int height, int width, float* dst, int new_height, int new_width) {
  // The renderer interpolates the RAW texels and activates afterwards (0.1·tanh of the
  // bilinear value), so the projection works on the raw field.
  TexelBlock raw{};
  for (int k = 0; k < height * width * 4; ++k) raw[k] = src[k];
  const TexelBlock projected = Project(raw, height, width, new_height, new_width);
  for (int k = 0; k < new_height * new_width * 4; ++k) dst[k] = static_cast<float>(projected[k]);
}

namespace {

// ShrinkResidual with tanh(src) given (a texture's two candidate halvings share it).
double ShrinkResidualOf(const float* src, const double* tanh_src, int height, int width, int new_height,
                        int new_width) {
  std::array<float, 4 * 4 * kTexelChannels> shrunk, back;
  ShrinkTexture(src, height, width, shrunk.data(), new_height, new_width);
  detail::UpsampleTexture(shrunk.data(), new_height, new_width, back.data(), height, width, 4);
  const int count = height * width * 4;
  double sum = 0;
  for (int k = 0; k < count; ++k) {
    const double d = kScale * (std::tanh(static_cast<double>(back[k])) - tanh_src[k]);
    sum += d * d;
  }
  return sum / static_cast<double>(count);
}

std::array<double, 4 * 4 * kTexelChannels> TanhOf(const float* src, int height, int width) {
  std::array<double, 4 * 4 * kTexelChannels> out{};
  for (int k = 0; k < height * width * kTexelChannels; ++k) out[k] = std::tanh(static_cast<double>(src[k]));
  return out;
}

}  // namespace

double ShrinkResidual(const float* src, int height, int width, int new_height, int new_width) {
  return ShrinkResidualOf(src, TanhOf(src, height, width).data(), height, width, new_height, new_width);
}

HalvingResiduals HalvingResidualsOf(const float* src, int height, int width) {
  HalvingResiduals r;
  if (height * width == 1) return r;
  const auto tanh_src = TanhOf(src, height, width);
  if (width > 1) r.width = ShrinkResidualOf(src, tanh_src.data(), height, width, height, width / 2);
  if (height > 1) r.height = ShrinkResidualOf(src, tanh_src.data(), height, width, height / 2, width);
  return r;
}

HalvingResiduals TextureShrinkMemo::Residuals(const float* src, int height, int width) {
  const container::Fingerprint key = container::FingerprintBuilder()
                                         .Add(src, sizeof(float) * kTexelChannels * height * width)
                                         .AddValue(static_cast<uint8_t>(height * 8 + width))
                                         .Finish();
  Shard& shard = shards_[key.a % kShards];
  {
    std::lock_guard<std::mutex> lock(shard.mutex);
    const auto it = shard.residuals.find(key);
    if (it != shard.residuals.end()) return it->second;
  }
  const HalvingResiduals r = HalvingResidualsOf(src, height, width);
  std::lock_guard<std::mutex> lock(shard.mutex);
  // A bound on memory: a shard that fills up starts again (the values are only recomputed).
  if (shard.residuals.size() >= kEntriesPerShard) shard.residuals.clear();
  shard.residuals.emplace(key, r);
  return r;
}

uint64_t ShrinkableTexels(const TexturePool& pool) { return pool.texel_count() - pool.size(); }

namespace {

struct Op {
  double cost = 0;     // damage per removed texel
  double demand = 0;
  uint32_t index = 0;
  uint8_t new_h = 1, new_w = 1;
  bool operator>(const Op& o) const {
    return std::tie(cost, demand, index) > std::tie(o.cost, o.demand, o.index);
  }
};

}  // namespace

StatusOr<uint64_t> ShrinkTextures(Asset* asset, uint64_t count, TextureShrinkMemo* memo) {
  if (!asset->textures) return uint64_t{0};
  TexturePool& pool = *asset->textures;
  const size_t n = pool.size();
  // Statistics the trainer leaves (model.h, GaussianStats); missing ones count as
  // importance 1, demand 0 and equal scales.
  static const std::vector<float> kMissing;
  const GaussianStats* stats = asset->stats ? &*asset->stats : nullptr;
  const std::vector<float>& importance_of = stats ? stats->importance : kMissing;
  const std::vector<float>& demand_of = stats ? stats->texture_demand : kMissing;
  const std::vector<float>& scale_u_of = stats ? stats->peak_scale_u : kMissing;
  const std::vector<float>& scale_v_of = stats ? stats->peak_scale_v : kMissing;
  const auto stat = [&](const std::vector<float>& v, size_t i, float fallback) {
    return v.size() == n ? v[i] : fallback;
  };
  // Current texels per Gaussian (modified copies are kept separately until the pool is rebuilt).
  std::vector<std::vector<float>> changed(n);
  std::vector<uint8_t> heights = pool.heights, widths = pool.widths;
  const auto texels_of = [&](uint32_t i) -> const float* {
    return changed[i].empty() ? pool.texels.data() + pool.offsets[i] * kTexelChannels : changed[i].data();
  };
  const auto best_op = [&](uint32_t i, Op* op) -> bool {
    const int h = heights[i], w = widths[i];
    if (h == 1 && w == 1) return false;
    const double importance = std::max(0.0f, stat(importance_of, i, 1.0f));
    struct Choice { double cost; double scale; int nh, nw; };
    std::array<Choice, 2> choices;
    int choice_count = 0;
    // Halving w (u axis) or h (v axis); the peak scale along the axis breaks ties (smaller matters less).
    const float* src = texels_of(i);
    const HalvingResiduals r = memo != nullptr ? memo->Residuals(src, h, w) : HalvingResidualsOf(src, h, w);
    if (w > 1) {
      choices[choice_count++] = {importance * r.width * h * w / (h * (w - w / 2)), stat(scale_u_of, i, 0.0f), h,
                                 w / 2};
    }
    if (h > 1) {
      choices[choice_count++] = {importance * r.height * h * w / (w * (h - h / 2)), stat(scale_v_of, i, 0.0f),
                                 h / 2, w};
    }
    const Choice* best = &choices[0];
    for (int c = 1; c < choice_count; ++c) {
      if (choices[c].cost < best->cost || (choices[c].cost == best->cost && choices[c].scale < best->scale)) {
        best = &choices[c];
      }
    }
    op->cost = best->cost;
    op->demand = stat(demand_of, i, 0.0f);
    op->index = i;
    op->new_h = static_cast<uint8_t>(best->nh);
    op->new_w = static_cast<uint8_t>(best->nw);
    return true;
  };
  // Every texture's cheapest halving, computed in parallel (independent), then a
  // min-heap in Op order (a total order, so the result does not depend on threads).
  std::vector<Op> initial(n);
  std::vector<uint8_t> has_op(n, 0);
#ifdef _OPENMP
#pragma omp parallel for schedule(static) if (n > 4096)
#endif
  for (int64_t i = 0; i < static_cast<int64_t>(n); ++i) {
    has_op[i] = best_op(static_cast<uint32_t>(i), &initial[i]);
  }
  std::vector<Op> heap;
  heap.reserve(n);
  for (size_t i = 0; i < n; ++i)
    if (has_op[i]) heap.push_back(initial[i]);
  std::priority_queue<Op, std::vector<Op>, std::greater<Op>> queue(std::greater<Op>{}, std::move(heap));
  uint64_t done = 0;
  while (done < count && !queue.empty()) {
    const Op op = queue.top();
    queue.pop();
    const uint32_t i = op.index;
    std::vector<float> shrunk(static_cast<size_t>(op.new_h) * op.new_w * kTexelChannels);
    ShrinkTexture(texels_of(i), heights[i], widths[i], shrunk.data(), op.new_h, op.new_w);
    changed[i] = std::move(shrunk);
    heights[i] = op.new_h;
    widths[i] = op.new_w;
    ++done;
    Op next;
    if (best_op(i, &next)) queue.push(next);
  }
  // Rebuild the packed pool.
  TexturePool out;
  out.heights = std::move(heights);
  out.widths = std::move(widths);
  out.axis_u = pool.axis_u;
  out.axis_v = pool.axis_v;
  out.RebuildOffsets();
  out.texels.resize(out.texel_count() * kTexelChannels);
  // Independent copies into disjoint ranges: on several threads (a Panoptic pool is 70 MB).
  container::ForRowBlocks(n, container::RowBlocks(n, out.texels.size()), [&](int64_t, uint64_t begin, uint64_t end) {
    for (size_t i = begin; i < end; ++i) {
      const float* src = texels_of(static_cast<uint32_t>(i));
      std::copy(src, src + static_cast<size_t>(out.heights[i]) * out.widths[i] * kTexelChannels,
                out.texels.begin() + static_cast<std::ptrdiff_t>(out.offsets[i] * kTexelChannels));
    }
  });
  pool = std::move(out);
  // Textures of different sizes are an adaptive pool, whatever mode trained them.
  if (done > 0 && asset->metadata.texture_mode == "uniform") asset->metadata.texture_mode = "adaptive";
  return done;
}

Status HalveAllTextures(Asset* asset) {
  if (!asset->textures || ShrinkableTexels(*asset->textures) == 0) {
    return MakeError(StatusCode::kInvalidArgument, "every texture is already 1x1");
  }
  const TexturePool& pool = *asset->textures;
  const size_t n = pool.size();
  TexturePool out;
  out.heights = pool.heights;
  out.widths = pool.widths;
  out.axis_u = pool.axis_u;
  out.axis_v = pool.axis_v;
  for (size_t i = 0; i < n; ++i) {
    uint8_t& h = out.heights[i];
    uint8_t& w = out.widths[i];
    if (h >= w && h > 1) {
      h = static_cast<uint8_t>(h / 2);
    } else if (w > 1) {
      w = static_cast<uint8_t>(w / 2);
    }
  }
  out.RebuildOffsets();
  out.texels.resize(out.texel_count() * kTexelChannels);
#ifdef _OPENMP
#pragma omp parallel for schedule(static) if (n > 4096)
#endif
  for (int64_t i = 0; i < static_cast<int64_t>(n); ++i) {
    const float* src = pool.texels.data() + pool.offsets[i] * kTexelChannels;
    float* dst = out.texels.data() + out.offsets[i] * kTexelChannels;
    if (out.heights[i] == pool.heights[i] && out.widths[i] == pool.widths[i]) {
      std::copy(src, src + static_cast<size_t>(pool.heights[i]) * pool.widths[i] * kTexelChannels, dst);
    } else {
      ShrinkTexture(src, pool.heights[i], pool.widths[i], dst, out.heights[i], out.widths[i]);
    }
  }
  asset->textures = std::move(out);
  return Status::Ok();
}

}  // namespace atex::fit
