#include "atex/train/config.h"

#include <cmath>
#include <limits>

namespace atex {

// JSON forms of the model's config structs (used by the training config only).
static void to_json(nlohmann::json& j, const HexPlaneConfig& c) {
  j = {{"channels", c.channels}, {"base_resolution", c.base_resolution}, {"multires", c.multires}};
}
static void from_json(const nlohmann::json& j, HexPlaneConfig& c) {
  c.channels = j.value("channels", c.channels);
  c.base_resolution = j.value("base_resolution", c.base_resolution);
  c.multires = j.value("multires", c.multires);
}
static void to_json(nlohmann::json& j, const DeformationConfig& c) {
  j = {{"grid", c.grid},
       {"mlp_width", c.mlp_width},
       {"trunk_layers", c.trunk_layers},
       {"heads", {{"position", c.heads[kHeadPosition]},
                  {"scale", c.heads[kHeadScale]},
                  {"rotation", c.heads[kHeadRotation]},
                  {"opacity", c.heads[kHeadOpacity]},
                  {"sh", c.heads[kHeadSH]}}}};
}
static void from_json(const nlohmann::json& j, DeformationConfig& c) {
  if (j.contains("grid")) from_json(j.at("grid"), c.grid);
  c.mlp_width = j.value("mlp_width", c.mlp_width);
  c.trunk_layers = j.value("trunk_layers", c.trunk_layers);
  if (j.contains("heads")) {
    const auto& h = j.at("heads");
    c.heads[kHeadPosition] = h.value("position", c.heads[kHeadPosition]);
    c.heads[kHeadScale] = h.value("scale", c.heads[kHeadScale]);
    c.heads[kHeadRotation] = h.value("rotation", c.heads[kHeadRotation]);
    c.heads[kHeadOpacity] = h.value("opacity", c.heads[kHeadOpacity]);
    c.heads[kHeadSH] = h.value("sh", c.heads[kHeadSH]);
  }
}

namespace train {

NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE_WITH_DEFAULT(ExpDecay, initial, final, max_steps, delay_steps, delay_mult)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE_WITH_DEFAULT(LearningRates, position, sh_dc, sh_rest, opacity, log_scale, rotation,
                                                mlp, grid, texels)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE_WITH_DEFAULT(DensifyConfig, enabled, from_step, until_step, interval,
                                                grad_threshold, percent_dense, min_opacity, opacity_reset_interval,
                                                opacity_reset_in_fine, max_screen_radius, max_world_scale_fraction,
                                                max_gaussians, min_observing_cameras)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE_WITH_DEFAULT(RegularizerConfig, plane_tv, time_smoothness, time_l1)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE_WITH_DEFAULT(InitVolumeConfig, far, uniform_depth, max_colour_spread,
                                                attempts_per_point)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE_WITH_DEFAULT(InitMvsConfig, max_image_side, near, far, depth_planes, plane_step_px,
                                                max_depth_planes, neighbors,
                                                best_neighbors, window_radius, min_zncc, min_texture, max_cost_ratio,
                                                min_consistent_views, max_reprojection_px, max_relative_depth)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE_WITH_DEFAULT(FastObjectsConfig, enabled, points, hull_resolution, max_presence,
                                                window_frames)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE_WITH_DEFAULT(Stage1Config, coarse_iterations, fine_iterations, batch_size,
                                                same_time_batches, lambda_dssim, sh_degree, sh_increase_interval, lr,
                                                densify, regularizer, deformation, init_method, init_points,
                                                init_hull_fraction, init_volume, init_mvs, init_point_cloud,
                                                fast_objects)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE_WITH_DEFAULT(GrowthAblations, temporal_peak, anisotropic,
                                                visibility_normalization)

static void to_json(nlohmann::json& j, const Stage2Config& c) {
  j = {{"iterations", c.iterations},
       {"batch_size", c.batch_size},
       {"same_time_batches", c.same_time_batches},
       {"lambda_dssim", c.lambda_dssim},
       {"textures", std::string(TextureModeName(c.textures))},
       {"growth_steps", c.growth_steps},
       {"growth_threshold", c.growth_threshold},
       {"time_bins", c.time_bins},
       {"anisotropy_ratio", c.anisotropy_ratio},
       {"anisotropy_max_scale", c.anisotropy_max_scale},
       {"texel_budget_fraction", c.texel_budget_fraction},
       {"ablations", c.ablations},
       {"rescale_grown_moments", c.rescale_grown_moments}};
}
static void from_json(const nlohmann::json& j, Stage2Config& c) {
  c.iterations = j.value("iterations", c.iterations);
  c.batch_size = j.value("batch_size", c.batch_size);
  c.same_time_batches = j.value("same_time_batches", c.same_time_batches);
  c.lambda_dssim = j.value("lambda_dssim", c.lambda_dssim);
  if (j.contains("textures")) {
    auto mode = ParseTextureMode(j.at("textures").get<std::string>());
    if (!mode.ok()) throw nlohmann::json::other_error::create(501, mode.status().message(), &j);
    c.textures = *mode;
  }
  c.growth_steps = j.value("growth_steps", c.growth_steps);
  c.growth_threshold = j.value("growth_threshold", c.growth_threshold);
  c.time_bins = j.value("time_bins", c.time_bins);
  c.anisotropy_ratio = j.value("anisotropy_ratio", c.anisotropy_ratio);
  c.anisotropy_max_scale = j.value("anisotropy_max_scale", c.anisotropy_max_scale);
  c.texel_budget_fraction = j.value("texel_budget_fraction", c.texel_budget_fraction);
  c.ablations = j.value("ablations", c.ablations);
  c.rescale_grown_moments = j.value("rescale_grown_moments", c.rescale_grown_moments);
}

NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE_WITH_DEFAULT(CameraColourConfig, enabled, first_step, interval, views_per_camera,
                                                keep)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE_WITH_DEFAULT(TrainConfig, seed, stage1, stage2, camera_colour, background,
                                                near_plane, eval_every, eval_views, checkpoint_every,
                                                images_on_every_gpu)

double ExpDecay::At(int step) const {
  if (step < 0 || (initial == 0.0 && final == 0.0)) return 0.0;
  double delay = 1.0;
  if (delay_steps > 0) {
    // 3DGS: a smooth warm-up from delay_mult * lr to lr over delay_steps.
    const double x = std::min(1.0, static_cast<double>(step) / delay_steps);
    delay = delay_mult + (1.0 - delay_mult) * std::sin(0.5 * M_PI * x);
  }
  const double t = max_steps > 0 ? std::clamp(static_cast<double>(step) / max_steps, 0.0, 1.0) : 1.0;
  return delay * std::exp(std::log(initial) * (1.0 - t) + std::log(final) * t);
}

TrainConfig DefaultConfig(std::string_view dataset_kind) {
  TrainConfig config;
  DeformationConfig& d = config.stage1.deformation;
  if (dataset_kind == "dnerf" || dataset_kind == "dnerf_npz") {
    // 4DGaussians arguments/dnerf: C=32, [64,64,64,25], multires [1,2], width 64, heads x/s/r,
    // 3000 coarse + 20000 fine, batch 1, TV 1e-4, time smoothness 1e-2.
    d.grid.channels = 32;
    d.grid.base_resolution = {64, 64, 64, 25};
    d.mlp_width = 64;
    d.heads = {true, true, true, false, false};
    config.stage1.fine_iterations = 20000;
    config.stage1.batch_size = 1;
    config.stage1.regularizer = {1e-4, 1e-2, 1e-4};
    config.stage1.densify.until_step = 15000;
    config.stage1.lr.grid = {1.6e-3, 1.6e-5, 20000};
    config.stage1.lr.mlp = {1.6e-4, 1.6e-6, 20000};
  } else {
    // N3DV (REFERENCE.md §1): C=16, [64,64,64,150], multires [1,2], width 128, all five heads,
    // 3000 coarse + 14000 fine, batch 4, TV 2e-4, time smoothness 1e-3, densify until 10000.
    d.grid.channels = 16;
    d.grid.base_resolution = {64, 64, 64, 150};
    d.mlp_width = 128;
    d.heads = {true, true, true, true, true};
    if (dataset_kind == "panoptic") {
      // [choice] 30 timesteps here: the time resolution follows 4DGaussians' advice of half the frame count.
      d.grid.base_resolution = {64, 64, 64, 16};
      // [choice, issue 20] a fixed rig of calibrated cameras with foreground masks: the stereo cloud of
      // the first timestep (walls, floor, people) plus the masks' visual hull instead of hull + view-volume
      // points (whose photo-consistency test accepts points in the air in front of near-textureless
      // walls: the haze), and per-camera colour correction. Measured on basketball (BENCHMARKS.md,
      // issue 20, third run, two seeds, H100): test PSNR 28.07 dB against 24.69 for hull + volume with
      // the same colour correction, 27.25 without the colour correction, 26.95 with its first fit after
      // the coarse stage.
      config.stage1.init_method = "mvs+hull";
      config.camera_colour.enabled = true;
      // [choice, issue 20] fast-object seeds from every timestep's visual hull (time-local Gaussians,
      // atex/transient_hull.h): the ball in flight, which the deformation field loses, is drawn in every
      // test frame; on an H100, same seeds: camera 0's dynamic region +0.9 dB, test PSNR +0.18 and +0.34
      // dB, stage 1 no slower (BENCHMARKS.md, issue 20, fourth run).
      config.stage1.fast_objects.enabled = true;
    }
  }
  return config;
}

const char* DefaultConfigKind(DatasetKind kind) {
  switch (kind) {
    case DatasetKind::kPanoptic: return "panoptic";
    case DatasetKind::kN3dv: return "n3dv";
    // [choice] per-frame cameras (nerfstudio) and static captures (COLMAP): D-NeRF's smaller
    // deformation field, as for the other layouts whose frames each have their own camera.
    case DatasetKind::kDNerf:
    case DatasetKind::kDNerfNpz:
    case DatasetKind::kNerfstudio:
    case DatasetKind::kColmap: return "dnerf";
    default: return "generic";
  }
}

nlohmann::json ConfigToJson(const TrainConfig& config) { return config; }

// The JSON type name used in messages.
static const char* TypeName(const nlohmann::json& j) {
  if (j.is_number_integer()) return "an integer";
  if (j.is_number_float()) return "a real number";
  return j.type_name();
}

// Whether `value` may replace `reference` (a value of the default config) without a silent
// conversion: integers stay integers (1.5 is not 1, true is not 1), unsigned values are not
// negative, booleans stay booleans, fixed-length arrays keep their length.
static Status CheckType(const nlohmann::json& value, const nlohmann::json& reference, const std::string& key) {
  const auto mismatch = [&](const char* wanted) {
    return MakeError(StatusCode::kInvalidArgument, "training config key '", key, "' = ", value.dump(), " is ",
                     TypeName(value), ", not ", wanted);
  };
  if (reference.is_boolean()) return value.is_boolean() ? Status::Ok() : mismatch("true or false");
  if (reference.is_number_unsigned()) {
    if (value.is_number_unsigned() || (value.is_number_integer() && value.get<long long>() >= 0)) return Status::Ok();
    return mismatch("an integer >= 0");
  }
  if (reference.is_number_integer()) {
    if (!value.is_number_integer()) return mismatch("an integer");
    const long long v = value.is_number_unsigned() ? -1 : value.get<long long>();
    if (value.is_number_unsigned() ? value.get<unsigned long long>() > unsigned(std::numeric_limits<int>::max())
                                   : (v > std::numeric_limits<int>::max() || v < std::numeric_limits<int>::min())) {
      return MakeError(StatusCode::kOutOfRange, "training config key '", key, "' = ", value.dump(),
                       " does not fit a 32-bit integer");
    }
    return Status::Ok();
  }
  if (reference.is_number_float()) return value.is_number() ? Status::Ok() : mismatch("a number");
  if (reference.is_string()) return value.is_string() ? Status::Ok() : mismatch("a string");
  if (reference.is_array()) {
    if (!value.is_array()) return mismatch("an array");
    // std::array members (background, grid.base_resolution) have a fixed length.
    static const char* const kFixed[] = {"background", "stage1.deformation.grid.base_resolution"};
    for (const char* fixed : kFixed) {
      if (key == fixed && value.size() != reference.size()) {
        return MakeError(StatusCode::kInvalidArgument, "training config key '", key, "' = ", value.dump(), " has ",
                         value.size(), " values, not ", reference.size());
      }
    }
    if (!reference.empty()) {
      for (size_t k = 0; k < value.size(); ++k) {
        ATEX_RETURN_IF_ERROR(CheckType(value[k], reference[0], StrCat(key, "[", k, "]")));
      }
    }
    return Status::Ok();
  }
  if (reference.is_object() && !value.is_object()) return mismatch("an object");
  return Status::Ok();
}

// Every key of `patch` must exist in `reference` (recursively, for objects), with a value of its type.
static Status CheckKnownKeys(const nlohmann::json& patch, const nlohmann::json& reference, const std::string& path) {
  if (!patch.is_object()) return Status::Ok();
  for (auto it = patch.begin(); it != patch.end(); ++it) {
    const std::string key_path = path.empty() ? it.key() : path + "." + it.key();
    if (!reference.is_object() || !reference.contains(it.key())) {
      return MakeError(StatusCode::kInvalidArgument, "unknown training config key '", key_path, "'");
    }
    ATEX_RETURN_IF_ERROR(CheckType(it.value(), reference.at(it.key()), key_path));
    ATEX_RETURN_IF_ERROR(CheckKnownKeys(it.value(), reference.at(it.key()), key_path));
  }
  return Status::Ok();
}

StatusOr<TrainConfig> ConfigFromJson(const nlohmann::json& json, const TrainConfig& base) {
  if (!json.is_object()) return MakeError(StatusCode::kInvalidArgument, "training config must be a JSON object");
  nlohmann::json merged = ConfigToJson(base);
  ATEX_RETURN_IF_ERROR(CheckKnownKeys(json, merged, ""));
  merged.merge_patch(json);
  try {
    return merged.get<TrainConfig>();
  } catch (const nlohmann::json::exception& e) {
    return MakeError(StatusCode::kInvalidArgument, "training config: ", e.what());
  }
}

StatusOr<TrainConfig> ApplyOverride(const TrainConfig& config, std::string_view assignment) {
  const size_t eq = assignment.find('=');
  if (eq == std::string_view::npos || eq == 0) {
    return MakeError(StatusCode::kInvalidArgument, "override '", assignment, "' is not of the form key.path=value");
  }
  const std::string key(assignment.substr(0, eq));
  const std::string text(assignment.substr(eq + 1));
  nlohmann::json value = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (value.is_discarded()) value = text;  // a bare word is a string
  nlohmann::json patch = nlohmann::json::object();
  nlohmann::json* node = &patch;
  size_t start = 0;
  while (true) {
    const size_t dot = key.find('.', start);
    const std::string part = key.substr(start, dot == std::string::npos ? std::string::npos : dot - start);
    if (part.empty()) return MakeError(StatusCode::kInvalidArgument, "override key '", key, "' has an empty part");
    if (dot == std::string::npos) {
      (*node)[part] = value;
      break;
    }
    node = &(*node)[part];
    start = dot + 1;
  }
  return ConfigFromJson(patch, config);
}

}  // namespace train
}  // namespace atex
