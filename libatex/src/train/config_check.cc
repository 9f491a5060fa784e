#include "atex/train/config_check.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "atex/init.h"
#include "atex/train/trainer.h"  // CameraExtent

namespace atex::train {

namespace {

// Collects the first range error; each Validate* below is one section of the config.
class Ranges {
 public:
  template <typename T>
  void In(const std::string& key, T value, T lo, T hi) {
    if (!status_.ok()) return;
    bool finite = true;
    if constexpr (std::is_floating_point_v<T>) finite = std::isfinite(value);
    if (!finite || value < lo || value > hi) {
      status_ = MakeError(StatusCode::kOutOfRange, key, "=", value, " is outside [", lo, ", ", hi, "]");
    }
  }
  // A learning-rate schedule: both ends >= 0, and both zero or both positive (the
  // interpolation is exponential); steps >= 0, delay_mult in (0, 1].
  void Decay(const std::string& key, const ExpDecay& d) {
    In(key + ".initial", d.initial, 0.0, 1e3);
    In(key + ".final", d.final, 0.0, 1e3);
    In(key + ".max_steps", d.max_steps, 0, 1 << 30);
    In(key + ".delay_steps", d.delay_steps, 0, 1 << 30);
    In(key + ".delay_mult", d.delay_mult, 1e-12, 1.0);
    if (status_.ok() && (d.initial > 0) != (d.final > 0)) {
      status_ = MakeError(StatusCode::kOutOfRange, key, ".initial=", d.initial, " and ", key, ".final=", d.final,
                          ": both must be > 0 (exponential decay) or both 0 (frozen)");
    }
  }
  void Fail(Status s) {
    if (status_.ok()) status_ = std::move(s);
  }
  const Status& status() const { return status_; }

 private:
  Status status_;
};

constexpr int kMaxSteps = 100000000;  // 1e8 steps: far beyond any schedule, below int overflow of step sums
constexpr double kMaxLr = 1e3;

void ValidateTop(const TrainConfig& c, Ranges& r) {
  for (int k = 0; k < 3; ++k) r.In(StrCat("background[", k, "]"), double(c.background[k]), 0.0, 1.0);
  r.In("near_plane", double(c.near_plane), 1e-9, 1e9);
  r.In("eval_every", c.eval_every, 0, kMaxSteps);
  r.In("eval_views", c.eval_views, 0, 1 << 24);
  r.In("checkpoint_every", c.checkpoint_every, 0, kMaxSteps);
}

void ValidateDeformation(const DeformationConfig& d, Ranges& r) {
  const std::string p = "stage1.deformation.";
  r.In(p + "grid.channels", d.grid.channels, 1, 1024);
  for (int k = 0; k < 4; ++k) r.In(StrCat(p, "grid.base_resolution[", k, "]"), d.grid.base_resolution[k], 1, 8192);
  if (d.grid.multires.empty()) r.Fail(MakeError(StatusCode::kOutOfRange, p, "grid.multires is empty"));
  for (size_t k = 0; k < d.grid.multires.size(); ++k)
    r.In(StrCat(p, "grid.multires[", k, "]"), d.grid.multires[k], 1, 64);
  r.In(p + "grid.multires (count)", d.grid.multires.size(), size_t{0}, size_t{8});
  r.In(p + "mlp_width", d.mlp_width, 1, 4096);
  r.In(p + "trunk_layers", d.trunk_layers, 1, 64);
}

void ValidateStage1(const Stage1Config& s, Ranges& r) {
  const std::string p = "stage1.";
  r.In(p + "coarse_iterations", s.coarse_iterations, 0, kMaxSteps);
  r.In(p + "fine_iterations", s.fine_iterations, 0, kMaxSteps);
  r.In(p + "batch_size", s.batch_size, 1, 1024);
  r.In(p + "lambda_dssim", s.lambda_dssim, 0.0, 1.0);
  r.In(p + "sh_degree", s.sh_degree, 0, 3);
  r.In(p + "sh_increase_interval", s.sh_increase_interval, 1, kMaxSteps);
  r.Decay(p + "lr.position", s.lr.position);
  r.Decay(p + "lr.mlp", s.lr.mlp);
  r.Decay(p + "lr.grid", s.lr.grid);
  for (const auto& [key, value] : {std::pair{"sh_dc", s.lr.sh_dc},
                                   {"sh_rest", s.lr.sh_rest},
                                   {"opacity", s.lr.opacity},
                                   {"log_scale", s.lr.log_scale},
                                   {"rotation", s.lr.rotation},
                                   {"texels", s.lr.texels}}) {
    r.In(p + "lr." + key, value, 0.0, kMaxLr);
  }
  const DensifyConfig& d = s.densify;
  r.In(p + "densify.from_step", d.from_step, 0, kMaxSteps);
  r.In(p + "densify.until_step", d.until_step, 0, kMaxSteps);
  r.In(p + "densify.interval", d.interval, 1, kMaxSteps);
  r.In(p + "densify.grad_threshold", d.grad_threshold, 0.0, 1e6);
  r.In(p + "densify.percent_dense", d.percent_dense, 0.0, 1.0);
  r.In(p + "densify.min_opacity", d.min_opacity, 0.0, 1.0);
  r.In(p + "densify.opacity_reset_interval", d.opacity_reset_interval, 0, kMaxSteps);
  r.In(p + "densify.max_screen_radius", d.max_screen_radius, 0.0, 1e9);
  r.In(p + "densify.max_world_scale_fraction", d.max_world_scale_fraction, 0.0, 1e9);
  r.In(p + "densify.max_gaussians", d.max_gaussians, size_t{1}, size_t{1} << 32);
  r.In(p + "densify.min_observing_cameras", d.min_observing_cameras, 0, 1 << 20);
  r.In(p + "regularizer.plane_tv", s.regularizer.plane_tv, 0.0, 1e6);
  r.In(p + "regularizer.time_smoothness", s.regularizer.time_smoothness, 0.0, 1e6);
  r.In(p + "regularizer.time_l1", s.regularizer.time_l1, 0.0, 1e6);
  ValidateDeformation(s.deformation, r);
  if (r.status().ok()) {
    StatusOr<InitMethod> method = ParseInitMethod(s.init_method);
    if (!method.ok()) r.Fail(method.status().WithContext(p + "init_method"));
  }
  r.In(p + "init_points", s.init_points, size_t{0}, size_t{1} << 30);
  r.In(p + "init_hull_fraction", s.init_hull_fraction, 0.0, 1.0);
  r.In(p + "init_volume.far", s.init_volume.far, 1e-6, 1e6);
  r.In(p + "init_volume.max_colour_spread", s.init_volume.max_colour_spread, 0.0, 3.0);
  r.In(p + "init_volume.attempts_per_point", s.init_volume.attempts_per_point, 1, 1 << 20);
  const InitMvsConfig& m = s.init_mvs;  // the ranges of atex/mvs.h's MvsOptions
  r.In(p + "init_mvs.max_image_side", m.max_image_side, 16, 1 << 15);
  r.In(p + "init_mvs.near", m.near, 1e-6, 1e6);
  r.In(p + "init_mvs.far", m.far, m.near, 1e6);
  r.In(p + "init_mvs.depth_planes", m.depth_planes, 0, 1 << 16);
  r.In(p + "init_mvs.plane_step_px", m.plane_step_px, 1e-3, 1e3);
  r.In(p + "init_mvs.max_depth_planes", m.max_depth_planes, 2, 1 << 16);
  r.In(p + "init_mvs.neighbors", m.neighbors, 1, 16);
  r.In(p + "init_mvs.best_neighbors", m.best_neighbors, 1, m.neighbors);
  r.In(p + "init_mvs.window_radius", m.window_radius, 1, 5);
  r.In(p + "init_mvs.min_zncc", m.min_zncc, -1.0, 1.0);
  r.In(p + "init_mvs.min_texture", m.min_texture, 0.0, 1.0);
  r.In(p + "init_mvs.max_cost_ratio", m.max_cost_ratio, 1e-6, 1.0);
  r.In(p + "init_mvs.min_consistent_views", m.min_consistent_views, 1, 1 << 10);
  r.In(p + "init_mvs.max_reprojection_px", m.max_reprojection_px, 1e-6, 1e3);
  r.In(p + "init_mvs.max_relative_depth", m.max_relative_depth, 1e-9, 1.0);
  const FastObjectsConfig& f = s.fast_objects;  // the ranges of atex/transient_hull.h
  r.In(p + "fast_objects.points", f.points, 0, 1 << 24);
  r.In(p + "fast_objects.hull_resolution", f.hull_resolution, 4, 512);
  r.In(p + "fast_objects.max_presence", f.max_presence, 1e-6, 1.0 - 1e-6);
  r.In(p + "fast_objects.window_frames", f.window_frames, 1e-3, 1e6);
  if (r.status().ok() && s.init_method == "file" && s.init_point_cloud.empty()) {
    r.Fail(MakeError(StatusCode::kInvalidArgument, p, "init_method=file needs ", p,
                     "init_point_cloud (a PLY or COLMAP ", "points3D.txt/.bin)"));
  }
}

void ValidateCameraColour(const CameraColourConfig& c, Ranges& r) {
  const std::string p = "camera_colour.";
  r.In(p + "first_step", c.first_step, 1, kMaxSteps);
  r.In(p + "interval", c.interval, 0, kMaxSteps);
  r.In(p + "views_per_camera", c.views_per_camera, 1, 1 << 16);
  r.In(p + "keep", c.keep, 1e-6, 1.0);
}

void ValidateStage2(const Stage2Config& s, Ranges& r) {
  const std::string p = "stage2.";
  r.In(p + "iterations", s.iterations, 0, kMaxSteps);
  r.In(p + "batch_size", s.batch_size, 1, 1024);
  r.In(p + "lambda_dssim", s.lambda_dssim, 0.0, 1.0);
  for (size_t k = 0; k < s.growth_steps.size(); ++k) {
    r.In(StrCat(p, "growth_steps[", k, "]"), s.growth_steps[k], 0, kMaxSteps);
  }
  r.In(p + "growth_threshold", s.growth_threshold, 0.0, 1e6);
  r.In(p + "time_bins", s.time_bins, 1, 1024);
  r.In(p + "anisotropy_ratio", s.anisotropy_ratio, 1.0, 1e6);
  r.In(p + "anisotropy_max_scale", s.anisotropy_max_scale, 0.0, 1e9);
  r.In(p + "texel_budget_fraction", s.texel_budget_fraction, 0.0, 1.0);
}

bool SameColour(const std::array<float, 3>& a, const std::array<float, 3>& b) {
  for (int k = 0; k < 3; ++k) {
    if (std::abs(a[k] - b[k]) > 1e-6f) return false;
  }
  return true;
}

std::string Colour(const std::array<float, 3>& c) { return StrCat("[", c[0], ",", c[1], ",", c[2], "]"); }

// Key paths and values of a JSON object's leaves ("stage1.lr.grid.initial" -> 0.0016).
void Flatten(const nlohmann::json& j, const std::string& path,
             std::vector<std::pair<std::string, nlohmann::json>>* out) {
  if (j.is_object()) {
    for (auto it = j.begin(); it != j.end(); ++it)
      Flatten(it.value(), path.empty() ? it.key() : path + "." + it.key(), out);
  } else {
    out->emplace_back(path, j);
  }
}

}  // namespace

Status ValidateConfig(const TrainConfig& config) {
  Ranges r;
  ValidateTop(config, r);
  ValidateStage1(config.stage1, r);
  ValidateStage2(config.stage2, r);
  ValidateCameraColour(config.camera_colour, r);
  return r.status();
}

Status CrossCheckConfig(const TrainConfig& config, const Dataset& dataset, int stages,
                        std::vector<std::string>* warnings) {
  ATEX_RETURN_IF_ERROR(ValidateConfig(config));
  const auto warn = [&](std::string text) {
    if (warnings) warnings->push_back(std::move(text));
  };
  // Background: the images are composited on the dataset's background, the renderer draws
  // on the config's; they must be one colour, or every transparent pixel is a wrong target.
  if (!SameColour(config.background, dataset.background())) {
    return MakeError(StatusCode::kInvalidArgument, "background ", Colour(config.background),
                     " differs from the background the dataset's frames are composited on ",
                     Colour(dataset.background()),
                     " (DatasetOptions::background): open the dataset with the "
                     "training background");
  }
  if (!dataset.background_is_default() && !SameColour(config.background, DefaultBackground(dataset.kind())) &&
      !dataset.frames_have_alpha()) {
    warn(StrCat("background ", Colour(config.background), " is not the dataset's default ",
                Colour(DefaultBackground(dataset.kind())), " and its frames have no alpha: the renderer draws ",
                "this colour where the images show their own backdrop"));
  }
  // Near plane against the scene: beyond the farthest depth the dataset states nothing is
  // drawn; beyond its nearest depth, or half the camera extent, near content is culled.
  const double extent = CameraExtent(dataset.train_views());
  const auto bounds = dataset.depth_bounds();
  if (bounds[1] > 0 && config.near_plane >= bounds[1]) {
    return MakeError(StatusCode::kInvalidArgument, "near_plane=", config.near_plane,
                     " is beyond the dataset's farthest scene depth ", bounds[1], " (poses_bounds)");
  }
  if (bounds[0] > 0 && config.near_plane > bounds[0]) {
    warn(StrCat("near_plane=", config.near_plane, " is beyond the dataset's nearest scene depth ", bounds[0],
                ": the nearest content is culled"));
  } else if (bounds[1] <= 0 && config.near_plane > 0.5 * extent) {
    warn(StrCat("near_plane=", config.near_plane, " is more than half the camera extent ", extent,
                " (scene scale): content near the cameras is culled"));
  }
  if (stages & kStage1) {
    const Stage1Config& s1 = config.stage1;
    if (s1.densify.enabled && s1.densify.until_step <= s1.densify.from_step && s1.fine_iterations > 0) {
      warn(StrCat("stage1.densify.until_step=", s1.densify.until_step,
                  " <= stage1.densify.from_step=", s1.densify.from_step, ": densification never runs"));
    }
    if (s1.densify.enabled && s1.densify.from_step >= s1.coarse_iterations + s1.fine_iterations &&
        s1.coarse_iterations + s1.fine_iterations > 0) {
      warn(StrCat("stage1.densify.from_step=", s1.densify.from_step, " is beyond the ",
                  s1.coarse_iterations + s1.fine_iterations, " stage-1 steps: densification never runs"));
    }
    if (s1.coarse_iterations + s1.fine_iterations == 0) warn("stage 1 has 0 steps: the initial cloud is the model");
    const bool timed_views = !dataset.train_views().empty() && dataset.train_views()[0].timestep >= 0;
    if (s1.fast_objects.enabled && (!dataset.has_masks() || !timed_views)) {
      return MakeError(StatusCode::kInvalidArgument,
                       "stage1.fast_objects.enabled needs a multi-view dataset with timesteps and foreground masks "
                       "(its seeds come from every timestep's visual hull); '",
                       dataset.name(), "' has ", timed_views ? "no masks" : "no timesteps");
    }
    if (s1.fast_objects.enabled && timed_views && dataset.timestep_count() < 2) {
      warn("stage1.fast_objects.enabled with one timestep: nothing can be fast, no seeds are added");
    }
    if (s1.fast_objects.enabled && s1.fine_iterations == 0) {
      warn(
          "stage1.fast_objects.enabled with stage1.fine_iterations=0: the seeds are added where the fine stage starts");
    }
  }
  if (stages & kStage2) {
    const Stage2Config& s2 = config.stage2;
    if (s2.textures == TextureMode::kAdaptive) {
      for (size_t k = 0; k < s2.growth_steps.size(); ++k) {
        if (s2.growth_steps[k] > s2.iterations) {
          return MakeError(StatusCode::kInvalidArgument, "stage2.growth_steps[", k, "]=", s2.growth_steps[k],
                           " is beyond stage2.iterations=", s2.iterations, ": that growth would never happen");
        }
      }
      if (s2.growth_steps.empty()) warn("stage2.growth_steps is empty: adaptive textures stay 1x1");
    }
    if (s2.textures != TextureMode::kNone && s2.texel_budget_fraction * 16.0 < 1.0) {
      return MakeError(StatusCode::kInvalidArgument, "stage2.texel_budget_fraction=", s2.texel_budget_fraction,
                       " gives fewer than one texel per Gaussian (16 x fraction < 1), but stage2.textures=",
                       TextureModeName(s2.textures), " attaches at least one to each");
    }
  }
  // Time: the deformation's time axis needs a time range to map; a dataset of one time
  // makes the time resolution free (documented: the grid's t axis then sees one value).
  if (dataset.time_max() < dataset.time_min()) {
    return MakeError(StatusCode::kInvalidArgument, "the dataset's time range [", dataset.time_min(), ", ",
                     dataset.time_max(), "] is empty");
  }
  if (dataset.time_max() == dataset.time_min() && config.stage1.deformation.grid.base_resolution[3] > 1 &&
      (stages & kStage1)) {
    warn(StrCat("the dataset has one time, but stage1.deformation.grid.base_resolution[3]=",
                config.stage1.deformation.grid.base_resolution[3], ": the time axis is never trained"));
  }
  if (dataset.test_views().empty()) warn("the dataset has no test views: no test metrics are reported");
  return Status::Ok();
}

Status CheckResumeConfig(const TrainConfig& checkpoint, const TrainConfig& requested,
                         std::vector<std::string>* changed) {
  static const char* const kModelKeys[] = {"stage1.deformation.", "stage1.sh_degree", "stage2.textures",
                                           "stage2.time_bins", "background"};
  std::vector<std::pair<std::string, nlohmann::json>> before, after;
  Flatten(ConfigToJson(checkpoint), "", &before);
  Flatten(ConfigToJson(requested), "", &after);
  for (size_t k = 0; k < std::min(before.size(), after.size()); ++k) {
    if (before[k].second == after[k].second) continue;
    const std::string& key = after[k].first;
    for (const char* model_key : kModelKeys) {
      if (key.rfind(model_key, 0) == 0) {
        return MakeError(StatusCode::kInvalidArgument, "--resume: ", key, " is ", before[k].second.dump(),
                         " in the checkpoint's model but ", after[k].second.dump(),
                         " was asked; a resumed run continues the checkpoint's model");
      }
    }
    if (changed) changed->push_back(StrCat(key, ": ", before[k].second.dump(), " -> ", after[k].second.dump()));
  }
  return Status::Ok();
}

}  // namespace atex::train
