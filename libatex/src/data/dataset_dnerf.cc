// D-NeRF / Blender synthetic scenes:
//   transforms_{train,val,test}.json: {camera_angle_x, frames: [{file_path, time,
//   transform_matrix (4x4 c2w, Blender axes)}]}; file_path is relative to the
//   folder, ".png" is appended when it has no extension.
// Intrinsics: fx = fy = W/2 / tan(camera_angle_x/2), principal point at the
// image centre (W/2, H/2), as 3DGS/4DGaussians use them. RGBA frames are
// composited on the background; their alpha (> 0.5) is the mask.
//
// And the tiny lego .npz (images (N,H,W,3) f32, poses (N,4,4) c2w, times (N,),
// focal): N = 81 = 50 train + 11 val + 20 test, in that order.
#include <cmath>
#include <filesystem>
#include <set>

#include "atex/npy.h"
#include "data/dataset_loaders.h"

namespace atex::data_detail {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct Frame {
  std::string path;
  double time = 0;
  std::array<double, 16> c2w{};
};

struct Split {
  double camera_angle_x = 0;
  std::vector<Frame> frames;
};

StatusOr<Split> ReadTransforms(const fs::path& root, const std::string& name, std::vector<std::string>* warnings) {
  const fs::path file = root / ("transforms_" + name + ".json");
  ATEX_ASSIGN_OR_RETURN(const json doc, ReadJsonFile(file.string()));
  const std::string where = file.string();
  if (!doc.is_object() || !doc.contains("camera_angle_x") || !doc["camera_angle_x"].is_number() ||
      !doc.contains("frames") || !doc["frames"].is_array()) {
    return MakeError(StatusCode::kCorrupt, where, ": needs 'camera_angle_x' (number) and 'frames' (array)");
  }
  Split split;
  split.camera_angle_x = doc["camera_angle_x"].get<double>();
  if (!(split.camera_angle_x > 0 && split.camera_angle_x < M_PI)) {
    return MakeError(StatusCode::kCorrupt, where, ": camera_angle_x ", split.camera_angle_x, " is not in (0, pi)");
  }
  int skipped = 0;
  std::string first_skipped;
  for (size_t i = 0; i < doc["frames"].size(); ++i) {
    const json& f = doc["frames"][i];
    const std::string at = StrCat(where, ": frame ", i);
    if (!f.is_object() || !f.contains("file_path") || !f["file_path"].is_string() ||
        !f.contains("transform_matrix")) {
      return MakeError(StatusCode::kCorrupt, at, ": needs 'file_path' and 'transform_matrix'");
    }
    Frame frame;
    if (f.contains("time")) {
      if (!f["time"].is_number() || !std::isfinite(f["time"].get<double>())) {
        return MakeError(StatusCode::kCorrupt, at, ": 'time' is not a finite number");
      }
      frame.time = f["time"].get<double>();
    }
    const json& m = f["transform_matrix"];
    if (!m.is_array() || m.size() != 4) return MakeError(StatusCode::kCorrupt, at, ": transform_matrix is not 4x4");
    for (int r = 0; r < 4; ++r) {
      if (!m[r].is_array() || m[r].size() != 4) {
        return MakeError(StatusCode::kCorrupt, at, ": transform_matrix row ", r, " is not 4 numbers");
      }
      for (int c = 0; c < 4; ++c) {
        if (!m[r][c].is_number()) return MakeError(StatusCode::kCorrupt, at, ": transform_matrix[", r, "][", c, "]");
        frame.c2w[r * 4 + c] = m[r][c].get<double>();
      }
    }
    fs::path image = root / fs::path(f["file_path"].get<std::string>()).lexically_normal();
    if (!image.has_extension()) image += ".png";
    if (!fs::exists(image)) {
      if (skipped++ == 0) first_skipped = image.string();
      continue;
    }
    frame.path = image.string();
    split.frames.push_back(std::move(frame));
  }
  if (skipped > 0) {
    warnings->push_back(StrCat("dnerf: ", name, " split: ", skipped, " of ", doc["frames"].size(),
                               " frames skipped, image files missing (first: ", first_skipped, ")"));
  }
  return split;
}

class DNerfDataset final : public Dataset {
 public:
  DNerfDataset(const std::string& folder, const DatasetOptions& options)
      : Dataset(DatasetNameFromPath(folder), DatasetKind::kDNerf, options), root_(folder) {}

  Status Load(const DatasetOptions& options) {
    if (!options.test_cameras.empty()) {
      return MakeError(StatusCode::kInvalidArgument, root_.string(),
                       ": test_cameras cannot be chosen for D-NeRF (every frame has its own camera)");
    }
    std::vector<std::string> names = {"train", "test"};
    if (options.load_val_split) names.push_back("val");
    std::vector<Split> splits;
    for (const std::string& name : names) {
      if (name != "train" && !fs::exists(root_ / ("transforms_" + name + ".json"))) {
        warnings_.push_back(StrCat("dnerf: no transforms_", name, ".json"));
        splits.emplace_back();
        continue;
      }
      ATEX_ASSIGN_OR_RETURN(Split split, ReadTransforms(root_, name, &warnings_));
      splits.push_back(std::move(split));
    }
    if (splits[0].frames.empty()) {
      return MakeError(StatusCode::kNotFound, root_.string(), ": no training frame has an image file");
    }
    ATEX_ASSIGN_OR_RETURN(const ImageInfo info, ReadImageInfo(splits[0].frames[0].path));
    has_masks_ = info.channels == 4;
    std::set<double> train_times;
    for (size_t s = 0; s < splits.size(); ++s) {
      const double focal = 0.5 * info.width / std::tan(0.5 * splits[s].camera_angle_x);
      for (size_t i = 0; i < splits[s].frames.size(); ++i) {
        const Frame& frame = splits[s].frames[i];
        View view;
        view.camera.width = info.width;
        view.camera.height = info.height;
        view.camera.fx = view.camera.fy = focal;
        view.camera.cx = 0.5 * info.width;
        view.camera.cy = 0.5 * info.height;
        StatusOr<std::array<double, 16>> w2c = BlenderCameraToWorldToOpenCv(frame.c2w);
        if (!w2c.ok()) return w2c.status().WithContext(frame.path);
        view.camera.world_to_camera = *w2c;
        view.camera.time = frame.time;
        view.camera.name = StrCat(names[s], " ", i);
        view.camera = ScaleCamera(view.camera, downscale_);
        if (view.camera.width < 1 || view.camera.height < 1) {
          return MakeError(StatusCode::kInvalidArgument, root_.string(), ": downscale ", downscale_,
                           " leaves no pixels");
        }
        view.camera_id = static_cast<int>(i);
        view.image = frame.path;
        if (has_masks_) view.mask = frame.path;
        if (s == 0) train_times.insert(frame.time);
        (s == 0 ? train_ : s == 1 ? test_ : val_).push_back(std::move(view));
      }
    }
    timestep_count_ = static_cast<int>(train_times.size());
    FinishTimeRange(train_, test_, &time_min_, &time_max_);
    return Status::Ok();
  }

 protected:
  StatusOr<Image> ReadViewImage(const View& view) const override { return ReadImage(view.image); }
  StatusOr<Image> ReadViewMask(const View& view) const override {
    ATEX_ASSIGN_OR_RETURN(const Image rgba, ReadImage(view.mask));
    if (rgba.channels != 4) {
      return MakeError(StatusCode::kNotFound, view.mask, ": frame has no alpha channel, so no mask");
    }
    Image mask(rgba.width, rgba.height, 1);
    for (size_t p = 0; p < mask.pixels.size(); ++p) mask.pixels[p] = rgba.pixels[p * 4 + 3];
    return mask;
  }

 private:
  fs::path root_;
};

// --- the tiny lego .npz --------------------------------------------------------
constexpr int kLegoFrames = 81, kLegoTrain = 50, kLegoVal = 11;

Status ExpectShape(const NpyArray& a, const std::vector<int64_t>& shape, const std::string& what) {
  if (a.shape != shape) {
    std::string got;
    for (int64_t d : a.shape) got += StrCat(got.empty() ? "" : ",", d);
    std::string want;
    for (int64_t d : shape) want += StrCat(want.empty() ? "" : ",", d);
    return MakeError(StatusCode::kCorrupt, what, " has shape (", got, "), expected (", want, ")");
  }
  return Status::Ok();
}

class LegoNpzDataset final : public Dataset {
 public:
  LegoNpzDataset(const std::string& file, const DatasetOptions& options)
      : Dataset(fs::path(file).stem().string(), DatasetKind::kDNerfNpz, options), file_(file) {}

  Status Load(const DatasetOptions& options) {
    if (!options.test_cameras.empty()) {
      return MakeError(StatusCode::kInvalidArgument, file_, ": test_cameras cannot be chosen for the lego .npz");
    }
    // The images stay in memory as float32: a member larger than the image cache could hold
    // (twice that for float64) is refused from the ZIP directory, before it is inflated.
    ZipLimits limits;
    limits.max_member_bytes = std::min(limits.max_member_bytes, 2 * options.image_cache_bytes + (uint64_t{1} << 20));
    ATEX_ASSIGN_OR_RETURN(auto arrays, ReadNpzFile(file_, limits));
    for (const char* key : {"images", "poses", "times", "focal"}) {
      if (!arrays.count(key)) return MakeError(StatusCode::kCorrupt, file_, ": no '", key, "' array");
    }
    const NpyArray& images = arrays["images"];
    if (images.shape.size() != 4 || images.shape[3] != 3 || images.shape[1] < 1 || images.shape[2] < 1 ||
        images.shape[1] > kMaxImageSide || images.shape[2] > kMaxImageSide) {
      return MakeError(StatusCode::kCorrupt, file_, ": 'images' must be (N, H, W, 3)");
    }
    if (images.dtype != NpyDtype::kFloat32 && images.dtype != NpyDtype::kFloat64) {
      return MakeError(StatusCode::kCorrupt, file_, ": 'images' are ", NpyDtypeDescr(images.dtype),
                       "; the packed layout stores float32 in [0, 1]");
    }
    const int64_t n = images.shape[0];
    height_ = static_cast<int>(images.shape[1]);
    width_ = static_cast<int>(images.shape[2]);
    const uint64_t float_bytes = uint64_t(std::max<int64_t>(n, 0)) * uint64_t(height_) * uint64_t(width_) * 3 * 4;
    if (float_bytes > options.image_cache_bytes) {
      return MakeError(StatusCode::kLimitExceeded, file_, ": 'images' need ", float_bytes,
                       " bytes in memory, more than the image cache's ", options.image_cache_bytes,
                       " (DatasetOptions::image_cache_bytes)");
    }
    if (n != kLegoFrames) {
      return MakeError(StatusCode::kUnsupported, file_, ": ", n, " frames; the packed D-NeRF layout has ",
                       kLegoFrames, " (50 train, 11 val, 20 test)");
    }
    ATEX_RETURN_IF_ERROR(ExpectShape(arrays["poses"], {n, 4, 4}, file_ + ": 'poses'"));
    ATEX_RETURN_IF_ERROR(ExpectShape(arrays["times"], {n}, file_ + ": 'times'"));
    ATEX_ASSIGN_OR_RETURN(const double focal, arrays["focal"].Scalar(file_ + ": 'focal'"));
    if (!(focal > 0) || !std::isfinite(focal)) return MakeError(StatusCode::kCorrupt, file_, ": focal ", focal);
    pixels_ = images.ToFloat();  // [N][H][W][3]
    for (size_t k = 0; k < pixels_.size(); ++k) {
      if (!(pixels_[k] >= 0.0f && pixels_[k] <= 1.0f)) {
        const size_t frame = k / (size_t(width_) * height_ * 3);
        return MakeError(StatusCode::kCorrupt, file_, ": 'images' value ", pixels_[k], " at element ", k, " (frame ",
                         frame, ") is outside [0, 1]");
      }
    }
    const std::vector<double> poses = arrays["poses"].ToDouble();  // [N][4][4]
    const std::vector<double> times = arrays["times"].ToDouble();  // [N]

    std::set<double> train_times;
    for (int64_t i = 0; i < n; ++i) {
      View view;
      view.camera.width = width_;
      view.camera.height = height_;
      view.camera.fx = view.camera.fy = focal;
      view.camera.cx = 0.5 * width_;
      view.camera.cy = 0.5 * height_;
      std::array<double, 16> c2w;
      std::copy(poses.begin() + i * 16, poses.begin() + i * 16 + 16, c2w.begin());
      StatusOr<std::array<double, 16>> w2c = BlenderCameraToWorldToOpenCv(c2w);
      if (!w2c.ok()) return w2c.status().WithContext(StrCat(file_, ": poses[", i, "]"));
      view.camera.world_to_camera = *w2c;
      if (!std::isfinite(times[i])) return MakeError(StatusCode::kCorrupt, file_, ": times[", i, "] is not finite");
      view.camera.time = times[i];
      const char* split = i < kLegoTrain ? "train" : i < kLegoTrain + kLegoVal ? "val" : "test";
      view.camera.name = StrCat(split, " ", i);
      view.camera = ScaleCamera(view.camera, downscale_);
      if (view.camera.width < 1 || view.camera.height < 1) {
        return MakeError(StatusCode::kInvalidArgument, file_, ": downscale ", downscale_, " leaves no pixels");
      }
      view.camera_id = static_cast<int>(i);
      view.frame_index = static_cast<int>(i);
      view.image = StrCat(file_, ":images[", i, "]");
      if (i < kLegoTrain) {
        train_times.insert(times[i]);
        train_.push_back(std::move(view));
      } else if (i < kLegoTrain + kLegoVal) {
        if (options.load_val_split) val_.push_back(std::move(view));
      } else {
        test_.push_back(std::move(view));
      }
    }
    timestep_count_ = static_cast<int>(train_times.size());
    FinishTimeRange(train_, test_, &time_min_, &time_max_);
    return Status::Ok();
  }

 protected:
  StatusOr<Image> ReadViewImage(const View& view) const override {
    Image image(width_, height_, 3);
    const size_t count = image.pixels.size();
    std::copy(pixels_.begin() + view.frame_index * count, pixels_.begin() + (view.frame_index + 1) * count,
              image.pixels.begin());
    return image;
  }

 private:
  std::string file_;
  int width_ = 0, height_ = 0;
  std::vector<float> pixels_;  // [N][H][W][3]
};

}  // namespace

StatusOr<std::unique_ptr<Dataset>> OpenDNerf(const std::string& folder, const DatasetOptions& options) {
  auto dataset = std::make_unique<DNerfDataset>(folder, options);
  ATEX_RETURN_IF_ERROR(dataset->Load(options));
  return std::unique_ptr<Dataset>(std::move(dataset));
}

StatusOr<std::unique_ptr<Dataset>> OpenDNerfNpz(const std::string& file, const DatasetOptions& options) {
  auto dataset = std::make_unique<LegoNpzDataset>(file, options);
  ATEX_RETURN_IF_ERROR(dataset->Load(options));
  return std::unique_ptr<Dataset>(std::move(dataset));
}

}  // namespace atex::data_detail
