// Nerfstudio / instant-ngp scenes (atex/dataset.h, kNerfstudio): a transforms.json
// (atex/dataset_formats.h) given as the file or as the folder holding it; paths in it are
// relative to its folder (".png" added to a file_path without extension, as Blender's).
// Poses: OpenGL camera-to-world, converted as D-NeRF's (BlenderCameraToWorldToOpenCv).
// Time: per-frame `time`, else `timestep` / the largest timestep, else 0 (static); times
// outside [0, 1] are rescaled over the file's range (with a warning).
// Split (the first rule that applies):
//   1. DatasetOptions::test_cameras: frames whose camera_id is listed are the test split;
//   2. transforms_test.json beside the file: its frames are the test split;
//   3. nerfstudio's test_filenames (else val_filenames): frames listed there are the test
//      split, those of train_filenames (else all others) the training split;
//   4. frames sorted by file_path: ranks 0, 8, 16, ... are the test split (LLFF rule).
// Masks: a frame's mask_path (first channel > 0.5 keeps the pixel), else the alpha of RGBA
// frames. ply_file_path: the dataset's point cloud (the initialisation's by default).
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <set>

#include "atex/dataset_formats.h"
#include "atex/file_io.h"
#include "data/dataset_loaders.h"

namespace atex::data_detail {
namespace {

namespace fs = std::filesystem;

constexpr uint64_t kMaxTransformsBytes = uint64_t{1} << 30;

StatusOr<TransformsFile> ReadTransformsFile(const fs::path& file) {
  ATEX_ASSIGN_OR_RETURN(const std::vector<uint8_t> bytes, ReadFileBytes(file.string(), kMaxTransformsBytes));
  return ParseTransformsJson(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()),
                             file.string());
}

// A path as written in the file, normalised for comparing split lists with file_path.
std::string SplitKey(const std::string& path) {
  std::string s = fs::path(path).lexically_normal().generic_string();
  if (fs::path(s).extension().empty()) s += ".png";
  return s;
}

class NerfstudioDataset final : public Dataset {
 public:
  NerfstudioDataset(const fs::path& file, const DatasetOptions& options)
      : Dataset(DatasetNameFromPath(file.parent_path().empty() ? file.string() : file.parent_path().string()),
                DatasetKind::kNerfstudio, options),
        file_(file),
        root_(file.parent_path()) {}

  Status Load(const DatasetOptions& options) {
    ATEX_ASSIGN_OR_RETURN(TransformsFile main, ReadTransformsFile(file_));
    if (main.frames.empty()) return MakeError(StatusCode::kNotFound, file_.string(), ": no frames");
    // Every frame with its split: 0 train, 1 test, 2 dropped.
    std::vector<std::pair<TransformsFrame, int>> frames;
    std::sort(main.frames.begin(), main.frames.end(),
              [](const TransformsFrame& a, const TransformsFrame& b) { return a.file_path < b.file_path; });
    const fs::path test_file = root_ / "transforms_test.json";
    std::error_code ec;
    if (!options.test_cameras.empty()) {
      const std::set<int> test(options.test_cameras.begin(), options.test_cameras.end());
      std::set<int> present;
      for (const TransformsFrame& f : main.frames) {
        if (f.camera_id < 0) {
          return MakeError(StatusCode::kInvalidArgument, file_.string(), ": frames[", f.index,
                           "] has no camera_id, so test cameras cannot be chosen");
        }
        present.insert(f.camera_id);
        frames.emplace_back(f, test.count(f.camera_id) ? 1 : 0);
      }
      for (int id : test) {
        if (!present.count(id))
          return MakeError(StatusCode::kNotFound, file_.string(), ": no frame of test camera ", id);
      }
    } else if (fs::is_regular_file(test_file, ec) && file_.filename() != "transforms_test.json") {
      ATEX_ASSIGN_OR_RETURN(TransformsFile test, ReadTransformsFile(test_file));
      std::sort(test.frames.begin(), test.frames.end(),
                [](const TransformsFrame& a, const TransformsFrame& b) { return a.file_path < b.file_path; });
      for (const TransformsFrame& f : main.frames) frames.emplace_back(f, 0);
      for (const TransformsFrame& f : test.frames) frames.emplace_back(f, 1);
      split_rule_ = "transforms_test.json";
    } else if (!main.test_files.empty() || !main.val_files.empty()) {
      std::set<std::string> test, train;
      for (const auto& p : main.test_files.empty() ? main.val_files : main.test_files) test.insert(SplitKey(p));
      for (const auto& p : main.train_files) train.insert(SplitKey(p));
      for (const TransformsFrame& f : main.frames) {
        const std::string key = SplitKey(f.file_path);
        frames.emplace_back(f, test.count(key) ? 1 : (train.empty() || train.count(key)) ? 0 : 2);
      }
      split_rule_ = main.test_files.empty() ? "val_filenames" : "test_filenames";
    } else {
      for (size_t i = 0; i < main.frames.size(); ++i) frames.emplace_back(main.frames[i], i % 8 == 0 ? 1 : 0);
      split_rule_ = "every 8th frame";
    }
    ATEX_RETURN_IF_ERROR(MakeViews(frames));
    if (!main.ply_file_path.empty()) {
      const fs::path ply = (root_ / main.ply_file_path).lexically_normal();
      if (fs::is_regular_file(ply, ec)) {
        point_cloud_ = ply.string();
      } else {
        warnings_.push_back(StrCat("nerfstudio: ply_file_path ", ply.string(), " does not exist"));
      }
    }
    if (test_.empty()) warnings_.push_back(StrCat("nerfstudio: the test split (", split_rule_, ") is empty"));
    FinishTimeRange(train_, test_, &time_min_, &time_max_);
    return Status::Ok();
  }

 protected:
  StatusOr<Image> ReadViewImage(const View& view) const override { return ReadImage(view.image); }
  StatusOr<Image> ReadViewMask(const View& view) const override {
    ATEX_ASSIGN_OR_RETURN(const Image raw, ReadImage(view.mask));
    const bool alpha = view.mask == view.image;
    if (alpha && raw.channels != 4 && raw.channels != 2) {
      return MakeError(StatusCode::kNotFound, view.mask, ": frame has no alpha channel, so no mask");
    }
    Image mask(raw.width, raw.height, 1);
    const int channel = alpha ? raw.channels - 1 : 0;
    for (size_t p = 0; p < mask.pixels.size(); ++p) mask.pixels[p] = raw.pixels[p * raw.channels + channel];
    return mask;
  }

 private:
  // Times of the frames: `time`, else timestep / the largest, else 0; all frames alike.
  StatusOr<std::vector<double>> FrameTimes(const std::vector<std::pair<TransformsFrame, int>>& frames) {
    const bool timed = frames[0].first.time.has_value(), stepped = frames[0].first.timestep.has_value();
    int64_t last_step = 0;
    for (const auto& [f, split] : frames) {
      if (f.time.has_value() != timed || (!timed && f.timestep.has_value() != stepped)) {
        return MakeError(StatusCode::kCorrupt, file_.string(), ": frames[", f.index, "] (", f.file_path,
                         ") ", timed ? "has no 'time'" : stepped ? "has no 'timestep'" : "has a time",
                         " unlike frames[", frames[0].first.index, "]: every frame needs one or none has one");
      }
      if (f.timestep) last_step = std::max(last_step, *f.timestep);
    }
    std::vector<double> times;
    double lo = INFINITY, hi = -INFINITY;
    for (const auto& [f, split] : frames) {
      const double t = timed ? *f.time : stepped && last_step > 0 ? double(*f.timestep) / double(last_step) : 0.0;
      times.push_back(t);
      lo = std::min(lo, t);
      hi = std::max(hi, t);
    }
    if (lo < 0 || hi > 1) {
      for (double& t : times) t = hi > lo ? (t - lo) / (hi - lo) : 0.0;
      warnings_.push_back(StrCat("nerfstudio: frame times span [", lo, ", ", hi, "]; rescaled to [0, 1]"));
    }
    return times;
  }

  Status MakeViews(const std::vector<std::pair<TransformsFrame, int>>& frames) {
    ATEX_ASSIGN_OR_RETURN(const std::vector<double> times, FrameTimes(frames));
    const bool multi_camera =
        std::all_of(frames.begin(), frames.end(), [](const auto& f) { return f.first.camera_id >= 0; });
    std::map<double, int> time_rank;
    for (double t : times) time_rank.emplace(t, 0);
    int rank = 0;
    for (auto& [t, r] : time_rank) r = rank++;
    std::set<double> train_times;
    bool alpha_checked = false, alpha = false;
    for (size_t i = 0; i < frames.size(); ++i) {
      const auto& [f, split] = frames[i];
      if (split == 2) continue;
      const std::string at = StrCat(file_.string(), ": frames[", f.index, "]");
      fs::path image = (root_ / f.file_path).lexically_normal();
      if (!image.has_extension()) image += ".png";
      std::error_code ec;
      if (!fs::is_regular_file(image, ec)) {
        return MakeError(StatusCode::kNotFound, at, ".file_path: no image file ", image.string());
      }
      int width = f.width, height = f.height;
      if (width == 0 || height == 0) {
        StatusOr<ImageInfo> info = ReadImageInfo(image.string());
        if (!info.ok()) return info.status().WithContext(at);
        if (width == 0) width = info->width;
        if (height == 0) height = info->height;
      }
      if (!alpha_checked) {
        StatusOr<ImageInfo> info = ReadImageInfo(image.string());
        if (!info.ok()) return info.status().WithContext(at);
        alpha = info->channels == 4 || info->channels == 2;
        alpha_checked = true;
      }
      View view;
      view.camera.width = width;
      view.camera.height = height;
      view.camera.fx = f.fx > 0 ? f.fx : 0.5 * width / std::tan(0.5 * f.angle_x);
      view.camera.fy = f.fy > 0 ? f.fy : f.angle_y > 0 ? 0.5 * height / std::tan(0.5 * f.angle_y) : view.camera.fx;
      view.camera.cx = f.cx.value_or(0.5 * width);
      view.camera.cy = f.cy.value_or(0.5 * height);
      StatusOr<std::array<double, 16>> w2c = BlenderCameraToWorldToOpenCv(f.camera_to_world);
      if (!w2c.ok()) return w2c.status().WithContext(at + ".transform_matrix");
      view.camera.world_to_camera = *w2c;
      view.camera.time = times[i];
      view.camera.name = f.file_path;
      view.camera = ScaleCamera(view.camera, downscale_);
      if (view.camera.width < 1 || view.camera.height < 1) {
        return MakeError(StatusCode::kInvalidArgument, file_.string(), ": downscale ", downscale_, " leaves no pixels");
      }
      view.camera_id = multi_camera ? f.camera_id : static_cast<int>(i);
      view.timestep = multi_camera ? time_rank[times[i]] : -1;
      view.image = image.string();
      if (!f.mask_path.empty()) {
        const fs::path mask = (root_ / f.mask_path).lexically_normal();
        if (!fs::is_regular_file(mask, ec))
          return MakeError(StatusCode::kNotFound, at, ".mask_path: no file ", mask.string());
        view.mask = mask.string();
        has_masks_ = true;
      } else if (alpha) {
        view.mask = view.image;
        has_masks_ = true;
      }
      if (split == 0) train_times.insert(times[i]);
      (split == 0 ? train_ : test_).push_back(std::move(view));
    }
    if (train_.empty()) return MakeError(StatusCode::kNotFound, file_.string(), ": no training frame");
    timestep_count_ = static_cast<int>(train_times.size());
    return Status::Ok();
  }

  fs::path file_, root_;
  std::string split_rule_ = "test_cameras";
};

fs::path NerfstudioFile(const std::string& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) return fs::path(path) / "transforms.json";
  return fs::path(path);
}

}  // namespace

StatusOr<std::unique_ptr<Dataset>> OpenNerfstudio(const std::string& path, const DatasetOptions& options) {
  auto dataset = std::make_unique<NerfstudioDataset>(NerfstudioFile(path), options);
  ATEX_RETURN_IF_ERROR(dataset->Load(options));
  return std::unique_ptr<Dataset>(std::move(dataset));
}

}  // namespace atex::data_detail
