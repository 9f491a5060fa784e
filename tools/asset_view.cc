#include "asset_view.h"

#include <string>
#include <vector>

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

StatusOr<std::unique_ptr<Dataset>> OpenDatasetArgs(const std::string& path, const DatasetArgs& args) {
  DatasetOptions options;
  ATEX_ASSIGN_OR_RETURN(options.kind, ParseDatasetKind(args.kind));
  options.max_timesteps = args.timesteps;
  options.downscale = args.downscale;
  options.timestep_stride = args.timestep_stride;
  options.train_cameras = args.train_cameras;
  options.test_cameras = args.test_cameras;
  return OpenDataset(path, options);
}

StatusOr<View> PickView(const Dataset& data, const std::string& spec) {
  const size_t colon = spec.find(':');
  const std::string split = spec.substr(0, colon);
  const std::vector<View>* views = split == "test" ? &data.test_views() : split == "train" ? &data.train_views() : nullptr;
  if (views == nullptr || colon == std::string::npos) {
    return MakeError(StatusCode::kInvalidArgument, "--view '", spec, "' is not test:N or train:N");
  }
  size_t index = 0;
  try {
    index = std::stoul(spec.substr(colon + 1));
  } catch (...) {
    return MakeError(StatusCode::kInvalidArgument, "--view '", spec, "': bad index");
  }
  if (index >= views->size()) {
    return MakeError(StatusCode::kNotFound, "--view ", spec, ": the ", split, " split has ", views->size(), " views");
  }
  return (*views)[index];
}

}  // namespace atex::cli
