#include "asset_view.h"

#include <string>
#include <vector>

#include "atex/container.h"
#include "atex/train/trainer.h"
#include "cli_parse.h"

namespace atex::cli {

Status LoadAssetIntoBackend(const std::string& path, train::Backend* backend, Asset* asset,
                            train::RenderRequest* request) {
  ATEX_ASSIGN_OR_RETURN(*asset, ReadAssetFile(path));
  ATEX_RETURN_IF_ERROR(backend->Load(train::RenderStateFromAsset(*asset)).WithContext(path));
  *request = train::RenderRequestFor(*asset);
  return Status::Ok();
}

StatusOr<std::unique_ptr<Dataset>> OpenDatasetArgs(const std::string& path, const DatasetArgs& args,
                                                   const std::array<float, 3>* background) {
  DatasetOptions options;
  if (background != nullptr) options.background = *background;
  ATEX_ASSIGN_OR_RETURN(options.kind, ParseDatasetKind(args.kind));
  options.max_timesteps = args.timesteps;
  options.downscale = args.downscale;
  options.timestep_stride = args.timestep_stride;
  options.train_cameras = args.train_cameras;
  options.test_cameras = args.test_cameras;
  return OpenDataset(path, options);
}

StatusOr<View> PickView(const Dataset& data, const std::string& spec) {
  ATEX_ASSIGN_OR_RETURN(const ViewSpec parsed, ParseViewSpec(spec, "--view"));
  const std::vector<View>& views = parsed.split == "test" ? data.test_views() : data.train_views();
  if (parsed.index >= views.size()) {
    return MakeError(StatusCode::kNotFound, "--view ", spec, ": the ", parsed.split, " split has ", views.size(),
                     " views");
  }
  return views[parsed.index];
}

}  // namespace atex::cli
