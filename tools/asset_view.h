// Shared by `atex eval` and `atex render`: load an asset into a backend and pick
// cameras from a dataset.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "atex/dataset.h"
#include "atex/model.h"
#include "atex/status.h"
#include "atex/train/backend.h"

namespace atex::cli {

// The dataset options of the commands that open --data (atex/dataset.h DatasetOptions);
// cli::AddDatasetOptions registers them.
struct DatasetArgs {
  std::string kind = "auto";
  int timesteps = 0, downscale = 1, timestep_stride = 1, train_cameras = 0;
  std::vector<int> test_cameras;  // empty: the dataset's own split
};

// Reads the asset and loads it into the backend; fills a render request that uses
// everything the asset has (deformation, textures, full SH, its background).
Status LoadAssetIntoBackend(const std::string& path, train::Backend* backend, Asset* asset,
                            train::RenderRequest* request);

// Opens --data with the dataset options of the commands (cli::AddDatasetOptions). RGBA
// frames are composited on `background` when given (an asset's, so that ground truth
// matches its renders), else on the dataset kind's default (DefaultBackground).
StatusOr<std::unique_ptr<Dataset>> OpenDatasetArgs(const std::string& path, const DatasetArgs& args,
                                                   const std::array<float, 3>* background = nullptr);

// "test:3" / "train:12": the index-th view of that split (errors name the spec).
StatusOr<View> PickView(const Dataset& data, const std::string& spec);

}  // namespace atex::cli
