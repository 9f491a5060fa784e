// Shared by `atex eval` and `atex render`: load an asset into a backend and pick
// cameras from a dataset.
#pragma once

#include <string>

#include "atex/model.h"
#include "atex/status.h"
#include "atex/train/backend.h"

namespace atex::cli {

// Reads the asset and loads it into the backend; fills a render request that uses
// everything the asset has (deformation, textures, full SH, its background).
Status LoadAssetIntoBackend(const std::string& path, train::Backend* backend, Asset* asset,
                            train::RenderRequest* request);

}  // namespace atex::cli
