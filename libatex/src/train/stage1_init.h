// Stage 1's starting point: the initial Gaussians (atex/init.h, by stage1.init_method), the
// deformation field over their bounding box, and the metadata a fresh run begins with.
#pragma once

#include <string>

#include "atex/dataset.h"
#include "atex/model.h"
#include "atex/status.h"
#include "atex/train/backend.h"
#include "atex/train/config.h"

namespace atex::train {

struct Stage1Start {
  ModelState state;    // initial Gaussians and deformation field, zero Adam moments
  Metadata metadata;   // bounds, time range, background, world up axis
  std::string event;   // the training log's "initialised N Gaussians (...)" line
};

// Errors of the initialisation (no training views, a stereo run that fuses no point, an
// unreadable point-cloud file) and kInvalidArgument for an init_hull_fraction outside [0, 1].
StatusOr<Stage1Start> InitialStage1State(const Dataset& data, const TrainConfig& config);

// Appends the fast-object seeds of stage1.fast_objects (atex/transient_hull.h) to the model
// that `backend` holds, with zero Adam moments; the Gaussians already there keep their
// parameters and moments and get no window (k = 0). Called once, where the fine stage
// starts. Returns the training log's line. A dataset of one timestep, or without transient
// foreground, leaves the model as it is (nothing can be fast). Errors: TransientSeeds' (a
// dataset without masks or timesteps), kInvalidArgument for a model with textures.
StatusOr<std::string> AddFastObjectSeeds(const Dataset& data, const TrainConfig& config, Backend& backend);

}  // namespace atex::train
