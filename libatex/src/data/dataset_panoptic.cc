// CMU Panoptic in Dynamic3DGaussians' layout:
//   train_meta.json / test_meta.json: {w, h, k[t][i] (3x3), w2c[t][i] (4x4, OpenCV
//   world-to-camera), fn[t][i] ("<cam>/<t>.jpg"), cam_id[t][i]}
//   ims/<fn>       the frames
//   seg/<fn>.png   foreground masks (train cameras only)
// Intrinsics are used as given (as Dynamic3DGaussians and gsplat do). The
// timesteps used are the longest prefix 0..T-1 whose images exist for every
// camera of both splits (capped by max_timesteps); time = t/(T-1).
#include <cmath>
#include <filesystem>
#include <map>
#include <set>

#include <nlohmann/json.hpp>

#include "data/dataset_loaders.h"

namespace atex::data_detail {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct MetaEntry {
  int cam_id = -1;
  std::string fn;  // relative to ims/
  double k[9] = {};
  std::array<double, 16> w2c{};
};

struct Meta {
  int width = 0, height = 0;
  std::vector<std::vector<MetaEntry>> timesteps;  // [T][cameras]
};

Status ReadNumbers(const json& value, size_t rows, size_t cols, double* out, const std::string& where) {
  if (!value.is_array() || value.size() != rows) {
    return MakeError(StatusCode::kCorrupt, where, ": expected a ", rows, "x", cols, " array");
  }
  for (size_t r = 0; r < rows; ++r) {
    if (!value[r].is_array() || value[r].size() != cols) {
      return MakeError(StatusCode::kCorrupt, where, ": row ", r, " is not an array of ", cols, " numbers");
    }
    for (size_t c = 0; c < cols; ++c) {
      const json& v = value[r][c];
      if (!v.is_number() || !std::isfinite(v.get<double>())) {
        return MakeError(StatusCode::kCorrupt, where, ": element [", r, "][", c, "] is not a finite number");
      }
      out[r * cols + c] = v.get<double>();
    }
  }
  return Status::Ok();
}

bool SafeRelativePath(const std::string& p) {
  if (p.empty() || p[0] == '/' || p[0] == '\\') return false;
  for (const auto& part : fs::path(p)) {
    if (part == "..") return false;
  }
  return true;
}

StatusOr<Meta> ReadMeta(const fs::path& path) {
  ATEX_ASSIGN_OR_RETURN(const json root, ReadJsonFile(path));
  const std::string where = path.string();
  if (!root.is_object()) return MakeError(StatusCode::kCorrupt, where, ": not a JSON object");
  for (const char* key : {"w", "h", "k", "w2c", "fn", "cam_id"}) {
    if (!root.contains(key)) return MakeError(StatusCode::kCorrupt, where, ": missing key '", key, "'");
  }
  Meta meta;
  if (!root["w"].is_number_integer() || !root["h"].is_number_integer()) {
    return MakeError(StatusCode::kCorrupt, where, ": 'w' and 'h' must be integers");
  }
  meta.width = root["w"].get<int>();
  meta.height = root["h"].get<int>();
  if (meta.width < 1 || meta.height < 1 || meta.width > kMaxImageSide || meta.height > kMaxImageSide) {
    return MakeError(StatusCode::kCorrupt, where, ": image size ", meta.width, "x", meta.height);
  }
  const json &k = root["k"], &w2c = root["w2c"], &fn = root["fn"], &cam = root["cam_id"];
  if (!k.is_array() || !w2c.is_array() || !fn.is_array() || !cam.is_array() || k.size() != w2c.size() ||
      k.size() != fn.size() || k.size() != cam.size()) {
    return MakeError(StatusCode::kCorrupt, where, ": 'k', 'w2c', 'fn', 'cam_id' must be arrays of equal length");
  }
  meta.timesteps.resize(k.size());
  for (size_t t = 0; t < k.size(); ++t) {
    const size_t n = k[t].is_array() ? k[t].size() : 0;
    if (!k[t].is_array() || !w2c[t].is_array() || !fn[t].is_array() || !cam[t].is_array() || w2c[t].size() != n ||
        fn[t].size() != n || cam[t].size() != n) {
      return MakeError(StatusCode::kCorrupt, where, ": timestep ", t, ": per-camera arrays differ in length");
    }
    for (size_t i = 0; i < n; ++i) {
      const std::string at = StrCat(where, ": timestep ", t, ", camera #", i);
      MetaEntry entry;
      ATEX_RETURN_IF_ERROR(ReadNumbers(k[t][i], 3, 3, entry.k, StrCat(at, " 'k'")));
      ATEX_RETURN_IF_ERROR(ReadNumbers(w2c[t][i], 4, 4, entry.w2c.data(), StrCat(at, " 'w2c'")));
      if (!fn[t][i].is_string() || !SafeRelativePath(fn[t][i].get<std::string>())) {
        return MakeError(StatusCode::kCorrupt, at, ": 'fn' must be a relative path inside the dataset");
      }
      if (!cam[t][i].is_number_integer()) return MakeError(StatusCode::kCorrupt, at, ": 'cam_id' is not an integer");
      entry.fn = fn[t][i].get<std::string>();
      entry.cam_id = cam[t][i].get<int>();
      if (!(entry.k[0] > 0) || !(entry.k[4] > 0)) {
        return MakeError(StatusCode::kCorrupt, at, ": focal lengths must be positive");
      }
      meta.timesteps[t].push_back(std::move(entry));
    }
  }
  return meta;
}

class PanopticDataset final : public Dataset {
 public:
  PanopticDataset(const std::string& folder, const DatasetOptions& options)
      : Dataset(DatasetNameFromPath(folder), DatasetKind::kPanoptic, options), root_(folder) {}

  Status Load(const DatasetOptions& options) {
    ATEX_ASSIGN_OR_RETURN(Meta train, ReadMeta(root_ / "train_meta.json"));
    ATEX_ASSIGN_OR_RETURN(Meta test, ReadMeta(root_ / "test_meta.json"));
    if (train.width != test.width || train.height != test.height) {
      return MakeError(StatusCode::kCorrupt, root_.string(), ": train and test metas disagree on the image size");
    }
    const size_t meta_steps = std::min(train.timesteps.size(), test.timesteps.size());
    if (meta_steps == 0) return MakeError(StatusCode::kCorrupt, root_.string(), ": the metas list no timesteps");

    // Split per timestep: the metas' own split, or the requested test cameras.
    std::vector<std::vector<MetaEntry>> train_steps(meta_steps), test_steps(meta_steps);
    if (options.test_cameras.empty()) {
      for (size_t t = 0; t < meta_steps; ++t) {
        train_steps[t] = train.timesteps[t];
        test_steps[t] = test.timesteps[t];
      }
    } else {
      const std::set<int> wanted(options.test_cameras.begin(), options.test_cameras.end());
      std::set<int> seen;
      for (size_t t = 0; t < meta_steps; ++t) {
        for (const auto* split : {&train.timesteps[t], &test.timesteps[t]}) {
          for (const MetaEntry& e : *split) {
            (wanted.count(e.cam_id) ? test_steps : train_steps)[t].push_back(e);
            seen.insert(e.cam_id);
          }
        }
      }
      for (int id : wanted) {
        if (!seen.count(id))
          return MakeError(StatusCode::kNotFound, root_.string(), ": test camera ", id, " not in the metas");
      }
    }

    // The longest prefix of timesteps with every image present.
    size_t steps = 0;
    std::string first_missing;
    for (; steps < meta_steps; ++steps) {
      for (const auto* split : {&train_steps[steps], &test_steps[steps]}) {
        for (const MetaEntry& e : *split) {
          if (first_missing.empty() && !fs::exists(root_ / "ims" / e.fn))
            first_missing = (root_ / "ims" / e.fn).string();
        }
      }
      if (!first_missing.empty()) break;
    }
    if (steps == 0) {
      return MakeError(StatusCode::kNotFound, root_.string(), ": timestep 0 lacks images (", first_missing, ")");
    }
    if (steps < meta_steps) {
      warnings_.push_back(StrCat("panoptic: images exist for timesteps 0-", steps - 1, " only; ", meta_steps - steps,
                                 " of ", meta_steps, " listed timesteps dropped (first missing: ", first_missing, ")"));
    }
    if (options.max_timesteps > 0) steps = std::min<size_t>(steps, options.max_timesteps);
    timestep_count_ = static_cast<int>(steps);

    Camera base;
    base.width = train.width;
    base.height = train.height;
    if (base.width / downscale_ < 1 || base.height / downscale_ < 1) {
      return MakeError(StatusCode::kInvalidArgument, root_.string(), ": downscale ", downscale_, " leaves no pixels");
    }
    for (size_t t = 0; t < steps; ++t) {
      const double time = steps > 1 ? double(t) / double(steps - 1) : 0.0;
      for (int split = 0; split < 2; ++split) {
        for (const MetaEntry& e : (split == 0 ? train_steps : test_steps)[t]) {
          View view;
          view.camera = base;
          view.camera.fx = e.k[0];
          view.camera.fy = e.k[4];
          view.camera.cx = e.k[2];
          view.camera.cy = e.k[5];
          view.camera.world_to_camera = e.w2c;
          view.camera.time = time;
          view.camera.name = StrCat("cam ", e.cam_id, " / t ", t);
          view.camera = ScaleCamera(view.camera, downscale_);
          view.camera_id = e.cam_id;
          view.timestep = static_cast<int>(t);
          view.image = (root_ / "ims" / e.fn).string();
          fs::path mask = root_ / "seg" / e.fn;
          mask.replace_extension(".png");
          if (fs::exists(mask)) {
            view.mask = mask.string();
            has_masks_ = true;
          }
          (split == 0 ? train_ : test_).push_back(std::move(view));
        }
      }
    }
    FinishTimeRange(train_, test_, &time_min_, &time_max_);
    return Status::Ok();
  }

 protected:
  StatusOr<Image> ReadViewImage(const View& view) const override { return ReadImage(view.image); }
  StatusOr<Image> ReadViewMask(const View& view) const override {
    ATEX_ASSIGN_OR_RETURN(Image mask, ReadImage(view.mask));
    if (mask.channels == 1) return mask;
    // A colour mask: foreground where any channel is set.
    Image grey(mask.width, mask.height, 1);
    for (size_t p = 0; p < grey.pixels.size(); ++p) {
      float v = 0;
      for (int c = 0; c < std::min(mask.channels, 3); ++c) v = std::max(v, mask.pixels[p * mask.channels + c]);
      grey.pixels[p] = v;
    }
    return grey;
  }

 private:
  fs::path root_;
};

}  // namespace

StatusOr<std::unique_ptr<Dataset>> OpenPanoptic(const std::string& folder, const DatasetOptions& options) {
  auto dataset = std::make_unique<PanopticDataset>(folder, options);
  ATEX_RETURN_IF_ERROR(dataset->Load(options));
  return std::unique_ptr<Dataset>(std::move(dataset));
}

}  // namespace atex::data_detail
