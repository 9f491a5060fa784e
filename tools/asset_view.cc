#include "asset_view.h"

#include "atex/container.h"
#include "atex/train/trainer.h"

namespace atex::cli {

Status LoadAssetIntoBackend(const std::string& path, train::Backend* backend, Asset* asset,
                            train::RenderRequest* request) {
  ATEX_ASSIGN_OR_RETURN(*asset, ReadAssetFile(path));
  ATEX_RETURN_IF_ERROR(backend->Load(train::StateFromAsset(*asset)).WithContext(path));
  request->active_sh_degree = asset->gaussians.sh_degree;
  request->apply_deformation = asset->deformation.has_value();
  request->use_textures = asset->textures.has_value();
  request->background = asset->metadata.background;
  return Status::Ok();
}

}  // namespace atex::cli
