// IncrementalProbes (incremental_probes.h): candidate renders against the base.
#include "incremental_probes.h"

#include <algorithm>
#include <cstring>
#include <exception>
#include <new>

#include "atex/detail/composite.h"
#include "atex/render.h"
#include "atex/train/trainer.h"
#include "incremental_probes_state.h"
#include "render/parallel.h"
#include "render/render_internal.h"
#include "tile_composite.h"

namespace atex::fit::internal {
namespace {

constexpr uint32_t kFresh = 0x80000000u;  // tile-list entry: a changed splat (index into `changed`)

// Asks for the cache line of `p` ahead of its use. GCC 12 drops a __builtin_prefetch
// behind a branch as dead code, so on x86 the instruction is written out.
inline void Prefetch(const void* p) {
#if defined(__x86_64__) || defined(__i386__)
  asm volatile("prefetcht0 %0" : : "m"(*static_cast<const char*>(p)));
#else
  __builtin_prefetch(p);
#endif
}

// The candidate Gaussians of `indices` (canonical values) and their textures.
void Subset(const Asset& asset, const std::vector<uint32_t>& indices, Gaussians* g, std::optional<TexturePool>* t) {
  const Gaussians& a = asset.gaussians;
  const size_t sh = 3 * static_cast<size_t>(a.sh_coeffs());
  g->sh_degree = a.sh_degree;
  g->time_windows.clear();
  if (a.has_time_windows()) g->time_windows.assign(2, 0.0f);  // present, so that Resize sizes it
  g->Resize(indices.size());
  for (size_t k = 0; k < indices.size(); ++k) {
    const size_t i = indices[k];
    std::copy_n(a.positions.data() + 3 * i, 3, g->positions.data() + 3 * k);
    std::copy_n(a.rotations.data() + 4 * i, 4, g->rotations.data() + 4 * k);
    std::copy_n(a.log_scales.data() + 3 * i, 3, g->log_scales.data() + 3 * k);
    g->opacity_logits[k] = a.opacity_logits[i];
    std::copy_n(a.sh.data() + sh * i, sh, g->sh.data() + sh * k);
    if (a.has_time_windows()) std::copy_n(a.time_windows.data() + 2 * i, 2, g->time_windows.data() + 2 * k);
  }
  t->reset();
  if (!asset.textures) return;
  const TexturePool& p = *asset.textures;
  TexturePool& s = t->emplace();
  for (uint32_t i : indices) {
    s.heights.push_back(p.heights[i]);
    s.widths.push_back(p.widths[i]);
    s.axis_u.push_back(p.axis_u[i]);
    s.axis_v.push_back(p.axis_v[i]);
    s.texels.insert(s.texels.end(), p.texels.begin() + p.offsets[i] * 4, p.texels.begin() + p.offsets[i + 1] * 4);
  }
  s.RebuildOffsets();
}

}  // namespace

IncrementalProbes::IncrementalProbes(CpuProbeRenderer* deformer, std::vector<Camera> cameras)
    : deformer_(deformer),
      cameras_(std::move(cameras)),
      probes_(cameras_.size()) {
  for (const Camera& c : cameras_) times_.push_back(c.time);
}

IncrementalProbes::~IncrementalProbes() = default;

StatusOr<std::vector<Image>> IncrementalProbes::Render(const Asset& asset, const CandidateMap& map,
                                                       std::shared_ptr<const Pending>* pending) {
  const size_t n = asset.gaussians.size();
  if (map.base_of.size() != n) {
    return MakeError(StatusCode::kInvalidArgument, "probe render: the candidate map has ", map.base_of.size(),
                     " entries for ", n, " Gaussians");
  }
  uint32_t previous = kNoBase;
  for (size_t j = 0; j < n; ++j) {
    const uint32_t b = map.base_of[j];
    if (b == kNoBase) continue;
    if (b >= base_size_ || (previous != kNoBase && b <= previous)) {
      return MakeError(StatusCode::kInvalidArgument, "probe render: candidate Gaussian ", j, " maps to base Gaussian ",
                       b, ", not ascending within the base's ", base_size_);
    }
    previous = b;
  }
  size_t listed = 0;
  for (size_t k = 0; k < map.changed.size(); ++k) {
    if (map.changed[k] >= n || (k > 0 && map.changed[k] <= map.changed[k - 1])) {
      return MakeError(StatusCode::kInvalidArgument, "probe render: changed Gaussian ", map.changed[k],
                       " out of order or range");
    }
  }
  for (size_t j = 0; j < n; ++j) {
    if (map.base_of[j] != kNoBase) continue;
    while (listed < map.changed.size() && map.changed[listed] < j) ++listed;
    if (listed == map.changed.size() || map.changed[listed] != j) {
      return MakeError(StatusCode::kInvalidArgument, "probe render: candidate Gaussian ", j,
                       " is new to the base but not listed as changed");
    }
  }
  auto out = std::make_shared<Pending>();
  out->generation = generation_;
  out->size = n;
  out->base_of = map.base_of;
  out->settings.request = train::RenderRequestFor(asset);
  out->settings.sh_degree = asset.gaussians.sh_degree;
  out->settings.textured = out->settings.request.use_textures && asset.textures.has_value();
  if (out->settings.request.apply_deformation && asset.deformation) out->settings.field = asset.deformation;
  // RenderImportance needs every pixel composited (its weights sum over all of them). A
  // candidate that changes every Gaussian (requantised positions, another field) has
  // every pixel of the base to mark: a full render gives the same images for less.
  const bool all_changed = full_when_all_changed_ && n > 0 && map.changed.size() == n;
  const bool full = weigh_ || settings_ == nullptr || !settings_->Same(out->settings) || all_changed;
  if (full) {
    out->changed.resize(n);
    for (size_t j = 0; j < n; ++j) out->changed[j] = static_cast<uint32_t>(j);
  } else {
    out->changed = map.changed;
  }
  StatusOr<std::vector<Image>> images = std::vector<Image>{};
  try {
    images = RenderProbes(asset, map, full, out.get());
  } catch (const std::bad_alloc&) {
    return MakeError(StatusCode::kLimitExceeded, "fit: probe render: out of memory");
  } catch (const std::exception& e) {
    return MakeError(StatusCode::kInternal, "fit: probe render: ", e.what());
  }
  if (images.ok() && pending != nullptr) *pending = std::move(out);
  return images;
}

namespace {

// The tile rectangle of each Gaussian of a render state, from its tile lists (the lists
// cover exactly the rectangle BuildRenderState computed).
template <typename Splat>
void RectsFromLists(const RenderOutput& o, int tiles_x, std::vector<Splat>* splats) {
  constexpr int16_t kNone = 0x7FFF;
  for (Splat& s : *splats) s.x0 = s.y0 = kNone, s.x1 = s.y1 = -1;
  const size_t tiles = o.state.tile_ranges.empty() ? 0 : o.state.tile_ranges.size() - 1;
  for (size_t t = 0; t < tiles; ++t) {
    const int16_t tx = static_cast<int16_t>(t % size_t(tiles_x)), ty = static_cast<int16_t>(t / size_t(tiles_x));
    for (uint64_t e = o.state.tile_ranges[t]; e < o.state.tile_ranges[t + 1]; ++e) {
      Splat& s = (*splats)[size_t(o.state.tile_gaussians[e])];
      s.x0 = std::min(s.x0, tx), s.y0 = std::min(s.y0, ty);
      s.x1 = std::max<int16_t>(s.x1, tx + 1), s.y1 = std::max<int16_t>(s.y1, ty + 1);
    }
  }
  for (Splat& s : *splats)
    if (s.x1 < 0) s.x0 = s.y0 = s.x1 = s.y1 = 0;
}

template <typename Splat>
void MarkTiles(const Splat& s, int tiles_x, std::vector<uint8_t>* affected) {
  for (int ty = s.y0; ty < s.y1; ++ty)
    for (int tx = s.x0; tx < s.x1; ++tx) (*affected)[size_t(ty) * size_t(tiles_x) + size_t(tx)] = 1;
}

}  // namespace

// What the render of one candidate shares between its probes and tiles.
struct IncrementalProbes::Job {
  const CandidateMap& map;
  bool full;
  const std::vector<uint32_t>& changed;
  std::vector<uint32_t> cand_of;          // [base] candidate index; kNoBase: removed
  std::vector<uint8_t> stale;             // [base] removed or changed
  std::vector<uint32_t> fresh_of;         // [candidate] index into `changed`; kNoBase: unchanged
  const TexturePool* textures = nullptr;  // of `changed`, null for an untextured render
  const Texels* fresh_texels = nullptr;
  detail::Vec3<float> background{};
  bool weigh = false;  // sum each splat's blending weights (PendingProbe::importance)
};

detail::SplatParams<float> IncrementalProbes::Params(const Splat& sp, const Texels* texels, size_t i) {
  detail::SplatParams<float> q;
  q.mean2d = {{sp.mean2d[0], sp.mean2d[1]}};
  q.conic = {{sp.conic[0], sp.conic[1], sp.conic[2]}};
  q.opacity = sp.opacity;
  q.color = {{sp.color[0], sp.color[1], sp.color[2]}};
  q.frame = texels != nullptr ? &sp.frame : nullptr;
  q.texels = texels != nullptr ? texels->values.data() + texels->offset[i] * 4 : nullptr;
  q.tex_h = texels != nullptr ? texels->height[i] : 0;
  q.tex_w = texels != nullptr ? texels->width[i] : 0;
  q.constant = q.tex_h == 1 && q.tex_w == 1 ? &texels->constant[i] : nullptr;
  return q;
}

StatusOr<std::vector<Image>> IncrementalProbes::RenderProbes(const Asset& asset, const CandidateMap& map, bool full,
                                                             Pending* out) {
  const size_t n = asset.gaussians.size();
  const Settings& settings = out->settings;
  Job job{map, full, out->changed, {}, {}, {}};
  job.weigh = weigh_;
  const size_t nc = job.changed.size();
  // Base Gaussians that are removed or changed (their old splats leave the tile lists).
  job.cand_of.assign(base_size_, kNoBase);
  job.stale.assign(base_size_, 1);
  for (size_t j = 0; j < n; ++j) {
    const uint32_t b = map.base_of[j];
    if (b == kNoBase) continue;
    job.cand_of[b] = static_cast<uint32_t>(j);
    job.stale[b] = full ? 1 : 0;
  }
  job.fresh_of.assign(n, kNoBase);
  for (size_t k = 0; k < nc; ++k) {
    job.fresh_of[job.changed[k]] = static_cast<uint32_t>(k);
    if (map.base_of[job.changed[k]] != kNoBase) job.stale[map.base_of[job.changed[k]]] = 1;
  }
  Gaussians subset;
  std::optional<TexturePool> subset_textures;
  Subset(asset, job.changed, &subset, &subset_textures);
  if (settings.textured) {
    job.textures = &*subset_textures;
    Texels& t = out->changed_texels;
    t.height = job.textures->heights;
    t.width = job.textures->widths;
    t.offset = job.textures->offsets;
    t.values = job.textures->texels;
    t.constant.resize(nc);
    for (size_t k = 0; k < nc; ++k) {
      if (t.height[k] == 1 && t.width[k] == 1) {
        t.constant[k] = detail::MakeConstantTexel(t.values.data() + t.offset[k] * 4);
      }
    }
    job.fresh_texels = &t;
  }
  std::vector<Gaussians> deformed;
  if (settings.field && nc > 0) {
    ATEX_RETURN_IF_ERROR(deformer_->DeformCached(*settings.field, subset, times_, n, &deformed));
  }
  RenderSettings render_settings;
  render_settings.background = settings.request.background;
  render_settings.near_plane = settings.request.near_plane;
  render_settings.active_sh_degree = settings.request.active_sh_degree;
  ATEX_RETURN_IF_ERROR(render_internal::ValidateSettings(render_settings));
  job.background = {{settings.request.background[0], settings.request.background[1], settings.request.background[2]}};
  out->probes.resize(cameras_.size());
  for (const Camera& camera : cameras_) ATEX_RETURN_IF_ERROR(render_internal::ValidateCamera(camera));
  // One probe per thread: a candidate's probes are independent, and most candidates
  // change too little of each probe to keep several threads busy within it.
  const int64_t probes = static_cast<int64_t>(cameras_.size());
  std::vector<Status> failed(cameras_.size(), Status::Ok());
  std::vector<uint64_t> drawn(cameras_.size(), 0);
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 1)
#endif
  for (int64_t pi = 0; pi < probes; ++pi) {
    const size_t p = size_t(pi);
    try {
      const auto cam = detail::MakeCameraModel<float>(cameras_[p], render_settings.near_plane);
      const Gaussians& shown = deformed.empty() ? subset : deformed[p];
      RenderOutput o;
      if (nc > 0) {
        failed[p] = render_internal::ValidateGaussians(shown);
        if (failed[p].ok() && job.textures != nullptr) failed[p] = ValidateTexturePool(*job.textures, nc);
        if (failed[p].ok()) {
          failed[p] = render_internal::BuildRenderState(
              cam, shown, job.textures, std::min(settings.request.active_sh_degree, shown.sh_degree), &o);
        }
      }
      if (failed[p].ok()) drawn[p] = RenderProbe(job, cam, o, probes_[p], &out->probes[p]);
    } catch (const std::bad_alloc&) {
      failed[p] = MakeError(StatusCode::kLimitExceeded, "fit: probe render: out of memory");
    } catch (const std::exception& e) {
      failed[p] = MakeError(StatusCode::kInternal, "fit: probe render: ", e.what());
    }
  }
  std::vector<Image> images;
  for (size_t p = 0; p < cameras_.size(); ++p) {
    ATEX_RETURN_IF_ERROR(failed[p]);
    const uint64_t tiles = uint64_t(out->probes[p].tiles_total);
    tiles_drawn_ += drawn[p];
    tiles_kept_ += tiles - drawn[p];
    deformer_->CountTiles(drawn[p], tiles - drawn[p]);
    Image image;
    image.width = cameras_[p].width;
    image.height = cameras_[p].height;
    image.channels = 3;
    image.pixels = out->probes[p].color;
    images.push_back(std::move(image));
  }
  projected_ += nc * cameras_.size();
  return images;
}

uint64_t IncrementalProbes::RenderProbe(const Job& job, const detail::CameraModel<float>& cam, const RenderOutput& o,
                                        const ProbeBase& base, PendingProbe* pp) const {
  const size_t nc = job.changed.size();
  const int tiles = cam.tiles_x * cam.tiles_y;
  pp->tiles_total = tiles;
  pp->fresh.assign(nc, Splat{});
  pp->importance.assign(job.weigh ? job.map.base_of.size() : 0, 0.0f);
  for (size_t k = 0; k < nc; ++k) {
    Splat& s = pp->fresh[k];
    s.depth = o.depth[k];
    for (int c = 0; c < 2; ++c) s.mean2d[c] = o.mean2d[2 * k + c];
    for (int c = 0; c < 3; ++c) s.conic[c] = o.state.conic[3 * k + c], s.color[c] = o.state.color[3 * k + c];
    s.opacity = o.state.opacity[k];
    if (job.textures != nullptr) s.frame = o.state.frames[k];
    s.reach = ReachOf(cam, Params(s, job.fresh_texels, k));
  }
  if (nc > 0) RectsFromLists(o, cam.tiles_x, &pp->fresh);
  std::vector<uint8_t> affected(size_t(tiles), job.full ? 1 : 0);
  if (!job.full) {
    for (size_t b = 0; b < base_size_; ++b)
      if (job.stale[b] && base.splats[b].listed()) MarkTiles(base.splats[b], cam.tiles_x, &affected);
    for (const Splat& s : pp->fresh)
      if (s.listed()) MarkTiles(s, cam.tiles_x, &affected);
  }
  pp->tiles.clear();
  for (int t = 0; t < tiles; ++t)
    if (affected[size_t(t)]) pp->tiles.push_back(t);
  const int64_t count = static_cast<int64_t>(pp->tiles.size());
  pp->list_ranges.assign(pp->tiles.size() + 1, 0);
  for (int64_t i = 0; i < count; ++i) {
    const size_t t = size_t(pp->tiles[size_t(i)]);
    uint64_t entries = 0;
    if (!job.full) {
      for (uint64_t e = base.tile_ranges[t]; e < base.tile_ranges[t + 1]; ++e) entries += !job.stale[base.tile_list[e]];
    }
    if (nc > 0) entries += o.state.tile_ranges[t + 1] - o.state.tile_ranges[t];
    pp->list_ranges[size_t(i) + 1] = pp->list_ranges[size_t(i)] + entries;
  }
  pp->lists.assign(pp->list_ranges.back(), 0);
  pp->list_depths.assign(pp->list_ranges.back(), 0.0f);
  const size_t pixels = size_t(cam.width) * size_t(cam.height);
  pp->color = job.full ? std::vector<float>(pixels * 3, 0.0f) : base.color;
  pp->stops.assign(pixels, kNeverStopped);
  if (!job.full) {
    // In candidate indices; a pixel whose stop splat is removed is composited again.
    for (size_t q = 0; q < pixels; ++q) {
      const StopKey& b = base.stops[q];
      if (b.index != kNoBase) pp->stops[q] = StopKey{b.depth, job.cand_of[b.index]};
    }
  }
  uint64_t drawn = 0;
  for (int64_t i = 0; i < count; ++i) drawn += RenderTile(job, cam, o, base, size_t(i), pp);
  return drawn;
}

bool IncrementalProbes::RenderTile(const Job& job, const detail::CameraModel<float>& cam, const RenderOutput& o,
                                   const ProbeBase& base, size_t i, PendingProbe* pp) const {
  const int t = pp->tiles[i];
  const bool fresh_any = !job.changed.empty();
  uint64_t a = 0, a_end = 0, f = 0, f_end = 0;
  if (!job.full) a = base.tile_ranges[size_t(t)], a_end = base.tile_ranges[size_t(t) + 1];
  if (fresh_any) f = o.state.tile_ranges[size_t(t)], f_end = o.state.tile_ranges[size_t(t) + 1];
  uint8_t mask[kTilePixels];
  std::fill_n(mask, kTilePixels, uint8_t(job.full ? 1 : 0));
  bool dirty = job.full;
  if (!job.full) {
    // Pixels where a removed or changed splat may have contributed, or a changed one may now.
    const Texels* base_texels = job.textures != nullptr ? &texels_ : nullptr;
    for (uint64_t e = a; e < a_end; ++e) {
      const uint32_t b = base.tile_list[e];
      if (!job.stale[b]) continue;
      const Splat& sp = base.splats[b];
      dirty |= MarkPixels(cam, t, Params(sp, base_texels, b), sp.reach, sp.depth, b, base.stops.data(), mask);
    }
    for (uint64_t e = f; e < f_end; ++e) {
      const size_t k = size_t(o.state.tile_gaussians[e]);
      const uint32_t b = job.map.base_of[job.changed[k]];  // kNoBase: before any stop
      const float depth = b == kNoBase ? -__builtin_inff() : pp->fresh[k].depth;
      dirty |= MarkPixels(cam, t, Params(pp->fresh[k], job.fresh_texels, k), pp->fresh[k].reach, depth,
                          b == kNoBase ? 0 : b, base.stops.data(), mask);
    }
  }
  // The merged list: the base's surviving splats and the fresh ones, both already in
  // (depth, index) order.
  uint32_t* dst = pp->lists.data() + pp->list_ranges[i];
  float* dst_depth = pp->list_depths.data() + pp->list_ranges[i];
  while (true) {
    while (a < a_end && job.stale[base.tile_list[a]]) ++a;
    if (a == a_end && f == f_end) break;
    const uint32_t from_base = a < a_end ? job.cand_of[base.tile_list[a]] : kNoBase;
    const uint32_t from_fresh = f < f_end ? job.changed[size_t(o.state.tile_gaussians[f])] : kNoBase;
    const float da = from_base != kNoBase ? base.tile_depth[a] : 0.0f;
    const float df = from_fresh != kNoBase ? pp->fresh[size_t(o.state.tile_gaussians[f])].depth : 0.0f;
    bool take_base = from_fresh == kNoBase;
    if (from_base != kNoBase && from_fresh != kNoBase) take_base = da < df || (da == df && from_base < from_fresh);
    *dst++ = take_base ? from_base : from_fresh;
    *dst_depth++ = take_base ? da : df;
    (take_base ? a : f)++;
  }
  if (!dirty) return false;  // no pixel of the tile changes
  // The marked pixels' box: a splat whose reach misses it fails the skip test at each of
  // them, where the reference loop passes it by, so it is left out of the compositing.
  const int tx0 = (t % cam.tiles_x) * detail::kTileSize, ty0 = (t / cam.tiles_x) * detail::kTileSize;
  PixelBox marked{cam.width, -1, cam.height, -1};
  for (int q = 0; q < kTilePixels; ++q) {
    if (!mask[q]) continue;
    const int x = tx0 + q % detail::kTileSize, y = ty0 + q / detail::kTileSize;
    marked = {std::min(marked.x0, x), std::max(marked.x1, x + 1), std::min(marked.y0, y), std::max(marked.y1, y + 1)};
  }
  thread_local std::vector<detail::SplatParams<float>> splats;
  thread_local std::vector<float> depths;
  thread_local std::vector<SplatReach> reach;
  thread_local std::vector<uint32_t> indices;
  thread_local std::vector<detail::ConstantTexel<float>> constants;
  splats.clear();
  depths.clear();
  reach.clear();
  indices.clear();
  constants.clear();
  const Texels* base_texels = job.textures != nullptr ? &texels_ : nullptr;
  const uint64_t e_begin = pp->list_ranges[i], e_end = pp->list_ranges[i + 1];
  // The list is in depth order, the base's splats in index order: fetch a few entries
  // ahead, so that the memory reads overlap instead of waiting one after another.
  constexpr uint64_t kAhead = 24;
  const auto prefetch = [&](uint64_t e) {
    const uint32_t j = pp->lists[e];
    if (job.fresh_of[j] != kNoBase) return;
    const uint32_t b = job.map.base_of[j];
    const char* at = reinterpret_cast<const char*>(&base.splats[b]);
    Prefetch(at);
    Prefetch(at + sizeof(Splat) - 1);
    if (base_texels != nullptr) {
      Prefetch(&base_texels->offset[b]);
      Prefetch(&base_texels->height[b]);
      Prefetch(&base_texels->width[b]);
      Prefetch(&base_texels->constant[b]);
    }
  };
  for (uint64_t e = e_begin; e < std::min(e_end, e_begin + kAhead); ++e) prefetch(e);
  for (uint64_t e = e_begin; e < e_end; ++e) {
    if (e + kAhead < e_end) prefetch(e + kAhead);
    const uint32_t j = pp->lists[e];
    const uint32_t k = job.fresh_of[j];
    const uint32_t b = k != kNoBase ? kNoBase : job.map.base_of[j];
    const Splat& sp = k != kNoBase ? pp->fresh[k] : base.splats[b];
    const PixelBox& box = sp.reach.box;
    if (!(box.x0 < marked.x1 && marked.x0 < box.x1 && box.y0 < marked.y1 && marked.y0 < box.y1)) continue;
    splats.push_back(k != kNoBase ? Params(sp, job.fresh_texels, k) : Params(sp, base_texels, b));
    // A copy of the 1×1 texture's activations next to the others: the compositing reads
    // them at every pixel the splat reaches (the same values).
    constants.push_back(splats.back().constant != nullptr ? *splats.back().constant : detail::ConstantTexel<float>{});
    depths.push_back(sp.depth);
    reach.push_back(sp.reach);
    indices.push_back(j);
  }
  for (size_t q = 0; q < splats.size(); ++q) {
    if (splats[q].constant != nullptr) splats[q].constant = &constants[q];
  }
  const TileList list{splats.data(), reach.data(), depths.data(), indices.data(), static_cast<int>(splats.size())};
  thread_local std::vector<float> weights;
  weights.assign(job.weigh ? splats.size() : 0, 0.0f);
  CompositePixels(cam, t, list, job.background, mask, pp->color.data(), pp->stops.data(),
                  job.weigh ? weights.data() : nullptr);
  // Tiles come in ascending order, so each Gaussian's weights are summed tile by tile as
  // RasterizeForward sums its entries (a splat left out above has weight 0 here).
  for (size_t k = 0; k < weights.size(); ++k) pp->importance[indices[k]] += weights[k];
  return true;
}

}  // namespace atex::fit::internal
