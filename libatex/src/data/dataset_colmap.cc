// COLMAP scenes (static multi-view; atex/dataset.h, kColmap):
//   <root>/sparse/0/, <root>/sparse/ or <root>/ holding cameras, images and (optionally)
//   points3D, all .bin or all .txt (.bin preferred when both are there), and the frames
//   in <root>/images/<NAME>.
// Every image is its own camera (camera_id = its rank by name), time 0. Images sorted by
// name; those of rank 0, 8, 16, ... are the test split (the LLFF / Mip-NeRF 360 rule).
// points3D is the dataset's point cloud (Dataset::point_cloud(): the initialisation's by
// default).
#include <algorithm>
#include <filesystem>
#include <map>

#include "atex/dataset_formats.h"
#include "atex/file_io.h"
#include "data/dataset_loaders.h"

namespace atex::data_detail {
namespace {

namespace fs = std::filesystem;

constexpr uint64_t kMaxModelFileBytes = uint64_t{4} << 30;

struct ModelFiles {
  fs::path folder;
  std::string ext;  // ".bin" or ".txt"
};

std::optional<ModelFiles> FindModel(const fs::path& root) {
  std::error_code ec;
  for (const fs::path& folder : {root / "sparse" / "0", root / "sparse", root}) {
    for (const char* ext : {".bin", ".txt"}) {
      if (fs::is_regular_file(folder / (std::string("cameras") + ext), ec)) return ModelFiles{folder, ext};
    }
  }
  return std::nullopt;
}

StatusOr<std::vector<ColmapCamera>> ReadCameras(const std::string& path, bool binary) {
  ATEX_ASSIGN_OR_RETURN(const std::vector<uint8_t> bytes, ReadFileBytes(path, kMaxModelFileBytes));
  if (binary) return ParseColmapCamerasBinary(bytes.data(), bytes.size(), path);
  return ParseColmapCamerasText(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()), path);
}

StatusOr<std::vector<ColmapImage>> ReadImages(const std::string& path, bool binary) {
  ATEX_ASSIGN_OR_RETURN(const std::vector<uint8_t> bytes, ReadFileBytes(path, kMaxModelFileBytes));
  if (binary) return ParseColmapImagesBinary(bytes.data(), bytes.size(), path);
  return ParseColmapImagesText(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()), path);
}

class ColmapDataset final : public Dataset {
 public:
  ColmapDataset(const std::string& folder, const DatasetOptions& options)
      : Dataset(DatasetNameFromPath(folder), DatasetKind::kColmap, options), root_(folder) {}

  Status Load(const DatasetOptions& options) {
    if (!options.test_cameras.empty()) {
      return MakeError(StatusCode::kInvalidArgument, root_.string(),
                       ": test_cameras cannot be chosen for a COLMAP model (every image has its own camera; the "
                       "test split is every 8th image by name)");
    }
    const std::optional<ModelFiles> model = FindModel(root_);
    if (!model) {
      return MakeError(StatusCode::kNotFound, root_.string(),
                       ": no COLMAP model (cameras.bin or cameras.txt in sparse/0/, sparse/ or the folder)");
    }
    const bool binary = model->ext == ".bin";
    const std::string cameras_path = (model->folder / ("cameras" + model->ext)).string();
    const std::string images_path = (model->folder / ("images" + model->ext)).string();
    ATEX_ASSIGN_OR_RETURN(const std::vector<ColmapCamera> cameras, ReadCameras(cameras_path, binary));
    ATEX_ASSIGN_OR_RETURN(std::vector<ColmapImage> images, ReadImages(images_path, binary));
    if (images.empty()) return MakeError(StatusCode::kNotFound, images_path, ": the model has no images");
    const fs::path points = model->folder / ("points3D" + model->ext);
    std::error_code ec;
    if (fs::is_regular_file(points, ec)) {
      point_cloud_ = points.string();
    } else {
      warnings_.push_back(StrCat("colmap: no ", points.string(), ", so no initial point cloud from the model"));
    }
    const fs::path image_dir = root_ / "images";
    if (!fs::is_directory(image_dir, ec)) {
      return MakeError(StatusCode::kNotFound, root_.string(), ": no images/ folder beside the COLMAP model");
    }

    std::map<uint32_t, const ColmapCamera*> camera_by_id;
    for (const ColmapCamera& c : cameras) {
      if (!camera_by_id.emplace(c.id, &c).second) {
        return MakeError(StatusCode::kCorrupt, cameras_path, ": camera id ", c.id, " appears twice");
      }
    }
    std::sort(images.begin(), images.end(), [](const ColmapImage& a, const ColmapImage& b) { return a.name < b.name; });
    for (size_t i = 0; i < images.size(); ++i) {
      const ColmapImage& image = images[i];
      const std::string at = StrCat(images_path, ": image ", image.id, " ('", image.name, "')");
      if (i > 0 && images[i - 1].name == image.name) {
        return MakeError(StatusCode::kCorrupt, at, ": the name appears twice");
      }
      const auto found = camera_by_id.find(image.camera_id);
      const ColmapCamera* camera = found == camera_by_id.end() ? nullptr : found->second;
      if (camera == nullptr) {
        return MakeError(StatusCode::kCorrupt, at, ": camera ", image.camera_id, " is not in ", cameras_path);
      }
      ATEX_ASSIGN_OR_RETURN(const auto k, ColmapPinholeIntrinsics(*camera, cameras_path));
      ATEX_ASSIGN_OR_RETURN(const auto w2c, ColmapWorldToCamera(image, images_path));
      const fs::path file = (image_dir / image.name).lexically_normal();
      if (!fs::is_regular_file(file, ec))
        return MakeError(StatusCode::kNotFound, at, ": no image file ", file.string());
      View view;
      view.camera.width = static_cast<int>(camera->width);
      view.camera.height = static_cast<int>(camera->height);
      view.camera.fx = k[0];
      view.camera.fy = k[1];
      view.camera.cx = k[2];
      view.camera.cy = k[3];
      view.camera.world_to_camera = w2c;
      view.camera.time = 0;
      view.camera.name = image.name;
      view.camera = ScaleCamera(view.camera, downscale_);
      if (view.camera.width < 1 || view.camera.height < 1) {
        return MakeError(StatusCode::kInvalidArgument, root_.string(), ": downscale ", downscale_, " leaves no pixels");
      }
      view.camera_id = static_cast<int>(i);
      view.image = file.string();
      (i % 8 == 0 ? test_ : train_).push_back(std::move(view));
    }
    if (train_.empty()) {
      // One image: it trains; a test split cannot exist.
      train_.swap(test_);
      warnings_.push_back("colmap: one image only, so no test view");
    }
    timestep_count_ = 1;
    FinishTimeRange(train_, test_, &time_min_, &time_max_);
    return Status::Ok();
  }

 protected:
  StatusOr<Image> ReadViewImage(const View& view) const override { return ReadImage(view.image); }

 private:
  fs::path root_;
};

}  // namespace

bool LooksLikeColmap(const std::string& folder) { return FindModel(folder).has_value(); }

StatusOr<std::unique_ptr<Dataset>> OpenColmap(const std::string& folder, const DatasetOptions& options) {
  auto dataset = std::make_unique<ColmapDataset>(folder, options);
  ATEX_RETURN_IF_ERROR(dataset->Load(options));
  return std::unique_ptr<Dataset>(std::move(dataset));
}

}  // namespace atex::data_detail
