// Probe renders on the CPU for the fitter's many measurements of nearly equal assets
// (ProbeRenderer without a GPU). Not part of the public API.
//
// A fit measures dozens of candidate assets that differ from each other in a few
// streams: a prune move removes Gaussians, a texture move changes texels, an encoding
// move requantises one stream. The expensive part of a probe render of a dynamic asset
// is the deformation (HexPlane samples and the MLP, per Gaussian and probe time), and
// the deformation of a Gaussian depends on its canonical position only (docs/conventions.md
// §3: deformed = canonical + residual(position, time)). So the residuals are kept per
// exact position (bit pattern) and probe, and a measurement deforms only the Gaussians
// whose decoded position it has not seen with the same field.
//
// The renders then take the reference rasteriser's stages (render/render_internal.h):
// the projection and tile lists of every Gaussian (BuildRenderState), and the
// compositing (RasterizeTile) of each 16×16 tile only when the tile's splats changed:
// a tile's key hashes, in depth order, what the compositing reads of each of its splats
// (centre, conic, opacity, colour, texture frame and texels); its pixels are kept for the
// last few keys. A texture move changes a few dozen Gaussians, so most tiles come back
// from the cache. (A 64-bit hash: two different tile contents share a key with
// probability ~2^-64 per comparison.)
//
// Equal to the CPU backend's renders up to the MLP's summation order: the residuals of
// a Gaussian computed in a different block of Gaussians may differ in the last bits
// (Eigen's products per block), ~1e-7 relative (cpu_probes_test.cc states the bound).
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <unordered_map>
#include <vector>

#include "atex/camera.h"
#include "atex/image.h"
#include "atex/model.h"
#include "atex/render.h"
#include "atex/status.h"
#include "atex/train/backend.h"

namespace atex::fit::internal {

// Bitwise equality of two deformation fields (configuration and every value).
bool SameField(const DeformationField& a, const DeformationField& b);

class IncrementalProbes;

class CpuProbeRenderer {
 public:
  CpuProbeRenderer();
  ~CpuProbeRenderer();

  // Renders `asset` from `cameras` as train::Backend::Render would with `request`
  // (deformation at each camera's time, textures, background, SH degree).
  StatusOr<std::vector<Image>> Render(const Asset& asset, const std::vector<Camera>& cameras,
                                      const train::RenderRequest& request);

  // Per Gaussian of `asset`, the blending weight accumulated over the renders from
  // `cameras` (render.h's importance), as EnsureImportance measures it; the deformations
  // it computes stay cached for the renders that follow. With the request of
  // train::RenderRequestFor(asset), through Incremental(cameras) (the same values), whose
  // base it leaves at `asset` (ImportanceBase).
  StatusOr<std::vector<float>> Importance(const Asset& asset, const std::vector<Camera>& cameras,
                                          const train::RenderRequest& request);

  // The incremental renderer of `cameras` (incremental_probes.h), made on first use and
  // again when the cameras change; it deforms through this renderer's cache.
  IncrementalProbes* Incremental(const std::vector<Camera>& cameras);
  // The asset Importance last rendered, while the incremental renderer's base is still
  // that render (null otherwise): a plan of that asset starts from it.
  const Asset* ImportanceBase() const;

  // The Gaussians of `canonical` deformed to each time of `times` (out[t]), through the
  // cache of residuals (IncrementalProbes deforms only the Gaussians a candidate changed).
  // `asset_gaussians` sizes the cache's eviction (the Gaussians of the whole asset).
  Status DeformCached(const DeformationField& field, const Gaussians& canonical, const std::vector<double>& times,
                      size_t asset_gaussians, std::vector<Gaussians>* out);
  // Tiles composited and kept by IncrementalProbes, added to the counters below.
  void CountTiles(uint64_t drawn, uint64_t reused) {
    tiles_drawn_ += drawn;
    tiles_reused_ += reused;
  }

  // Gaussians deformed (per probe set) and reused since construction.
  uint64_t deformed() const { return deformed_; }
  uint64_t reused() const { return reused_; }
  // Tiles composited and taken from the cache since construction.
  uint64_t tiles_drawn() const { return tiles_drawn_; }
  uint64_t tiles_reused() const { return tiles_reused_; }

 private:
  struct PositionKey {
    uint32_t bits[3];
    bool operator==(const PositionKey& o) const {
      return bits[0] == o.bits[0] && bits[1] == o.bits[1] && bits[2] == o.bits[2];
    }
  };
  struct PositionHash {
    size_t operator()(const PositionKey& k) const;
  };

  // The deformed Gaussians of `canonical` at every time of `times`.
  Status Deform(const DeformationField& field, const Gaussians& canonical, const std::vector<double>& times,
                size_t asset_gaussians, std::vector<Gaussians>* out);
  // Forgets every entry unless the field, the times and the SH degree are the cached ones.
  void ResetUnlessSame(const DeformationField& field, const std::vector<double>& times, int sh_degree);
  // Drops the entries no render of the last few used, once the cache holds many more
  // entries than the asset has Gaussians.
  void Evict(size_t gaussians);

  // The render settings of `request` and the Gaussians deformed to each camera's time.
  struct Prepared {
    RenderSettings settings;
    const TexturePool* textures = nullptr;
    std::vector<Gaussians> deformed;  // [camera], empty for a static render
    const Gaussians& shown(const Asset& asset, size_t k) const {
      return deformed.empty() ? asset.gaussians : deformed[k];
    }
  };
  StatusOr<Prepared> Prepare(const Asset& asset, const std::vector<Camera>& cameras,
                             const train::RenderRequest& request);
  // One probe's image from `g` (already deformed), composited tile by tile through the cache.
  StatusOr<Image> RenderProbe(size_t probe, const Camera& camera, const Gaussians& g, const TexturePool* textures,
                              const RenderSettings& settings);

  // Pixels of one tile for one key.
  struct TileVersion {
    uint64_t key = 0;
    uint64_t used = 0;          // the render that last used it
    std::vector<float> color;   // [tile pixels][3]
  };
  static constexpr size_t kTileVersions = 4;
  std::vector<Camera> cameras_;                            // the probes the tile cache belongs to
  std::vector<std::vector<std::vector<TileVersion>>> tiles_;  // [probe][tile][version]
  uint64_t tiles_drawn_ = 0, tiles_reused_ = 0;

  std::optional<DeformationField> field_;
  std::vector<double> times_;
  int sh_degree_ = -1;
  int stride_ = 0;  // floats per (entry, time): deformed position 3, residuals of rotation 4,
                    // log-scale 3, opacity 1, SH 3K
  std::unordered_map<PositionKey, uint32_t, PositionHash> slot_of_;
  std::vector<float> values_;       // [slots][times][stride_]
  std::vector<uint64_t> last_used_; // [slots] the render that last used the entry
  uint64_t renders_ = 0;
  uint64_t deformed_ = 0, reused_ = 0;

  std::vector<Camera> incremental_cameras_;
  std::unique_ptr<IncrementalProbes> incremental_;
  std::optional<Asset> importance_asset_;
  uint64_t importance_generation_ = 0;  // the incremental base it was rendered as
};

}  // namespace atex::fit::internal
