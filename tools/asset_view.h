// Shared by `atex eval` and `atex render`: load an asset into a backend and pick
// cameras from a dataset.
#pragma once

#include <memory>
#include <string>

#include "atex/dataset.h"
#include "atex/model.h"
#include "atex/status.h"
#include "atex/train/backend.h"

namespace atex::cli {

// Reads the asset and loads it into the backend; fills a render request that uses
// everything the asset has (deformation, textures, full SH, its background).
Status LoadAssetIntoBackend(const std::string& path, train::Backend* backend, Asset* asset,
                            train::RenderRequest* request);

// Opens --data with the common dataset options of the commands (--dataset-kind,
// --timesteps, --downscale, --timestep-stride, --train-cameras).
StatusOr<std::unique_ptr<Dataset>> OpenDatasetArgs(const std::string& path, const std::string& kind, int timesteps,
                                                   int downscale, int timestep_stride = 1, int train_cameras = 0);

// "test:3" / "train:12": the index-th view of that split (errors name the spec).
StatusOr<View> PickView(const Dataset& data, const std::string& spec);

}  // namespace atex::cli
