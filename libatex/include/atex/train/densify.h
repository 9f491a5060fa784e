// Densification and pruning decisions (3DGS / 4DGaussians), made on the host from
// the statistics a backend accumulated, and expressed as a GaussianEdit.
#pragma once

#include <cstdint>

#include "atex/camera.h"
#include "atex/model.h"
#include "atex/status.h"
#include "atex/train/backend.h"
#include "atex/train/config.h"

namespace atex::train {

struct DensifyReport {
  size_t before = 0, cloned = 0, split = 0, pruned = 0, after = 0;
};

// Clone small Gaussians whose mean projected-centre gradient reaches the threshold,
// split large ones into two (positions drawn from the Gaussian, scales / 1.6), prune
// those below the opacity threshold and, when `prune_screen_size` is set, those whose
// screen radius or world size exceeds the config's limits.
// When config.min_observing_cameras > 0, `observing_cameras` ([N], CountObservingCameras)
// must be given, and Gaussians seen by fewer cameras are pruned too (with their clones
// and split children).
// New Gaussians get zero Adam moments; parents of a split are removed. `seed` makes the
// split positions deterministic. `extent` is the scene extent (3DGS's cameras_extent).
StatusOr<GaussianEdit> PlanDensification(const Gaussians& canonical, const DensifyStats& stats,
                                         const DensifyConfig& config, double extent, bool prune_screen_size,
                                         uint64_t seed, DensifyReport* report,
                                         const std::vector<uint16_t>* observing_cameras = nullptr);

// For each Gaussian, how many of `cameras` see its canonical centre: in front of the
// near plane (camera z > near_plane) and projecting inside the image. A point seen by
// one or two cameras cannot be placed in depth by the others, so a Gaussian there can
// sit anywhere along those rays: a floater for every other viewpoint. Saturates at 65535.
std::vector<uint16_t> CountObservingCameras(const Gaussians& canonical, const std::vector<Camera>& cameras,
                                            float near_plane);

// Pruning only (used after an opacity reset or for a fixed Gaussian count).
GaussianEdit PlanPrune(const Gaussians& canonical, const std::vector<uint8_t>& remove /*[N] 1 = drop*/);

}  // namespace atex::train
