// CpuProbeRenderer (cpu_probes.h): probe renders with the deformation residuals of
// unchanged positions reused.
#include "cpu_probes.h"

#include "atex/train/trainer.h"
#include "incremental_probes.h"

#include <algorithm>
#include <cstring>
#include <exception>
#include <new>

#include "atex/deform.h"
#include "atex/render.h"
#include "render/parallel.h"
#include "render/render_internal.h"

namespace atex::fit::internal {
namespace {

bool SameValues(const std::vector<float>& a, const std::vector<float>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0);
}

bool SameLinear(const Linear& a, const Linear& b) {
  return a.in == b.in && a.out == b.out && SameValues(a.weight, b.weight) && SameValues(a.bias, b.bias);
}

}  // namespace

// The residuals are a function of the field's values.
bool SameField(const DeformationField& a, const DeformationField& b) {
  const DeformationConfig &ca = a.config, &cb = b.config;
  if (ca.grid.channels != cb.grid.channels || ca.grid.base_resolution != cb.grid.base_resolution ||
      ca.grid.multires != cb.grid.multires || ca.mlp_width != cb.mlp_width || ca.trunk_layers != cb.trunk_layers ||
      ca.heads != cb.heads || ca.sh_coeffs != cb.sh_coeffs ||
      std::memcmp(ca.aabb_lo.data(), cb.aabb_lo.data(), sizeof(ca.aabb_lo)) != 0 ||
      std::memcmp(ca.aabb_hi.data(), cb.aabb_hi.data(), sizeof(ca.aabb_hi)) != 0 ||
      std::memcmp(&ca.time_scale, &cb.time_scale, sizeof(float)) != 0 ||
      std::memcmp(&ca.time_offset, &cb.time_offset, sizeof(float)) != 0) {
    return false;
  }
  if (a.planes.size() != b.planes.size() || a.trunk.size() != b.trunk.size()) return false;
  for (size_t s = 0; s < a.planes.size(); ++s) {
    for (size_t p = 0; p < a.planes[s].size(); ++p) {
      if (!SameValues(a.planes[s][p], b.planes[s][p])) return false;
    }
  }
  for (size_t l = 0; l < a.trunk.size(); ++l) {
    if (!SameLinear(a.trunk[l], b.trunk[l])) return false;
  }
  for (size_t h = 0; h < a.heads.size(); ++h) {
    for (size_t k = 0; k < 2; ++k) {
      if (!SameLinear(a.heads[h][k], b.heads[h][k])) return false;
    }
  }
  return true;
}

namespace {

uint32_t Bits(float x) {
  uint32_t b;
  std::memcpy(&b, &x, sizeof b);
  return b;
}

// One step of a 64-bit hash over a sequence of words (splitmix64's finaliser on the
// running state): order matters, as it does in compositing.
uint64_t Mix(uint64_t h, uint64_t word) {
  h ^= word + 0x9E3779B97F4A7C15ull + (h << 6) + (h >> 2);
  h ^= h >> 30;
  h *= 0xBF58476D1CE4E5B9ull;
  h ^= h >> 27;
  h *= 0x94D049BB133111EBull;
  return h ^ (h >> 31);
}

uint64_t MixFloats(uint64_t h, const float* v, size_t count) {
  for (size_t k = 0; k < count; ++k) h = Mix(h, Bits(v[k]));
  return h;
}

// Everything compositing reads of one splat (detail::EvaluateSplat).
uint64_t SplatKey(const detail::SplatParams<float>& s) {
  uint64_t h = Mix(0, 1);
  h = MixFloats(h, s.mean2d.v, 2);
  h = MixFloats(h, s.conic.v, 3);
  h = Mix(h, Bits(s.opacity));
  h = MixFloats(h, s.color.v, 3);
  if (s.frame != nullptr) {
    const detail::TextureFrame<float>& f = *s.frame;
    h = MixFloats(h, f.axis_u.v, 3);
    h = MixFloats(h, f.axis_v.v, 3);
    h = MixFloats(h, f.normal.v, 3);
    const float rest[5] = {f.offset_u, f.offset_v, f.offset_n, f.inv_scale_u, f.inv_scale_v};
    h = MixFloats(h, rest, 5);
    h = Mix(Mix(h, uint64_t(s.tex_h)), uint64_t(s.tex_w));
    h = MixFloats(h, s.texels, size_t(s.tex_h) * size_t(s.tex_w) * 4);
  }
  return h;
}

bool SameCamera(const Camera& a, const Camera& b) {
  return a.width == b.width && a.height == b.height && a.fx == b.fx && a.fy == b.fy && a.cx == b.cx &&
         a.cy == b.cy && a.world_to_camera == b.world_to_camera && a.time == b.time;
}

}  // namespace

size_t CpuProbeRenderer::PositionHash::operator()(const PositionKey& k) const {
  uint64_t h = 0x9E3779B97F4A7C15ull;
  for (uint32_t b : k.bits) {
    h ^= b;
    h *= 0xBF58476D1CE4E5B9ull;
    h ^= h >> 31;
  }
  return static_cast<size_t>(h);
}

void CpuProbeRenderer::ResetUnlessSame(const DeformationField& field, const std::vector<double>& times,
                                       int sh_degree) {
  if (field_ && times_ == times && sh_degree_ == sh_degree && SameField(*field_, field)) return;
  field_ = field;
  times_ = times;
  sh_degree_ = sh_degree;
  stride_ = 3 + 4 + 3 + 1 + 3 * ShCoeffCount(sh_degree);
  slot_of_.clear();
  values_.clear();
  last_used_.clear();
}

void CpuProbeRenderer::Evict(size_t gaussians) {
  // A measurement's candidates share most positions with the current state; entries of
  // candidates that were not taken stop being used within a few renders.
  constexpr uint64_t kKeepRenders = 4;
  if (slot_of_.size() <= 3 * gaussians + 1024) return;
  const size_t per_slot = times_.size() * static_cast<size_t>(stride_);
  std::vector<float> kept_values;
  std::vector<uint64_t> kept_used;
  std::unordered_map<PositionKey, uint32_t, PositionHash> kept_slots;
  kept_slots.reserve(2 * gaussians);
  for (const auto& [key, slot] : slot_of_) {
    if (last_used_[slot] + kKeepRenders < renders_) continue;
    const uint32_t fresh = static_cast<uint32_t>(kept_used.size());
    kept_slots.emplace(key, fresh);
    kept_used.push_back(last_used_[slot]);
    kept_values.insert(kept_values.end(), values_.begin() + slot * per_slot, values_.begin() + (slot + 1) * per_slot);
  }
  slot_of_ = std::move(kept_slots);
  values_ = std::move(kept_values);
  last_used_ = std::move(kept_used);
}

Status CpuProbeRenderer::DeformCached(const DeformationField& field, const Gaussians& canonical,
                                      const std::vector<double>& times, size_t asset_gaussians,
                                      std::vector<Gaussians>* out) {
  ++renders_;
  return Deform(field, canonical, times, asset_gaussians, out);
}

Status CpuProbeRenderer::Deform(const DeformationField& field, const Gaussians& canonical,
                                const std::vector<double>& times, size_t asset_gaussians, std::vector<Gaussians>* out) {
  ResetUnlessSame(field, times, canonical.sh_degree);
  const size_t n = canonical.size(), probes = times.size(), stride = static_cast<size_t>(stride_);
  const size_t per_slot = probes * stride;
  std::vector<uint32_t> slot(n);
  std::vector<uint32_t> missing;  // Gaussians whose position is new (the first of equal ones)
  for (size_t i = 0; i < n; ++i) {
    const float* p = canonical.positions.data() + 3 * i;
    const PositionKey key{{Bits(p[0]), Bits(p[1]), Bits(p[2])}};
    const auto [it, inserted] = slot_of_.try_emplace(key, static_cast<uint32_t>(last_used_.size()));
    if (inserted) {
      missing.push_back(static_cast<uint32_t>(i));
      last_used_.push_back(0);
    }
    slot[i] = it->second;
    last_used_[it->second] = renders_;
  }
  deformed_ += missing.size() * probes;
  reused_ += (n - missing.size()) * probes;
  values_.resize(last_used_.size() * per_slot);
  if (!missing.empty()) {
    // Deform the new positions with every other attribute zero: the outputs are then
    // the residuals themselves (0 + r = r exactly) and the deformed positions.
    Gaussians fresh;
    fresh.sh_degree = canonical.sh_degree;
    fresh.Resize(missing.size());
    for (size_t j = 0; j < missing.size(); ++j) {
      std::copy_n(canonical.positions.data() + 3 * size_t(missing[j]), 3, fresh.positions.data() + 3 * j);
    }
    const size_t sh = 3 * static_cast<size_t>(canonical.sh_coeffs());
    Gaussians deformed;
    for (size_t t = 0; t < probes; ++t) {
      if (Status s = DeformForward(field, fresh, times[t], &deformed, nullptr); !s.ok()) {
        field_.reset();  // the new entries hold no residuals: forget them all
        return s;
      }
      for (size_t j = 0; j < missing.size(); ++j) {
        float* v = values_.data() + size_t(slot[missing[j]]) * per_slot + t * stride;
        std::copy_n(deformed.positions.data() + 3 * j, 3, v);
        std::copy_n(deformed.rotations.data() + 4 * j, 4, v + 3);
        std::copy_n(deformed.log_scales.data() + 3 * j, 3, v + 7);
        v[10] = deformed.opacity_logits[j];
        std::copy_n(deformed.sh.data() + sh * j, sh, v + 11);
      }
    }
  }
  out->assign(probes, canonical);
  const size_t sh = 3 * static_cast<size_t>(canonical.sh_coeffs());
  for (size_t t = 0; t < probes; ++t) {
    Gaussians& g = (*out)[t];
    for (size_t i = 0; i < n; ++i) {
      const float* v = values_.data() + size_t(slot[i]) * per_slot + t * stride;
      std::copy_n(v, 3, g.positions.data() + 3 * i);
      for (int k = 0; k < 4; ++k) g.rotations[4 * i + k] += v[3 + k];
      for (int k = 0; k < 3; ++k) g.log_scales[3 * i + k] += v[7 + k];
      g.opacity_logits[i] += v[10];
      for (size_t k = 0; k < sh; ++k) g.sh[sh * i + k] += v[11 + k];
      if (canonical.has_time_windows()) {  // as DeformForward does
        g.opacity_logits[i] -=
            TimeWindowPenalty(canonical.time_windows[2 * i], canonical.time_windows[2 * i + 1], times[t]);
      }
    }
    g.time_windows.clear();
  }
  Evict(std::max(n, asset_gaussians));
  return Status::Ok();
}

StatusOr<CpuProbeRenderer::Prepared> CpuProbeRenderer::Prepare(const Asset& asset, const std::vector<Camera>& cameras,
                                                               const train::RenderRequest& request) {
  ++renders_;
  Prepared in;
  in.settings.background = request.background;
  in.settings.near_plane = request.near_plane;
  in.settings.active_sh_degree = request.active_sh_degree;
  in.textures = request.use_textures && asset.textures ? &*asset.textures : nullptr;
  if (request.apply_deformation && asset.deformation.has_value()) {
    std::vector<double> times;
    for (const Camera& c : cameras) times.push_back(c.time);
    ATEX_RETURN_IF_ERROR(Deform(*asset.deformation, asset.gaussians, times, asset.gaussians.size(), &in.deformed));
  }
  return in;
}

StatusOr<std::vector<Image>> CpuProbeRenderer::Render(const Asset& asset, const std::vector<Camera>& cameras,
                                                      const train::RenderRequest& request) {
  ATEX_ASSIGN_OR_RETURN(Prepared in, Prepare(asset, cameras, request));
  bool same_cameras = cameras_.size() == cameras.size();
  for (size_t k = 0; same_cameras && k < cameras.size(); ++k) same_cameras = SameCamera(cameras_[k], cameras[k]);
  if (!same_cameras) {
    cameras_ = cameras;
    tiles_.assign(cameras.size(), {});
  }
  std::vector<Image> images;
  images.reserve(cameras.size());
  for (size_t k = 0; k < cameras.size(); ++k) {
    ATEX_ASSIGN_OR_RETURN(Image image, RenderProbe(k, cameras[k], in.shown(asset, k), in.textures, in.settings));
    images.push_back(std::move(image));
  }
  return images;
}

CpuProbeRenderer::CpuProbeRenderer() = default;
CpuProbeRenderer::~CpuProbeRenderer() = default;

IncrementalProbes* CpuProbeRenderer::Incremental(const std::vector<Camera>& cameras) {
  bool same = incremental_ != nullptr && incremental_cameras_.size() == cameras.size();
  for (size_t k = 0; same && k < cameras.size(); ++k) same = SameCamera(incremental_cameras_[k], cameras[k]);
  if (!same) {
    incremental_cameras_ = cameras;
    incremental_ = std::make_unique<IncrementalProbes>(this, cameras);
    importance_asset_.reset();
  }
  return incremental_.get();
}

const Asset* CpuProbeRenderer::ImportanceBase() const {
  const bool current = importance_asset_ && incremental_ && incremental_->generation() == importance_generation_;
  return current ? &*importance_asset_ : nullptr;
}

StatusOr<std::vector<float>> CpuProbeRenderer::Importance(const Asset& asset, const std::vector<Camera>& cameras,
                                                          const train::RenderRequest& request) {
  const train::RenderRequest own = train::RenderRequestFor(asset);
  if (request.active_sh_degree == own.active_sh_degree && request.apply_deformation == own.apply_deformation &&
      request.use_textures == own.use_textures && request.background == own.background &&
      request.near_plane == own.near_plane) {
    IncrementalProbes* incremental = Incremental(cameras);
    importance_asset_.reset();
    ATEX_ASSIGN_OR_RETURN(std::vector<float> importance, incremental->RenderImportance(asset));
    importance_asset_ = asset;
    importance_generation_ = incremental->generation();
    return importance;
  }
  ATEX_ASSIGN_OR_RETURN(Prepared in, Prepare(asset, cameras, request));
  std::vector<float> importance(asset.gaussians.size(), 0.0f);
  for (size_t k = 0; k < cameras.size(); ++k) {
    ATEX_ASSIGN_OR_RETURN(RenderOutput out,
                          RenderForward<float>(cameras[k], in.shown(asset, k), in.textures, in.settings));
    for (size_t i = 0; i < importance.size(); ++i) importance[i] += out.importance[i];
  }
  return importance;
}

StatusOr<Image> CpuProbeRenderer::RenderProbe(size_t probe, const Camera& camera, const Gaussians& g,
                                              const TexturePool* textures, const RenderSettings& settings) {
  ATEX_RETURN_IF_ERROR(render_internal::ValidateCamera(camera));
  ATEX_RETURN_IF_ERROR(render_internal::ValidateSettings(settings));
  ATEX_RETURN_IF_ERROR(render_internal::ValidateGaussians(g));
  if (textures != nullptr) ATEX_RETURN_IF_ERROR(ValidateTexturePool(*textures, g.size()));
  const auto cam = detail::MakeCameraModel<float>(camera, settings.near_plane);
  RenderOutput out;
  try {
    ATEX_RETURN_IF_ERROR(render_internal::BuildRenderState(cam, g, textures,
                                                           std::min(settings.active_sh_degree, g.sh_degree), &out));
    const size_t pixels = size_t(cam.width) * cam.height;
    out.color.assign(pixels * 3, 0.0f);
    out.alpha.assign(pixels, 0.0f);
    out.state.final_transmittance.assign(pixels, 1.0f);
    out.state.contributor_end.assign(pixels, 0);
    // What compositing reads of each visible splat, hashed once per Gaussian.
    const size_t n = g.size();
    std::vector<uint64_t> splat_key(n, 0);
    const int64_t count = static_cast<int64_t>(n);
#ifdef _OPENMP
#pragma omp parallel for schedule(static) if (count >= 4096)
#endif
    for (int64_t i = 0; i < count; ++i) {
      if (out.radius[i] > 0) splat_key[i] = SplatKey(render_internal::MakeSplatParams(out, textures, int32_t(i)));
    }
    const uint64_t seed = Mix(Mix(Mix(0, Bits(settings.background[0])), Bits(settings.background[1])),
                              Bits(settings.background[2]));
    const int tiles = cam.tiles_x * cam.tiles_y;
    auto& versions = tiles_[probe];
    versions.resize(size_t(tiles));
    const uint64_t longest = render_internal::LongestTile(out);
    const int threads = render_internal::MaxThreads();
    std::vector<detail::SplatParams<float>> scratch(size_t(threads) * longest);
    std::vector<float> scratch_skip(scratch.size());
    const detail::Vec3<float> background{{settings.background[0], settings.background[1], settings.background[2]}};
    uint64_t drawn = 0;
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : drawn)
#endif
    for (int t = 0; t < tiles; ++t) {
      uint64_t key = Mix(seed, uint64_t(t));
      for (uint64_t e = out.state.tile_ranges[t]; e < out.state.tile_ranges[t + 1]; ++e) {
        key = Mix(key, splat_key[out.state.tile_gaussians[e]]);
      }
      const int x0 = (t % cam.tiles_x) * detail::kTileSize, y0 = (t / cam.tiles_x) * detail::kTileSize;
      const int x1 = std::min(x0 + detail::kTileSize, cam.width), y1 = std::min(y0 + detail::kTileSize, cam.height);
      std::vector<TileVersion>& slot = versions[size_t(t)];
      auto hit = std::find_if(slot.begin(), slot.end(), [&](const TileVersion& v) { return v.key == key; });
      if (hit == slot.end()) {
        const size_t thread = size_t(render_internal::ThreadIndex());
        render_internal::RasterizeTile<float>(cam, textures, background, t, scratch.data() + thread * longest,
                                       scratch_skip.data() + thread * longest, nullptr, &out);
        ++drawn;
        if (slot.size() < kTileVersions) {
          slot.emplace_back();
          hit = slot.end() - 1;
        } else {
          hit = std::min_element(slot.begin(), slot.end(),
                                 [](const TileVersion& a, const TileVersion& b) { return a.used < b.used; });
        }
        hit->key = key;
        hit->color.clear();
        for (int y = y0; y < y1; ++y) {
          const float* row = out.color.data() + 3 * (size_t(y) * cam.width + x0);
          hit->color.insert(hit->color.end(), row, row + 3 * (x1 - x0));
        }
      } else {
        const float* src = hit->color.data();
        for (int y = y0; y < y1; ++y, src += 3 * (x1 - x0)) {
          std::copy_n(src, 3 * (x1 - x0), out.color.data() + 3 * (size_t(y) * cam.width + x0));
        }
      }
      hit->used = renders_;
    }
    tiles_drawn_ += drawn;
    tiles_reused_ += uint64_t(tiles) - drawn;
  } catch (const std::bad_alloc&) {
    return MakeError(StatusCode::kLimitExceeded, "fit: probe render: out of memory");
  } catch (const std::exception& e) {
    return MakeError(StatusCode::kInternal, "fit: probe render: ", e.what());
  }
  return RenderedImage(out);
}

}  // namespace atex::fit::internal
