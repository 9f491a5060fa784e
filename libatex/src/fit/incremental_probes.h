// Incremental probe renders for the fitter's CPU measurements. Not part of the public API.
//
// A fit measures dozens of candidates that each differ from the current state in a few
// Gaussians: a texture move changes the texels of a few dozen, a prune move removes a
// tenth of them (the least important, mostly invisible). Rendering every candidate
// from scratch (CpuProbeRenderer) projects and sorts every Gaussian for every probe,
// which was most of a CPU fit's time once the deformations were cached.
//
// IncrementalProbes keeps a base: per probe, each Gaussian's projected splat (what the
// compositing reads), the tile lists in compositing order and the image. A candidate
// names, for each of its Gaussians, the base Gaussian it is (CandidateMap::base_of; a
// prune drops some) and which of them changed. The render then projects only the changed
// Gaussians (the reference rasteriser's own stages, render_internal::BuildRenderState,
// on that subset), and composites again (render_internal::RasterizeTile) only the tiles
// that a removed or changed Gaussian touched before or touches now; every other tile is
// the base's. The merged tile lists keep the reference order (depth, then index), so a
// candidate's images equal a full render of the asset it stands for: the base with the
// removals and the changed Gaussians' values (bitwise, up to the deformation's summation
// order that cpu_probes.h describes).
//
// A candidate's render can be committed: it becomes the base, without rendering again.
// When the candidate's deformation field, SH degree or render settings differ from the
// base's, every Gaussian counts as changed (a full render).
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "atex/camera.h"
#include "atex/detail/composite.h"
#include "atex/detail/texture.h"
#include "atex/image.h"
#include "atex/model.h"
#include "atex/render.h"
#include "atex/status.h"
#include "atex/train/backend.h"
#include "cpu_probes.h"
#include "tile_composite.h"

namespace atex::fit::internal {

inline constexpr uint32_t kNoBase = 0xFFFFFFFFu;

// A candidate relative to the base.
struct CandidateMap {
  // [candidate Gaussians] the base Gaussian each one is, strictly ascending over the
  // entries that are not kNoBase; kNoBase: a Gaussian the base lacks (it must be in `changed`).
  std::vector<uint32_t> base_of;
  // Candidate indices, strictly ascending, whose parameters differ from their base
  // Gaussian's. The others are rendered with the base's values whatever `asset` holds.
  std::vector<uint32_t> changed;
};

// For each Gaussian of `kept` (ascending input indices), its position in `base_kept`
// (ascending), or kNoBase when `base_kept` lacks it.
std::vector<uint32_t> BaseIndices(const std::vector<uint32_t>& base_kept, const std::vector<uint32_t>& kept);

// The Gaussians j of `after` whose rendered parameters (position, rotation, scale,
// opacity, SH, texture size, axes and texels) differ bitwise from those of Gaussian
// base_of[j] of `before`, or whose base_of[j] is kNoBase; all of them when the SH degree
// or the presence of textures differs. Ascending.
std::vector<uint32_t> ChangedGaussians(const Asset& before, const Asset& after, const std::vector<uint32_t>& base_of);

class IncrementalProbes {
 public:
  // Renders from `cameras` (each with its time) through `deformer`'s cache of residuals.
  IncrementalProbes(CpuProbeRenderer* deformer, std::vector<Camera> cameras);
  ~IncrementalProbes();

  // What a render leaves for Commit (the changed splats, the tiles composited again and
  // the images). Valid for the base it was rendered against only.
  struct Pending;

  // Renders the candidate `asset` described by `map` (see the file comment) as
  // train::Backend::Render would with train::RenderRequestFor(asset). With the base
  // empty (at construction), every Gaussian must be kNoBase. kInvalidArgument for a map
  // that does not fit the asset or the base; the renderer's errors otherwise. When
  // `pending` is not null it receives what Commit needs.
  StatusOr<std::vector<Image>> Render(const Asset& asset, const CandidateMap& map,
                                      std::shared_ptr<const Pending>* pending = nullptr);
  // Renders `asset` in full as the new base (every Gaussian new) and returns, per
  // Gaussian, its blending weight summed over the probes: render.h's importance as
  // fit::EnsureImportance and CpuProbeRenderer::Importance measure it (the same sums in the
  // same order, so the same values). `images` (optional) receives the renders.
  StatusOr<std::vector<float>> RenderImportance(const Asset& asset, std::vector<Image>* images = nullptr);
  // Commits so far: a base is identified by this count.
  uint64_t generation() const { return generation_; }

  // The rendered candidate becomes the base. An error when another commit
  // came between its render and this one (kInvalidArgument).
  Status Commit(const Pending& pending);

  size_t base_size() const { return base_size_; }
  // Whether a candidate that changes every one of its Gaussians is rendered as a full
  // render (the default): the same images as the incremental path, which would mark every
  // pixel of every splat of the base first. Tests switch it off to compare the two.
  void set_full_when_all_changed(bool on) { full_when_all_changed_ = on; }
  // Gaussians projected (per probe) and tiles composited / kept since construction.
  uint64_t projected() const { return projected_; }
  uint64_t tiles_drawn() const { return tiles_drawn_; }
  uint64_t tiles_kept() const { return tiles_kept_; }

 private:
  // What compositing reads of one Gaussian in one probe, and its tile rectangle.
  struct Splat {
    float depth = 0;
    float mean2d[2] = {0, 0};
    float conic[3] = {0, 0, 0};
    float opacity = 0;
    float color[3] = {0, 0, 0};
    detail::TextureFrame<float> frame{};
    int16_t x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // tiles [x0, x1) × [y0, y1); empty: in no tile list
    SplatReach reach;                         // its skip bound and pixel box (tile_composite.h)
    bool listed() const { return x1 > x0 && y1 > y0; }
  };
  struct ProbeBase {
    std::vector<Splat> splats;       // [base Gaussians]
    std::vector<uint64_t> tile_ranges;  // [tiles + 1]
    std::vector<uint32_t> tile_list;    // base indices in compositing order
    std::vector<float> tile_depth;      // [tile_list entries] each entry's splat depth (the
                                        // merge reads them in list order, not by index)
    std::vector<float> color;           // [pixels][3]
    std::vector<StopKey> stops;         // [pixels] (base indices)
  };
  // Texels of the base's Gaussians (probe-independent).
  struct Texels {
    std::vector<uint8_t> height, width;
    std::vector<uint64_t> offset;  // [N + 1] in texels
    std::vector<float> values;     // [texels][4]
    std::vector<detail::ConstantTexel<float>> constant;  // [N] the activations of the 1×1 ones
  };
  struct Settings;
  struct Job;
  void CommitUnchecked(const Pending& pending);
  struct PendingProbe;
  StatusOr<std::vector<Image>> RenderProbes(const Asset& asset, const CandidateMap& map, bool full, Pending* out);
  // One probe of a candidate: its fresh splats (from `o`, the render state of the changed
  // Gaussians), the tiles they and the stale base splats touch, and those tiles' pixels.
  // Returns the tiles composited.
  uint64_t RenderProbe(const Job& job, const detail::CameraModel<float>& cam, const RenderOutput& o,
                       const ProbeBase& base, PendingProbe* pp) const;
  // The merged list of the i-th affected tile and its changed pixels; whether any changed.
  bool RenderTile(const Job& job, const detail::CameraModel<float>& cam, const RenderOutput& o,
                  const ProbeBase& base, size_t i, PendingProbe* pp) const;
  // The compositing view of a splat; `texels` null for an untextured render.
  static detail::SplatParams<float> Params(const Splat& sp, const Texels* texels, size_t i);

  CpuProbeRenderer* deformer_;
  std::vector<Camera> cameras_;
  std::vector<double> times_;
  size_t base_size_ = 0;
  uint64_t generation_ = 0;  // commits so far
  std::unique_ptr<Settings> settings_;  // of the base; null while empty
  std::vector<ProbeBase> probes_;
  Texels texels_;
  uint64_t projected_ = 0, tiles_drawn_ = 0, tiles_kept_ = 0;
  bool weigh_ = false;  // RenderImportance's render: sum the blending weights
  bool full_when_all_changed_ = true;
};

}  // namespace atex::fit::internal
