#include "levers.h"

#include <algorithm>
#include <cmath>
#include <exception>
#include <functional>

#include "atex/deform.h"
#include "container/row_blocks.h"

namespace atex::fit {
namespace {

// The rows `kept` (ascending indices) of `values`, a [rows][width] array.
template <typename T>
std::vector<T> SubsetRows(const std::vector<T>& values, size_t rows, const std::vector<size_t>& kept) {
  if (rows == 0 || values.empty()) return {};
  const size_t width = values.size() / rows;
  std::vector<T> out(kept.size() * width);
  for (size_t j = 0; j < kept.size(); ++j) std::copy_n(values.data() + kept[j] * width, width, out.data() + j * width);
  return out;
}

// Runs every job, on several threads for a large asset (they write disjoint arrays). An
// exception (out of memory) leaves the parallel region caught and is thrown again here.
void RunAll(const std::vector<std::function<void()>>& jobs, size_t rows) {
  const bool parallel = rows >= (size_t{1} << 15);
  (void)parallel;  // unused without OpenMP
  std::vector<std::exception_ptr> errors(jobs.size());
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 1) if (parallel)
#endif
  for (size_t i = 0; i < jobs.size(); ++i) {
    try {
      jobs[i]();
    } catch (...) {
      errors[i] = std::current_exception();
    }
  }
  for (const std::exception_ptr& e : errors)
    if (e) std::rethrow_exception(e);
}

// Bilinear, align-corners sample of a [rows][cols] plane at fractional (y, x) in index units.
float SamplePlane(const float* plane, int rows, int cols, double y, double x) {
  const int x0 = std::clamp(static_cast<int>(std::floor(x)), 0, cols - 1), x1 = std::min(x0 + 1, cols - 1);
  const int y0 = std::clamp(static_cast<int>(std::floor(y)), 0, rows - 1), y1 = std::min(y0 + 1, rows - 1);
  const double fx = std::clamp(x - x0, 0.0, 1.0), fy = std::clamp(y - y0, 0.0, 1.0);
  const double top = plane[y0 * cols + x0] * (1 - fx) + plane[y0 * cols + x1] * fx;
  const double bottom = plane[y1 * cols + x0] * (1 - fx) + plane[y1 * cols + x1] * fx;
  return static_cast<float>(top * (1 - fy) + bottom * fy);
}

int Coarser(int resolution, int min_resolution) {
  return std::max(std::min(resolution, min_resolution), (resolution + 1) / 2);
}

}  // namespace

Asset SubsetGaussians(const Asset& asset, const std::vector<uint8_t>& keep) {
  const size_t n = asset.gaussians.size();
  std::vector<size_t> kept;  // ascending indices of the Gaussians kept
  kept.reserve(n);
  for (size_t i = 0; i < n; ++i)
    if (keep[i]) kept.push_back(i);
  Asset out;
  out.metadata = asset.metadata;
  const Gaussians& g = asset.gaussians;
  Gaussians& o = out.gaussians;
  o.sh_degree = g.sh_degree;
  // The large per-Gaussian arrays: [n][width] in, [kept][width] out. They are gathered in
  // blocks of rows, every array of a block by one thread: a Panoptic prune gathers 60 MB of SH
  // and 70 MB of texels, too much for one thread per array.
  struct Rows {
    const std::vector<float>* from;
    std::vector<float>* to;
  };
  std::vector<Rows> rows = {{&g.positions, &o.positions},
                            {&g.rotations, &o.rotations},
                            {&g.log_scales, &o.log_scales},
                            {&g.opacity_logits, &o.opacity_logits},
                            {&g.sh, &o.sh},
                            {&g.time_windows, &o.time_windows}};
  const TexturePool* t = asset.textures ? &*asset.textures : nullptr;
  TexturePool* p = nullptr;
  if (t != nullptr) {
    p = &out.textures.emplace();
    p->heights = SubsetRows(t->heights, n, kept);
    p->widths = SubsetRows(t->widths, n, kept);
    p->axis_u = SubsetRows(t->axis_u, n, kept);
    p->axis_v = SubsetRows(t->axis_v, n, kept);
    p->RebuildOffsets();
  }
  // The outputs are allocated first, each on its own thread (a vector's allocation zero-fills
  // it), then filled block by block.
  std::vector<std::function<void()>> allocate = {[&] { out.deformation = asset.deformation; }};
  for (const Rows& r : rows) {
    allocate.push_back([&, r] {
      if (n > 0 && !r.from->empty()) r.to->resize(r.from->size() / n * kept.size());
    });
  }
  if (p != nullptr) allocate.push_back([&] { p->texels.resize(p->texel_count() * kTexelChannels); });
  if (asset.stats) {
    const GaussianStats& s = *asset.stats;
    GaussianStats& so = out.stats.emplace();
    const auto subset = [&](const std::vector<float>& v) {
      return v.size() == n ? SubsetRows(v, n, kept) : std::vector<float>{};
    };
    allocate.push_back([&, subset] {  // `subset` by value: it ends with this block, before the jobs run
      so.texture_demand = subset(s.texture_demand);
      so.peak_scale_u = subset(s.peak_scale_u);
      so.peak_scale_v = subset(s.peak_scale_v);
      so.importance = subset(s.importance);
    });
  }
  RunAll(allocate, n);
  uint64_t values = p != nullptr ? p->texels.size() : 0;  // floats gathered
  for (const Rows& r : rows) values += r.to->size();
  container::ForRowBlocks(kept.size(), container::RowBlocks(kept.size(), values),
                          [&](int64_t, uint64_t begin, uint64_t end) {
                            for (const Rows& r : rows) {
                              if (r.to->empty()) continue;
                              const size_t width = r.from->size() / n;
                              for (size_t j = begin; j < end; ++j) {
                                std::copy_n(r.from->data() + kept[j] * width, width, r.to->data() + j * width);
                              }
                            }
                            if (p == nullptr) return;
                            for (size_t j = begin; j < end; ++j) {
                              const size_t i = kept[j];
                              std::copy_n(t->texels.data() + t->offsets[i] * kTexelChannels,
                                          (t->offsets[i + 1] - t->offsets[i]) * kTexelChannels,
                                          p->texels.data() + p->offsets[j] * kTexelChannels);
                            }
                          });
  return out;
}

Asset CopyAsset(const Asset& asset, bool with_texture_pool) {
  Asset out;
  out.metadata = asset.metadata;
  out.deformation = asset.deformation;  // grids and MLP: megabytes
  const Gaussians& g = asset.gaussians;
  Gaussians& og = out.gaussians;
  og.sh_degree = g.sh_degree;
  std::vector<std::function<void()>> jobs = {[&] { og.positions = g.positions; },
                                             [&] { og.rotations = g.rotations; },
                                             [&] { og.log_scales = g.log_scales; },
                                             [&] { og.opacity_logits = g.opacity_logits; },
                                             [&] { og.sh = g.sh; },
                                             [&] { og.time_windows = g.time_windows; }};
  if (asset.textures && with_texture_pool) {
    out.textures.emplace();
    jobs.push_back([&] {
      TexturePool& t = *out.textures;
      t.heights = asset.textures->heights;
      t.widths = asset.textures->widths;
      t.axis_u = asset.textures->axis_u;
      t.axis_v = asset.textures->axis_v;
      t.offsets = asset.textures->offsets;
    });
    jobs.push_back([&] { out.textures->texels = asset.textures->texels; });
  }
  if (asset.stats) jobs.push_back([&] { out.stats = asset.stats; });
  RunAll(jobs, g.size());
  return out;
}

Status LowerShDegree(Asset* asset) {
  Gaussians& g = asset->gaussians;
  if (g.sh_degree == 0) return MakeError(StatusCode::kInvalidArgument, "SH degree is already 0");
  const size_t n = g.size();
  const int old_k = g.sh_coeffs(), new_k = ShCoeffCount(g.sh_degree - 1);
  std::vector<float> sh(n * new_k * 3);
  for (size_t i = 0; i < n; ++i) {
    std::copy_n(g.sh.begin() + static_cast<std::ptrdiff_t>(i * old_k * 3), new_k * 3,
                sh.begin() + static_cast<std::ptrdiff_t>(i * new_k * 3));
  }
  g.sh = std::move(sh);
  g.sh_degree -= 1;
  if (asset->deformation) {
    DeformationField& d = *asset->deformation;
    if (d.config.heads[kHeadSH]) {
      // dSH is [K][3] like the coefficients (docs/conventions.md §3): keep the first 3K' rows.
      Linear& out = d.heads[kHeadSH][1];
      out.weight.resize(static_cast<size_t>(new_k) * 3 * out.in);
      out.bias.resize(static_cast<size_t>(new_k) * 3);
      out.out = new_k * 3;
      d.config.sh_coeffs = new_k;
    } else if (d.config.sh_coeffs == old_k) {
      d.config.sh_coeffs = new_k;
    }
  }
  return Status::Ok();
}

bool CanCoarsenGrid(const Asset& asset, int min_resolution) {
  if (!asset.deformation) return false;
  const auto& r = asset.deformation->config.grid.base_resolution;
  for (int a = 0; a < 3; ++a) {
    if (Coarser(r[a], min_resolution) < r[a]) return true;
  }
  return false;
}

Status CoarsenGrid(Asset* asset, int min_resolution) {
  if (!CanCoarsenGrid(*asset, min_resolution)) {
    return MakeError(StatusCode::kInvalidArgument, "deformation grids are already at the minimum resolution");
  }
  DeformationField& d = *asset->deformation;
  const HexPlaneConfig old_grid = d.config.grid;
  HexPlaneConfig new_grid = old_grid;
  for (int a = 0; a < 3; ++a) new_grid.base_resolution[a] = Coarser(old_grid.base_resolution[a], min_resolution);
  const int channels = old_grid.channels;
  for (int s = 0; s < old_grid.scales(); ++s) {
    for (int p = 0; p < kNumHexPlanes; ++p) {
      const int a = kHexPlaneAxes[p][0], b = kHexPlaneAxes[p][1];
      const int old_a = old_grid.resolution(s, a), old_b = old_grid.resolution(s, b);
      const int new_a = new_grid.resolution(s, a), new_b = new_grid.resolution(s, b);
      const std::vector<float>& src = d.planes[s][p];
      std::vector<float> dst(static_cast<size_t>(channels) * new_a * new_b);
      for (int c = 0; c < channels; ++c) {
        const float* plane = src.data() + static_cast<size_t>(c) * old_a * old_b;
        for (int y = 0; y < new_b; ++y) {
          const double sy = new_b > 1 ? static_cast<double>(y) * (old_b - 1) / (new_b - 1) : 0.0;
          for (int x = 0; x < new_a; ++x) {
            const double sx = new_a > 1 ? static_cast<double>(x) * (old_a - 1) / (new_a - 1) : 0.0;
            dst[(static_cast<size_t>(c) * new_b + y) * new_a + x] = SamplePlane(plane, old_b, old_a, sy, sx);
          }
        }
      }
      d.planes[s][p] = std::move(dst);
    }
  }
  d.config.grid = new_grid;
  return CheckDeformationField(d);
}

}  // namespace atex::fit
