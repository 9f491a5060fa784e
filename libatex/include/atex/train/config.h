// Training configuration: every value of both stages, loadable from JSON and
// overridable key by key ("stage1.batch_size=2"). The defaults are 4DGaussians'
// schedule (REFERENCE.md §1) for stage 1 and the AdaTex4D paper (§2) for stage 2;
// `atex train --print-config` writes them as JSON per dataset for users to copy.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "atex/dataset.h"  // DatasetKind
#include "atex/model.h"
#include "atex/render.h"  // TextureMode, kDefaultNearPlane
#include "atex/status.h"

namespace atex::train {

// Exponential interpolation from `initial` to `final` over `max_steps`, with
// 3DGS's optional delayed warm-up (delay_mult < 1 scales the first delay_steps).
struct ExpDecay {
  double initial = 0;
  double final = 0;
  int max_steps = 20000;
  int delay_steps = 0;
  double delay_mult = 1.0;
  double At(int step) const;
};

struct LearningRates {
  ExpDecay position{1.6e-4, 1.6e-6, 20000};  // multiplied by the scene extent
  double sh_dc = 2.5e-3;
  double sh_rest = 2.5e-3 / 20.0;            // 1.25e-4
  double opacity = 0.05;
  double log_scale = 5e-3;
  double rotation = 1e-3;
  ExpDecay mlp{1.6e-4, 1.6e-5, 20000};
  ExpDecay grid{1.6e-3, 1.6e-4, 20000};
  double texels = 0.0025;                    // stage 2 (paper)
};

struct DensifyConfig {
  bool enabled = true;
  int from_step = 500;
  int until_step = 10000;       // counted within the stage (4DGaussians: densify_until_iter)
  int interval = 100;
  double grad_threshold = 2e-4; // mean NDC projected-centre gradient (conventions §6)
  double percent_dense = 0.01;  // clone if max scale <= percent_dense * extent, else split
  double min_opacity = 0.005;   // prune below
  // 4DGaussians (train.py): opacities are reset every 3000 steps of the COARSE stage, and
  // once a stage is past that many steps, pruning also removes Gaussians whose screen
  // radius exceeded max_screen_radius or whose largest scale exceeds 0.1 x the extent.
  int opacity_reset_interval = 3000;  // 0 = never
  bool opacity_reset_in_fine = false;
  // [choice] 3DGS's screen rule (radius > 20 px) is off by default: it was tuned for ~1 MP
  // images, and at Panoptic's 640x360 it pruned the dome's wall Gaussians faster than
  // densification replaced them (measured: 185k -> 537 Gaussians, BENCHMARKS.md).
  double max_screen_radius = 0;         // pixels; 0 = no screen-size pruning
  double max_world_scale_fraction = 0.1;  // prune largest scale > this x extent; 0 = off
  size_t max_gaussians = 360000;   // densification stops adding beyond this (4DGaussians' cap)
  // [choice, not in 4DGaussians] prune, at every densification step, Gaussians whose canonical
  // centre is inside fewer than this many distinct training cameras' views (CountObservingCameras,
  // densify.h). 0 = off.
  int min_observing_cameras = 0;
};

struct RegularizerConfig {
  double plane_tv = 2e-4;
  double time_smoothness = 1e-3;
  double time_l1 = 1e-4;
};

// The view-volume sampler of atex/init.h (InitOptions::volume_*).
struct InitVolumeConfig {
  double far = 2.5;                // in median camera distances, when the dataset has no depth bounds
  bool uniform_depth = true;       // false: uniform in disparity
  double max_colour_spread = 0.03; // photo-consistency threshold (0 = off)
  int attempts_per_point = 1000;
};

// The multi-view stereo of init methods "mvs" and "mvs+hull" (atex/mvs.h MvsOptions;
// atex/init.h InitOptions::mvs_near/mvs_far). Its point count is init_points ("mvs") or
// the part of init_points that the hull does not take ("mvs+hull").
struct InitMvsConfig {
  int max_image_side = 320;          // stereo resolution: integer box downscale to this longer side
  double near = 0.2;                 // depth range in median camera distances to the scene centre
  double far = 2.5;                  //   (the dataset's depth bounds when it has them)
  int depth_planes = 0;              // fronto-parallel planes, uniform in inverse depth; 0 = as many as
  double plane_step_px = 1.0;        //   keep a neighbour's image of the plane within this many pixels
  int max_depth_planes = 512;        //   between planes, at most max_depth_planes
  int neighbors = 6;                 // neighbour cameras per reference
  int best_neighbors = 3;            // ZNCCs averaged per pixel (the rest may be occluded)
  int window_radius = 2;             // ZNCC window (2r + 1)^2
  double min_zncc = 0.5;
  double min_texture = 0.01;         // grey standard deviation over the window
  double max_cost_ratio = 0.9;       // (1 - best) / (1 - second best); 1 = off
  int min_consistent_views = 2;      // fusion: other cameras whose depths agree
  double max_reprojection_px = 1.0;
  double max_relative_depth = 0.01;
};

// Fast-object seeds (atex/transient_hull.h): time-local Gaussians added at the start of the
// fine stage, where the deformation field starts, from every timestep's visual hull.
// [not in 4DGaussians] Multi-view datasets with masks only (config_check refuses it elsewhere).
struct FastObjectsConfig {
  bool enabled = false;
  int points = 20000;          // seeds over all timesteps, at most
  int hull_resolution = 96;    // voxels along the longest side of the foreground box
  double max_presence = 0.25;  // a voxel is transient where the hull holds it in at most this share of timesteps
  double window_frames = 0.5;  // window width (1/k) in frame intervals
};

struct Stage1Config {
  int coarse_iterations = 3000;
  int fine_iterations = 14000;
  int batch_size = 4;
  // [choice, not in 4DGaussians, whose batches are random views] each fine-stage batch
  // takes its views from one time (TimeBatchSchedule, schedule.h), so the deformation
  // field runs once per step instead of once per view. false: random views (CameraSchedule).
  bool same_time_batches = true;
  double lambda_dssim = 0.2;
  int sh_degree = 3;
  int sh_increase_interval = 1000;
  LearningRates lr;
  DensifyConfig densify;
  RegularizerConfig regularizer;
  DeformationConfig deformation;  // grid/MLP shape; AABB and time mapping are set from the data
  // Initialisation (atex/init.h methods: "auto", "hull", "volume", "hull+volume", "cube", "mvs",
  // "mvs+hull", "file").
  std::string init_method = "auto";
  size_t init_points = 100000;            // "file": at most this many of the file's points (0 = all)
  double init_hull_fraction = 2.0 / 3.0;  // of init_points from the hull with "hull+volume" and "mvs+hull"
  InitVolumeConfig init_volume;
  InitMvsConfig init_mvs;
  std::string init_point_cloud;  // "file": PLY (x, y, z [, red/green/blue | f_dc_*]) or COLMAP points3D.txt/.bin
  FastObjectsConfig fast_objects;
};

struct GrowthAblations {
  bool temporal_peak = true;              // false: score = mean over bins only
  bool anisotropic = true;                // false: always (2h, 2w)
  bool visibility_normalization = true;   // false: per-bin SUM of demand instead of the mean over visible occurrences
};

struct Stage2Config {
  int iterations = 5000;
  int batch_size = 8;
  bool same_time_batches = false;  // as Stage1Config's; the paper's 8 workers draw random views
  double lambda_dssim = 0.2;
  TextureMode textures = TextureMode::kAdaptive;
  // The paper's steps of its 5,000 (10 % and 20 %). Scale them with a shortened `iterations`:
  // the trainer's report notes a last growth past half the schedule (BENCHMARKS.md, stage 2).
  std::vector<int> growth_steps{500, 1000};
  double growth_threshold = 2e-5;
  int time_bins = 8;
  double anisotropy_ratio = 4.0;     // s_u / s_v above this grows one axis only
  double anisotropy_max_scale = 0.01;  // ... and only when the short side is below this (world units)
  // Global texel budget as a fraction of what uniform 4x4 would use (16 texels per Gaussian).
  double texel_budget_fraction = 1.0;
  GrowthAblations ablations;
  // false (the paper): a grown texture's Adam moments are bilinear interpolations of the old
  // ones, like its texels. true [not in the paper]: they are then multiplied by a (m) and a² (v),
  // a = old texels / new texels, the share of the old texel's gradient that one new texel gets
  // when the gradient is spread evenly; otherwise the old v, kept for ~1/(1 − β2) = 1,000 steps,
  // may hold a grown texel's step at a fraction of the learning rate. Measured on Panoptic: no
  // gain on held-out views (BENCHMARKS.md, stage 2, seventh run), so off.
  bool rescale_grown_moments = false;
  // [choice] the 4DGS parameters continue at stage 1's final learning rates.
};

// Per-training-camera colour correction (atex/train/colour_correction.h, camera_colours.h).
// [not in 4DGaussians; Dynamic 3D Gaussians learn per-camera scale and offset on Panoptic]
struct CameraColourConfig {
  bool enabled = false;
  // Fitted from the current model at this stage-1 step (coarse steps count first; SH degree 0
  // until sh_increase_interval, so a camera's colour cast cannot yet hide in view-dependent
  // colour), then every `interval` steps of stage 1 (0: once). Stage 2 keeps the last fit.
  int first_step = 500;
  int interval = 2000;
  int views_per_camera = 3;  // frames per camera of each fit, evenly spaced in time
  double keep = 0.9;         // the fit's trimmed share of pixels (FitColourAffine)
};

struct TrainConfig {
  uint64_t seed = 6666;
  Stage1Config stage1;
  Stage2Config stage2;
  CameraColourConfig camera_colour;
  std::array<float, 3> background{0, 0, 0};
  float near_plane = kDefaultNearPlane;  // atex/render.h
  int eval_every = 1000;        // test-view evaluation during training (0 = only at the end)
  int eval_views = 16;          // test views (evenly spaced) of those evaluations; 0 = all. The final one uses all.
  int checkpoint_every = 2000;  // 0 = never
  // Data-parallel training (several ranks): false keeps each training image on its home rank's
  // device only (schedule.h, HomeRank), so a device holds about 1/R of the images and the GPUs
  // together cache R times as many; a view rendered away from home has its image copied in for
  // that step. true keeps every image a device draws, as one GPU does: more memory per GPU, no
  // such copies (basketball on 2 and 4 H100s: +8 % and +12 % views/s; BENCHMARKS.md, issue 25).
  // One rank: no effect.
  bool images_on_every_gpu = false;
};

// Defaults for a dataset kind ("panoptic", "dnerf", "n3dv"); unknown kinds get the generic defaults.
TrainConfig DefaultConfig(std::string_view dataset_kind);
// The name whose DefaultConfig a dataset of `kind` trains with: "panoptic", "n3dv", "dnerf" for
// both D-NeRF layouts and for the layouts whose frames each carry their own camera (nerfstudio
// transforms.json, COLMAP), "generic" otherwise. The CLI and the Python module both use it.
const char* DefaultConfigKind(DatasetKind kind);

nlohmann::json ConfigToJson(const TrainConfig& config);
// Reads a (possibly partial) JSON object on top of `base`; unknown keys are an error naming the key.
StatusOr<TrainConfig> ConfigFromJson(const nlohmann::json& json, const TrainConfig& base);
// Applies "a.b.c=value" (value parsed as JSON, or as a string when it is not valid JSON).
StatusOr<TrainConfig> ApplyOverride(const TrainConfig& config, std::string_view assignment);

}  // namespace atex::train
