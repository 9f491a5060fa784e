// The private state of IncrementalProbes (incremental_probes.h) that its two source
// files share: the base's settings and what a render leaves for Commit. Not part of the
// public API.
#pragma once

#include <optional>
#include <vector>

#include "incremental_probes.h"

namespace atex::fit::internal {

// The base's render settings: a candidate with others is rendered in full.
struct IncrementalProbes::Settings {
  train::RenderRequest request;
  int sh_degree = 0;
  bool textured = false;
  std::optional<DeformationField> field;

  bool Same(const Settings& o) const {
    const train::RenderRequest &a = request, &b = o.request;
    return a.active_sh_degree == b.active_sh_degree && a.apply_deformation == b.apply_deformation &&
           a.use_textures == b.use_textures && a.background == b.background && a.near_plane == b.near_plane &&
           sh_degree == o.sh_degree && textured == o.textured && field.has_value() == o.field.has_value() &&
           (!field || SameField(*field, *o.field));
  }
};

struct IncrementalProbes::PendingProbe {
  int tiles_total = 0;                   // of the probe's image
  std::vector<Splat> fresh;              // [changed]
  std::vector<int> tiles;                // composited again, ascending
  std::vector<uint64_t> list_ranges;     // [tiles + 1] into lists
  std::vector<uint32_t> lists;           // candidate indices in compositing order
  std::vector<float> list_depths;        // [lists entries] their splats' depths
  std::vector<float> color;              // [pixels][3] the candidate's image
  std::vector<StopKey> stops;            // [pixels] (candidate indices)
  std::vector<float> importance;         // [candidate Gaussians] with RenderImportance
};

struct IncrementalProbes::Pending {
  uint64_t generation = 0;
  size_t size = 0;                 // candidate Gaussians
  std::vector<uint32_t> base_of;   // as CandidateMap
  std::vector<uint32_t> changed;   // the Gaussians projected again (all of them for a full render)
  Settings settings;
  Texels changed_texels;           // of `changed`, in that order
  std::vector<PendingProbe> probes;
};

}  // namespace atex::fit::internal
