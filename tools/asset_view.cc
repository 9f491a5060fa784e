#include "asset_view.h"

#include "atex/container.h"
#include "atex/train/trainer.h"

namespace atex::cli {

Status LoadAssetIntoBackend(const std::string& path, train::Backend* backend, Asset* asset,
                            train::RenderRequest* request) {
  ATEX_ASSIGN_OR_RETURN(*asset, ReadAssetFile(path));
  ATEX_RETURN_IF_ERROR(backend->Load(train::StateFromAsset(*asset)).WithContext(path));
  *request = train::RenderRequestFor(*asset);
  return Status::Ok();
}

StatusOr<std::unique_ptr<Dataset>> OpenDatasetArgs(const std::string& path, const std::string& kind, int timesteps,
                                                   int downscale, int timestep_stride, int train_cameras) {
  DatasetOptions options;
  ATEX_ASSIGN_OR_RETURN(options.kind, ParseDatasetKind(kind));
  options.max_timesteps = timesteps;
  options.downscale = downscale;
  options.timestep_stride = timestep_stride;
  options.train_cameras = train_cameras;
  return OpenDataset(path, options);
}

}  // namespace atex::cli
