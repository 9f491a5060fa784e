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
  double cost = 0;  // damage per removed texel
  double demand = 0;
  uint32_t index = 0;
  uint8_t new_h = 1, new_w = 1;
  // Where the op sits in ShrinkTexturePool's chains (not part of the order).
  uint32_t chain = 0;
  uint8_t step = 0;
  bool operator>(const Op& o) const { return std::tie(cost, demand, index) > std::tie(o.cost, o.demand, o.index); }
};

// A texture's halvings one after another, down to 1×1 (4×4 takes four), and how many of them
// the greedy took. residuals[s] are those of the texture before ops[s]; after the last op it is
// 1×1 (its residuals are 0).
constexpr int kMaxHalvings = 4;
struct Chain {
  std::array<Op, kMaxHalvings> ops;
  std::array<HalvingResiduals, kMaxHalvings> residuals;
  uint8_t length = 0, taken = 0;
};
constexpr uint32_t kNoChain = UINT32_MAX;

// A shrunk texture: a halving leaves at most 4×2 texels.
using ShrunkTexels = std::array<float, 4 * 2 * kTexelChannels>;

// The cheapest halving of a texture of `asset`'s pool, whatever texels it holds now. The
// statistics the trainer leaves (model.h, GaussianStats) weigh it; missing ones count as
// importance 1, demand 0 and equal scales. Thread-safe.
class HalvingCosts {
 public:
  HalvingCosts(const Asset& asset, TextureShrinkMemo* memo) : n_(asset.textures->size()), memo_(memo) {
    if (const GaussianStats* stats = asset.stats ? &*asset.stats : nullptr) {
      importance_ = &stats->importance;
      demand_ = &stats->texture_demand;
      scale_u_ = &stats->peak_scale_u;
      scale_v_ = &stats->peak_scale_v;
    }
  }

  // The residuals of halving a texture whose texels are `src` ([h][w][4]).
  HalvingResiduals Residuals(const float* src, int h, int w) const {
    return memo_ != nullptr ? memo_->Residuals(src, h, w) : HalvingResidualsOf(src, h, w);
  }

  // The op halving texture i of size h×w, whose halvings' residuals are `r`, along its cheaper
  // axis (on a tie the one with the smaller peak scale); false at 1×1.
  bool Best(uint32_t i, const HalvingResiduals& r, int h, int w, Op* op) const {
    if (h == 1 && w == 1) return false;
    const double importance = std::max(0.0f, Stat(importance_, i, 1.0f));
    struct Choice {
      double cost;
      double scale;
      int nh, nw;
    };
    std::array<Choice, 2> choices;
    int choice_count = 0;
    if (w > 1)
      choices[choice_count++] = {importance * r.width * h * w / (h * (w - w / 2)), Stat(scale_u_, i, 0), h, w / 2};
    if (h > 1)
      choices[choice_count++] = {importance * r.height * h * w / (w * (h - h / 2)), Stat(scale_v_, i, 0), h / 2, w};
    const Choice* best = &choices[0];
    for (int c = 1; c < choice_count; ++c) {
      if (choices[c].cost < best->cost || (choices[c].cost == best->cost && choices[c].scale < best->scale)) {
        best = &choices[c];
      }
    }
    op->cost = best->cost;
    op->demand = Stat(demand_, i, 0.0f);
    op->index = i;
    op->new_h = static_cast<uint8_t>(best->nh);
    op->new_w = static_cast<uint8_t>(best->nw);
    return true;
  }

 private:
  float Stat(const std::vector<float>* v, size_t i, float fallback) const {
    return v != nullptr && v->size() == n_ ? (*v)[i] : fallback;
  }
  size_t n_;
  TextureShrinkMemo* memo_;
  const std::vector<float>*importance_ = nullptr, *demand_ = nullptr, *scale_u_ = nullptr, *scale_v_ = nullptr;
};

const float* InputTexels(const TexturePool& pool, size_t i) {
  return pool.texels.data() + pool.offsets[i] * kTexelChannels;
}

// The chains of halvings of the textures whose first halving is among the `count` cheapest
// (every texture's first halving is computed, in parallel); chain_of[i] is texture i's chain
// or kNoChain. A greedy of `count` pops only ever pops these chains' ops: a first halving
// outside them comes after all of theirs, and they are `count` pops. Each chain (every
// halving after the one before: most of the greedy's work, and independent) is computed on
// several threads.
// `residuals` holds every texture's residuals: given by the caller, or computed here when it
// comes empty.
std::vector<Chain> ChainsOfTheCheapest(const TexturePool& pool, const HalvingCosts& costs, uint64_t count,
                                       PoolResiduals* residuals, std::vector<uint32_t>* chain_of) {
  const size_t n = pool.size();
  const bool compute = residuals->empty();
  if (compute) residuals->resize(n);
  std::vector<Op> first(n);
  std::vector<uint8_t> has_op(n, 0);
#ifdef _OPENMP
#pragma omp parallel for schedule(static) if (n > 4096)
#endif
  for (int64_t i = 0; i < static_cast<int64_t>(n); ++i) {
    const int h = pool.heights[i], w = pool.widths[i];
    if (compute) (*residuals)[i] = costs.Residuals(InputTexels(pool, i), h, w);
    has_op[i] = costs.Best(static_cast<uint32_t>(i), (*residuals)[i], h, w, &first[i]);
  }
  size_t kept = 0;
  for (size_t i = 0; i < n; ++i)
    if (has_op[i]) first[kept++] = first[i];
  first.resize(kept);
  if (first.size() > count) {
    const auto before = [](const Op& a, const Op& b) { return b > a; };
    std::nth_element(first.begin(), first.begin() + static_cast<std::ptrdiff_t>(count), first.end(), before);
    first.resize(count);
  }
  std::vector<Chain> chains(first.size());
  chain_of->assign(n, kNoChain);
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 256) if (chains.size() > 1024)
#endif
  for (int64_t j = 0; j < static_cast<int64_t>(chains.size()); ++j) {
    Chain& chain = chains[j];
    const uint32_t i = first[j].index;
    (*chain_of)[i] = static_cast<uint32_t>(j);
    chain.ops[0] = first[j];
    chain.residuals[0] = (*residuals)[i];
    chain.length = 1;
    std::array<ShrunkTexels, 2> buffers;
    const float* src = InputTexels(pool, i);
    int h = pool.heights[i], w = pool.widths[i];
    while (chain.length < kMaxHalvings) {
      const Op& op = chain.ops[chain.length - 1];
      float* dst = buffers[chain.length % 2].data();
      ShrinkTexture(src, h, w, dst, op.new_h, op.new_w);
      src = dst;
      h = op.new_h;
      w = op.new_w;
      if (h * w == 1) break;
      chain.residuals[chain.length] = costs.Residuals(src, h, w);
      if (!costs.Best(i, chain.residuals[chain.length], h, w, &chain.ops[chain.length])) break;
      ++chain.length;
    }
    for (uint8_t step = 0; step < chain.length; ++step) {
      chain.ops[step].chain = static_cast<uint32_t>(j);
      chain.ops[step].step = step;
    }
  }
  return chains;
}

// `pool` with each chain's taken halvings applied, packed into `out`: a changed texture's
// texels are its halvings replayed (the same arithmetic as when its chain was computed).
void WriteShrunkPool(const TexturePool& pool, const std::vector<Chain>& chains, const std::vector<uint32_t>& chain_of,
                     TexturePool* out) {
  const size_t n = pool.size();
  out->heights = pool.heights;
  out->widths = pool.widths;
  for (const Chain& chain : chains) {
    if (chain.taken == 0) continue;
    const Op& last = chain.ops[chain.taken - 1];
    out->heights[last.index] = last.new_h;
    out->widths[last.index] = last.new_w;
  }
  out->axis_u = pool.axis_u;
  out->axis_v = pool.axis_v;
  out->RebuildOffsets();
  out->texels.resize(out->texel_count() * kTexelChannels);
  // Independent writes into disjoint ranges: on several threads (a Panoptic pool is 70 MB).
  container::ForRowBlocks(n, container::RowBlocks(n, out->texels.size()), [&](int64_t, uint64_t begin, uint64_t end) {
    std::array<ShrunkTexels, 2> buffers;
    for (size_t i = begin; i < end; ++i) {
      const float* src = InputTexels(pool, i);
      int h = pool.heights[i], w = pool.widths[i];
      const Chain* chain = chain_of[i] == kNoChain ? nullptr : &chains[chain_of[i]];
      for (uint8_t step = 0; chain != nullptr && step < chain->taken; ++step) {
        const Op& op = chain->ops[step];
        float* dst = buffers[step % 2].data();
        ShrinkTexture(src, h, w, dst, op.new_h, op.new_w);
        src = dst;
        h = op.new_h;
        w = op.new_w;
      }
      std::copy(src, src + static_cast<size_t>(h) * w * kTexelChannels,
                out->texels.begin() + static_cast<std::ptrdiff_t>(out->offsets[i] * kTexelChannels));
    }
  });
}

}  // namespace

StatusOr<uint64_t> ShrinkTexturePool(const Asset& asset, uint64_t count, TextureShrinkMemo* memo, TexturePool* out,
                                     const PoolResiduals* known, PoolResiduals* out_residuals) {
  if (!asset.textures) return MakeError(StatusCode::kInvalidArgument, "fit: no texture pool to shrink");
  const TexturePool& pool = *asset.textures;
  if (known != nullptr && known->size() != pool.size()) {
    return MakeError(StatusCode::kInvalidArgument, "fit: ", known->size(), " texture residuals for ", pool.size(),
                     " textures");
  }
  const HalvingCosts costs(asset, memo);
  PoolResiduals residuals;
  if (known != nullptr) residuals = *known;
  std::vector<uint32_t> chain_of;
  std::vector<Chain> chains = ChainsOfTheCheapest(pool, costs, count, &residuals, &chain_of);
  // The greedy: `count` pops in Op order (a total order, so the result does not depend on
  // threads), each offering the next halving of its texture.
  std::vector<Op> heads;
  heads.reserve(chains.size());
  for (const Chain& chain : chains) heads.push_back(chain.ops[0]);
  std::priority_queue<Op, std::vector<Op>, std::greater<Op>> queue(std::greater<Op>{}, std::move(heads));
  uint64_t done = 0;
  while (done < count && !queue.empty()) {
    const Op op = queue.top();
    queue.pop();
    Chain& chain = chains[op.chain];
    chain.taken = op.step + 1;
    ++done;
    if (chain.taken < chain.length) queue.push(chain.ops[chain.taken]);
  }
  WriteShrunkPool(pool, chains, chain_of, out);
  if (out_residuals != nullptr) {
    for (const Chain& chain : chains) {
      if (chain.taken == 0) continue;
      const uint32_t i = chain.ops[0].index;
      residuals[i] = chain.taken < chain.length ? chain.residuals[chain.taken] : HalvingResiduals{};
    }
    *out_residuals = std::move(residuals);
  }
  return done;
}

void MarkTexturesShrunk(Asset* asset, uint64_t done) {
  // Textures of different sizes are an adaptive pool, whatever mode trained them.
  if (done > 0 && asset->metadata.texture_mode == "uniform") asset->metadata.texture_mode = "adaptive";
}

StatusOr<uint64_t> ShrinkTextures(Asset* asset, uint64_t count, TextureShrinkMemo* memo) {
  if (!asset->textures) return uint64_t{0};
  TexturePool shrunk;
  ATEX_ASSIGN_OR_RETURN(const uint64_t done, ShrinkTexturePool(*asset, count, memo, &shrunk));
  asset->textures = std::move(shrunk);
  MarkTexturesShrunk(asset, done);
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
