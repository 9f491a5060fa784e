// Pieces of a trained asset that the training loop assembles at its start and end.
#pragma once

#include <array>
#include <cstddef>
#include <utility>

#include "atex/model.h"
#include "atex/train/backend.h"
#include "atex/train/config.h"

namespace atex::train {

// Per-axis minimum and maximum of the Gaussians' positions; {+1e30, -1e30} per axis when
// there are none.
std::pair<std::array<float, 3>, std::array<float, 3>> PositionBounds(const Gaussians& gaussians);

// What `atex fit` reads from a trained asset: the importance of the last epoch and the texture
// evidence since the last growth (zeros where the model has no textures or the statistics do not
// match `count` Gaussians).
GaussianStats FitterStats(const TrainingStats& stats, size_t count, bool textured, const GrowthAblations& ablations);

}  // namespace atex::train
