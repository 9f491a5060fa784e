// Dataset base class (cached, downscaled image access), kind detection and the
// in-memory dataset.
#include "atex/dataset.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <set>

#include "atex/file_io.h"
#include "data/dataset_loaders.h"
#include "data/image_cache.h"

namespace atex {

namespace fs = std::filesystem;

const char* DatasetKindName(DatasetKind kind) {
  switch (kind) {
    case DatasetKind::kAuto: return "auto";
    case DatasetKind::kPanoptic: return "panoptic";
    case DatasetKind::kDNerf: return "dnerf";
    case DatasetKind::kDNerfNpz: return "dnerf-npz";
    case DatasetKind::kN3dv: return "n3dv";
    case DatasetKind::kNerfstudio: return "nerfstudio";
    case DatasetKind::kColmap: return "colmap";
    case DatasetKind::kInMemory: return "in-memory";
  }
  return "?";
}

std::vector<const View*> FirstTimestepViews(const std::vector<View>& views) {
  int first_step = -1;
  for (const View& v : views) {
    if (v.timestep >= 0 && (first_step < 0 || v.timestep < first_step)) first_step = v.timestep;
  }
  std::vector<const View*> first;
  for (const View& v : views) {
    if (first_step < 0 || v.timestep == first_step) first.push_back(&v);
  }
  return first;
}

StatusOr<DatasetKind> ParseDatasetKind(const std::string& name) {
  for (DatasetKind kind : {DatasetKind::kAuto, DatasetKind::kPanoptic, DatasetKind::kDNerf, DatasetKind::kDNerfNpz,
                           DatasetKind::kN3dv, DatasetKind::kNerfstudio, DatasetKind::kColmap,
                           DatasetKind::kInMemory}) {
    if (name == DatasetKindName(kind)) return kind;
  }
  return MakeError(StatusCode::kInvalidArgument, "unknown dataset kind '", name,
                   "' (auto, panoptic, dnerf, dnerf-npz, n3dv, nerfstudio, colmap)");
}

Dataset::Dataset(std::string name, DatasetKind kind, const DatasetOptions& options)
    : name_(std::move(name)),
      kind_(kind),
      background_(options.background.value_or(DefaultBackground(kind))),
      background_is_default_(!options.background.has_value()),
      downscale_(options.downscale),
      cache_limit_(MemoryLimit(options.image_cache_bytes)),
      cache_(std::make_shared<ImageCache>(cache_limit_)) {
  // A cache larger than the machine degrades to half its RAM: images beyond it reload.
  if (cache_limit_ < options.image_cache_bytes) {
    warnings_.push_back(StrCat("image cache limited to ", cache_limit_ >> 20,
                               " MiB (half the machine's RAM) instead of ", options.image_cache_bytes >> 20,
                               " MiB; images beyond it are decoded again when needed"));
  }
}

std::array<float, 3> DefaultBackground(DatasetKind kind) {
  if (kind == DatasetKind::kDNerf) return {1.0f, 1.0f, 1.0f};
  return {0.0f, 0.0f, 0.0f};
}

std::string DefaultBackgroundReason(DatasetKind kind) {
  switch (kind) {
    case DatasetKind::kDNerf: return "white: D-NeRF's RGBA frames are composited on white in its published results";
    case DatasetKind::kDNerfNpz: return "black: the tiny lego .npz stores its frames with alpha dropped on black";
    default: return "black: the frames have no alpha (the background only shows where no Gaussian covers)";
  }
}

bool Dataset::frames_have_alpha() const {
  if (alpha_known_.load()) return alpha_seen_.load();
  if (!train_.empty()) {
    StatusOr<Image> decoded = ReadViewImage(train_.front());
    if (decoded.ok()) NoteAlpha(*decoded);
  }
  alpha_known_ = true;
  return alpha_seen_.load();
}

void Dataset::NoteAlpha(const Image& decoded) const {
  if (decoded.channels == 2 || decoded.channels == 4) alpha_seen_ = true;
  alpha_known_ = true;
}

StatusOr<Image> Dataset::ReadViewMask(const View& view) const {
  return MakeError(StatusCode::kNotFound, name_, ": no mask for ", view.camera.name);
}

uint64_t Dataset::cache_bytes() const { return cache_->bytes(); }

StatusOr<std::shared_ptr<const Image>> Dataset::LoadImage(const View& view) const {
  const std::string key = StrCat("image|", view.image, "|", view.frame_index);
  if (auto hit = cache_->Find(key)) return hit;
  StatusOr<Image> decoded = ReadViewImage(view);
  if (!decoded.ok()) return decoded.status();
  NoteAlpha(*decoded);
  ATEX_ASSIGN_OR_RETURN(Image image, DownscaleImage(ToRgb(*decoded, background_), images_prescaled_ ? 1 : downscale_));
  if (image.width != view.camera.width || image.height != view.camera.height) {
    return MakeError(StatusCode::kCorrupt, view.image, ": image is ", decoded->width, "x", decoded->height,
                     " but the dataset's cameras are ", view.camera.width * downscale_, "x",
                     view.camera.height * downscale_, " (downscale ", downscale_, ")");
  }
  return cache_->Insert(key, std::make_shared<const Image>(std::move(image)));
}

StatusOr<std::shared_ptr<const Image>> Dataset::LoadMask(const View& view) const {
  if (view.mask.empty()) {
    return MakeError(StatusCode::kNotFound, name_, ": no mask for view '", view.camera.name, "'");
  }
  const std::string key = StrCat("mask|", view.mask, "|", view.frame_index);
  if (auto hit = cache_->Find(key)) return hit;
  ATEX_ASSIGN_OR_RETURN(Image raw, ReadViewMask(view));
  if (raw.channels != 1) {
    return MakeError(StatusCode::kInternal, view.mask, ": mask has ", raw.channels, " channels");
  }
  ATEX_ASSIGN_OR_RETURN(Image mask, DownscaleImage(raw, downscale_));
  if (mask.width != view.camera.width || mask.height != view.camera.height) {
    return MakeError(StatusCode::kCorrupt, view.mask, ": mask is ", raw.width, "x", raw.height,
                     " but the dataset's cameras are ", view.camera.width * downscale_, "x",
                     view.camera.height * downscale_);
  }
  for (float& v : mask.pixels) v = v >= 0.5f ? 1.0f : 0.0f;
  return cache_->Insert(key, std::make_shared<const Image>(std::move(mask)));
}

Status Dataset::SelectViews(const DatasetOptions& options) {
  if (options.timestep_stride > 1) {
    const int stride = options.timestep_stride;
    std::set<int> steps;
    for (const auto* views : {&train_, &test_, &val_}) {
      for (const View& v : *views) {
        if (v.timestep >= 0) steps.insert(v.timestep);
      }
    }
    if (steps.empty()) {
      return MakeError(StatusCode::kInvalidArgument, name_, ": a timestep stride needs a multi-view video dataset (",
                       DatasetKindName(kind_), " views have no timesteps)");
    }
    std::map<int, int> renumber;  // kept timestep -> its new index
    int rank = 0;
    for (int t : steps) {
      if (rank % stride == 0) renumber[t] = rank / stride;
      ++rank;
    }
    for (auto* views : {&train_, &test_, &val_}) {
      std::vector<View> kept;
      for (View& v : *views) {
        auto it = renumber.find(v.timestep);
        if (it == renumber.end()) continue;
        v.timestep = it->second;
        kept.push_back(std::move(v));
      }
      *views = std::move(kept);
    }
    timestep_count_ = static_cast<int>(renumber.size());
    warnings_.push_back(StrCat("timestep stride ", stride, ": ", renumber.size(), " of ", steps.size(),
                               " timesteps kept (every ", stride, "th, times unchanged)"));
  }
  if (options.train_cameras > 0) {
    std::set<int> id_set;
    for (const View& v : train_) id_set.insert(v.camera_id);
    const std::vector<int> ids(id_set.begin(), id_set.end());
    const size_t m = ids.size(), n = static_cast<size_t>(options.train_cameras);
    if (n > m) {
      return MakeError(StatusCode::kInvalidArgument, name_, ": ", n, " training cameras requested, the dataset has ",
                       m);
    }
    std::set<int> chosen;
    for (size_t i = 0; i < n; ++i) chosen.insert(ids[i * m / n]);
    std::vector<View> kept;
    for (View& v : train_) {
      if (chosen.count(v.camera_id)) kept.push_back(std::move(v));
    }
    train_ = std::move(kept);
    std::string list;
    for (int id : chosen) list += StrCat(list.empty() ? "" : ",", id);
    warnings_.push_back(StrCat("training on ", n, " of ", m, " training cameras (ids ", list, ")"));
    bool has_timesteps = false;
    std::set<double> train_times;
    for (const View& v : train_) {
      has_timesteps |= v.timestep >= 0;
      train_times.insert(v.camera.time);
    }
    if (!has_timesteps) timestep_count_ = static_cast<int>(train_times.size());  // D-NeRF: distinct train times
  }
  if (options.timestep_stride > 1 || options.train_cameras > 0) {
    data_detail::FinishTimeRange(train_, test_, &time_min_, &time_max_);
  }
  return Status::Ok();
}

// ---------------------------------------------------------------------------
namespace {

// Rigid inverse of a row-major 4x4 [R | t] whose R must be orthonormal.
StatusOr<std::array<double, 16>> InvertRigid(const double r[3][3], const double t[3], const char* what) {
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) {
      double dot = 0;
      for (int k = 0; k < 3; ++k) dot += r[k][a] * r[k][b];
      if (!std::isfinite(dot) || std::abs(dot - (a == b ? 1.0 : 0.0)) > 1e-3) {
        return MakeError(StatusCode::kCorrupt, what, ": camera rotation is not orthonormal (column ", a, "·", b,
                         " = ", dot, ")");
      }
    }
  }
  for (int k = 0; k < 3; ++k) {
    if (!std::isfinite(t[k])) return MakeError(StatusCode::kCorrupt, what, ": non-finite camera position");
  }
  std::array<double, 16> w2c{};
  for (int i = 0; i < 3; ++i) {
    double ti = 0;
    for (int j = 0; j < 3; ++j) {
      w2c[i * 4 + j] = r[j][i];  // Rᵀ
      ti -= r[j][i] * t[j];
    }
    w2c[i * 4 + 3] = ti;
  }
  w2c[15] = 1;
  return w2c;
}

}  // namespace

StatusOr<std::array<double, 16>> BlenderCameraToWorldToOpenCv(const std::array<double, 16>& c2w) {
  // Flip the camera's y and z axes (columns 1 and 2 of the rotation), then invert.
  double r[3][3], t[3];
  for (int i = 0; i < 3; ++i) {
    r[i][0] = c2w[i * 4 + 0];
    r[i][1] = -c2w[i * 4 + 1];
    r[i][2] = -c2w[i * 4 + 2];
    t[i] = c2w[i * 4 + 3];
  }
  return InvertRigid(r, t, "Blender camera-to-world matrix");
}

StatusOr<std::array<double, 16>> LlffPoseToOpenCv(const double pose[15]) {
  // Row i of the 3x5 pose is (R_i0, R_i1, R_i2, t_i, hwf_i); the rotation's
  // columns are the camera's (down, right, back) axes in world coordinates.
  // OpenCV camera axes (right, down, forward) = (col 1, col 0, −col 2).
  double r[3][3], t[3];
  for (int i = 0; i < 3; ++i) {
    r[i][0] = pose[i * 5 + 1];
    r[i][1] = pose[i * 5 + 0];
    r[i][2] = -pose[i * 5 + 2];
    t[i] = pose[i * 5 + 3];
  }
  return InvertRigid(r, t, "LLFF pose");
}

// ---------------------------------------------------------------------------
namespace data_detail {

Status ValidateOptions(const DatasetOptions& options) {
  if (options.downscale < 1) {
    return MakeError(StatusCode::kInvalidArgument, "dataset downscale factor ", options.downscale, " (must be >= 1)");
  }
  if (options.max_timesteps < 0) {
    return MakeError(StatusCode::kInvalidArgument, "max_timesteps ", options.max_timesteps, " (0 = all)");
  }
  if (options.timestep_stride < 1) {
    return MakeError(StatusCode::kInvalidArgument, "timestep stride ", options.timestep_stride, " (must be >= 1)");
  }
  if (options.train_cameras < 0) {
    return MakeError(StatusCode::kInvalidArgument, "train camera count ", options.train_cameras, " (0 = all)");
  }
  if (options.background) {
    for (float v : *options.background) {
      if (!(v >= 0.0f && v <= 1.0f)) return MakeError(StatusCode::kInvalidArgument, "background value ", v);
    }
  }
  return Status::Ok();
}

Camera ScaleCamera(Camera camera, int factor) {
  if (factor == 1) return camera;
  camera.width /= factor;
  camera.height /= factor;
  camera.fx /= factor;
  camera.fy /= factor;
  camera.cx /= factor;
  camera.cy /= factor;
  return camera;
}

StatusOr<nlohmann::json> ReadJsonFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return MakeError(StatusCode::kNotFound, path, ": cannot open");
  std::stringstream text;
  text << in.rdbuf();
  try {
    return nlohmann::json::parse(text.str());
  } catch (const nlohmann::json::parse_error& e) {
    return MakeError(StatusCode::kCorrupt, path, ": invalid JSON at byte ", e.byte, ": ", e.what());
  } catch (const nlohmann::json::exception& e) {  // out_of_range: a number beyond double's range (1e999)
    return MakeError(StatusCode::kCorrupt, path, ": invalid JSON: ", e.what());
  }
}

std::string DatasetNameFromPath(const std::string& path) {
  fs::path p(path);
  while (p.has_parent_path() && p.filename().empty()) p = p.parent_path();
  std::string name = p.filename().string();
  return name.empty() ? path : name;
}

void FinishTimeRange(const std::vector<View>& train, const std::vector<View>& test, float* time_min, float* time_max) {
  double lo = INFINITY, hi = -INFINITY;
  for (const auto* views : {&train, &test}) {
    for (const View& v : *views) {
      lo = std::min(lo, v.camera.time);
      hi = std::max(hi, v.camera.time);
    }
  }
  *time_min = std::isfinite(lo) ? static_cast<float>(lo) : 0.0f;
  *time_max = std::isfinite(hi) ? static_cast<float>(hi) : 0.0f;
}

}  // namespace data_detail

// ---------------------------------------------------------------------------
namespace {

class InMemoryDataset final : public Dataset {
 public:
  InMemoryDataset(std::string name, const DatasetOptions& options, std::vector<InMemoryFrame> frames)
      : Dataset(std::move(name), DatasetKind::kInMemory, options), frames_(std::move(frames)) {}

  Status Build(const DatasetOptions& options) {
    std::set<int> timesteps;
    for (size_t i = 0; i < frames_.size(); ++i) {
      InMemoryFrame& frame = frames_[i];
      const Image& img = frame.image;
      if (img.width <= 0 || img.height <= 0 || (img.channels != 1 && img.channels != 3 && img.channels != 4) ||
          img.pixels.size() != size_t(img.width) * img.height * img.channels) {
        return MakeError(StatusCode::kInvalidArgument, "in-memory frame ", i, ": invalid image ", img.width, "x",
                         img.height, "x", img.channels);
      }
      if (img.width != frame.view.camera.width || img.height != frame.view.camera.height) {
        return MakeError(StatusCode::kInvalidArgument, "in-memory frame ", i, ": image ", img.width, "x", img.height,
                         " but camera ", frame.view.camera.width, "x", frame.view.camera.height);
      }
      if (!frame.mask.empty() && (frame.mask.channels != 1 || frame.mask.width != img.width ||
                                  frame.mask.height != img.height)) {
        return MakeError(StatusCode::kInvalidArgument, "in-memory frame ", i, ": mask must be ", img.width, "x",
                         img.height, "x1");
      }
      View view = frame.view;
      view.frame_index = static_cast<int>(i);
      view.image = StrCat(name_, ":frame[", i, "]");
      view.mask = frame.mask.empty() ? "" : StrCat(name_, ":mask[", i, "]");
      has_masks_ |= !frame.mask.empty();
      view.camera = data_detail::ScaleCamera(view.camera, downscale_);
      if (view.camera.width < 1 || view.camera.height < 1) {
        return MakeError(StatusCode::kInvalidArgument, "in-memory frame ", i, ": downscale ", downscale_,
                         " leaves no pixels");
      }
      if (view.timestep >= 0) timesteps.insert(view.timestep);
      (frame.test ? test_ : train_).push_back(std::move(view));
    }
    timestep_count_ = static_cast<int>(timesteps.size());
    data_detail::FinishTimeRange(train_, test_, &time_min_, &time_max_);
    return Status::Ok();
  }

 protected:
  StatusOr<Image> ReadViewImage(const View& view) const override { return frames_.at(view.frame_index).image; }
  StatusOr<Image> ReadViewMask(const View& view) const override { return frames_.at(view.frame_index).mask; }

 private:
  std::vector<InMemoryFrame> frames_;
};

}  // namespace

StatusOr<std::unique_ptr<Dataset>> MakeInMemoryDataset(std::string name, std::vector<InMemoryFrame> frames,
                                                       const DatasetOptions& options) {
  ATEX_RETURN_IF_ERROR(data_detail::ValidateOptions(options));
  auto dataset = std::make_unique<InMemoryDataset>(std::move(name), options, std::move(frames));
  ATEX_RETURN_IF_ERROR(dataset->Build(options));
  ATEX_RETURN_IF_ERROR(dataset->SelectViews(options));
  return std::unique_ptr<Dataset>(std::move(dataset));
}

StatusOr<std::unique_ptr<Dataset>> OpenDataset(const std::string& path, const DatasetOptions& options) {
  ATEX_RETURN_IF_ERROR(data_detail::ValidateOptions(options));
  std::error_code ec;
  if (!fs::exists(path, ec)) return MakeError(StatusCode::kNotFound, path, ": no such dataset file or folder");
  DatasetKind kind = options.kind;
  if (kind == DatasetKind::kAuto) {
    const fs::path p(path);
    if (fs::is_regular_file(p, ec) && p.extension() == ".npz") {
      kind = DatasetKind::kDNerfNpz;
    } else if (fs::is_regular_file(p, ec) && p.extension() == ".json") {
      kind = DatasetKind::kNerfstudio;
    } else if (fs::exists(p / "train_meta.json", ec)) {
      kind = DatasetKind::kPanoptic;
    } else if (fs::exists(p / "transforms_train.json", ec)) {
      kind = DatasetKind::kDNerf;
    } else if (fs::exists(p / "transforms.json", ec)) {
      kind = DatasetKind::kNerfstudio;
    } else if (fs::exists(p / "poses_bounds.npy", ec)) {
      kind = DatasetKind::kN3dv;
    } else if (data_detail::LooksLikeColmap(path)) {
      kind = DatasetKind::kColmap;
    } else {
      return MakeError(StatusCode::kNotFound, path,
                       ": not a known dataset (no train_meta.json, transforms_train.json, transforms.json, "
                       "poses_bounds.npy or COLMAP sparse/0/cameras.bin|txt, and not an .npz or .json file)");
    }
  }
  StatusOr<std::unique_ptr<Dataset>> dataset = MakeError(
      StatusCode::kInvalidArgument, path, ": dataset kind '", DatasetKindName(kind), "' cannot be opened from a path");
  switch (kind) {
    case DatasetKind::kPanoptic: dataset = data_detail::OpenPanoptic(path, options); break;
    case DatasetKind::kDNerf: dataset = data_detail::OpenDNerf(path, options); break;
    case DatasetKind::kDNerfNpz: dataset = data_detail::OpenDNerfNpz(path, options); break;
    case DatasetKind::kN3dv: dataset = data_detail::OpenN3dv(path, options); break;
    case DatasetKind::kNerfstudio: dataset = data_detail::OpenNerfstudio(path, options); break;
    case DatasetKind::kColmap: dataset = data_detail::OpenColmap(path, options); break;
    default: break;
  }
  if (dataset.ok()) ATEX_RETURN_IF_ERROR((*dataset)->SelectViews(options));
  return dataset;
}

}  // namespace atex
