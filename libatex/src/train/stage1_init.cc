#include "stage1_init.h"

#include <algorithm>
#include <cmath>

#include "atex/deform.h"
#include "atex/init.h"
#include "atex/transient_hull.h"
#include "atex/world_up.h"
#include "trained_asset.h"

namespace atex::train {
namespace {

// The stereo and file settings of stage 1 (init methods "mvs", "mvs+hull", "file"): the
// stereo takes the points the hull does not (all of init_points for "mvs").
void SetMvsInitOptions(const Stage1Config& s1, InitOptions* init) {
  const InitMvsConfig& c = s1.init_mvs;
  MvsOptions& m = init->mvs;
  m.max_image_side = c.max_image_side;
  m.depth_planes = c.depth_planes;
  m.plane_step_px = c.plane_step_px;
  m.max_depth_planes = c.max_depth_planes;
  m.neighbors = c.neighbors;
  m.best_neighbors = c.best_neighbors;
  m.window_radius = c.window_radius;
  m.min_zncc = c.min_zncc;
  m.min_texture = c.min_texture;
  m.max_cost_ratio = c.max_cost_ratio;
  m.min_consistent_views = c.min_consistent_views;
  m.max_reprojection_px = c.max_reprojection_px;
  m.max_relative_depth = c.max_relative_depth;
  init->mvs_near = c.near;
  init->mvs_far = c.far;
  init->point_cloud_path = s1.init_point_cloud;
  init->file_points = static_cast<int>(s1.init_points);
  if (s1.init_points > 0) {
    init->mvs_points = init->method == InitMethod::kMvs ? static_cast<int>(s1.init_points)
                                                        : static_cast<int>(s1.init_points) - init->hull_points;
  }
}

}  // namespace

StatusOr<Stage1Start> InitialStage1State(const Dataset& data, const TrainConfig& config) {
  Stage1Start start;
  const Stage1Config& s1 = config.stage1;
  InitOptions init;
  ATEX_ASSIGN_OR_RETURN(init.method, ParseInitMethod(s1.init_method));
  init.seed = config.seed;
  init.sh_degree = s1.sh_degree;
  if (!(s1.init_hull_fraction >= 0 && s1.init_hull_fraction <= 1)) {
    return MakeError(StatusCode::kInvalidArgument, "stage1.init_hull_fraction ", s1.init_hull_fraction,
                     " is outside [0, 1]");
  }
  if (s1.init_points > 0) {
    init.cube_points = static_cast<int>(s1.init_points);
    init.hull_points = static_cast<int>(std::lround(double(s1.init_points) * s1.init_hull_fraction));
    init.volume_points = static_cast<int>(s1.init_points) - init.hull_points;
  }
  init.volume_far = s1.init_volume.far;
  init.volume_uniform_depth = s1.init_volume.uniform_depth;
  init.volume_max_colour_spread = s1.init_volume.max_colour_spread;
  init.volume_attempts_per_point = s1.init_volume.attempts_per_point;
  SetMvsInitOptions(s1, &init);
  InitReport report;
  ATEX_ASSIGN_OR_RETURN(Gaussians gaussians, InitializeGaussians(data, init, &report));
  std::string detail = InitMethodName(report.method);
  if (report.method == InitMethod::kHullAndViewVolume || report.method == InitMethod::kViewVolume) {
    detail = StrCat(detail, ": ", report.hull_points, " hull, ", report.volume_points, " volume of ",
                    report.volume_candidates, " candidates");
  } else if (report.method == InitMethod::kMvs || report.method == InitMethod::kMvsAndHull) {
    detail = StrCat(detail, ": ", report.hull_points, " hull, ", report.mvs_points, " stereo of ",
                    report.mvs.fused_points, " fused, ", report.mvs.seconds_total, " s");
  } else if (report.method == InitMethod::kFile) {
    detail = StrCat(detail, ": ", report.file_points, " points of ",
                    s1.init_point_cloud.empty() ? data.point_cloud() : s1.init_point_cloud);
  }
  start.event = StrCat("initialised ", gaussians.size(), " Gaussians (", detail, ")");

  // The deformation field's AABB is the initial cloud's (4DGaussians), time spans [-1, 1].
  DeformationConfig dc = s1.deformation;
  dc.sh_coeffs = ShCoeffCount(s1.sh_degree);
  auto [lo, hi] = PositionBounds(gaussians);
  for (int k = 0; k < 3; ++k) {
    if (!(hi[k] > lo[k])) hi[k] = lo[k] + 1.0f;
  }
  dc.aabb_lo = lo;
  dc.aabb_hi = hi;
  const double span = data.time_max() - data.time_min();
  dc.time_scale = span > 0 ? static_cast<float>(2.0 / span) : 1.0f;
  dc.time_offset = span > 0 ? static_cast<float>(-1.0 - 2.0 * data.time_min() / span) : 0.0f;
  ATEX_ASSIGN_OR_RETURN(DeformationField field, InitDeformationField(dc, config.seed));

  start.metadata.bounds_min = lo;
  start.metadata.bounds_max = hi;
  start.metadata.time_min = data.time_min();
  start.metadata.time_max = data.time_max();
  start.metadata.background = config.background;
  {
    // The world's up axis as the training cameras agree on it (atex/world_up.h).
    std::vector<Camera> cameras;
    for (const auto& view : data.train_views()) cameras.push_back(view.camera);
    start.metadata.up = UpAxisFromCameras(cameras).value_or("");
  }
  start.state.gaussians = std::move(gaussians);
  start.state.deformation = std::move(field);
  ResetMoments(&start.state);
  return start;
}

StatusOr<std::string> AddFastObjectSeeds(const Dataset& data, const TrainConfig& config, Backend& backend) {
  const FastObjectsConfig& f = config.stage1.fast_objects;
  if (data.timestep_count() < 2) return std::string("no fast-object seeds: the dataset has one timestep");
  InitOptions init;
  init.seed = config.seed;
  init.sh_degree = config.stage1.sh_degree;
  TransientSeedOptions options;
  options.points = f.points;
  options.hull_resolution = f.hull_resolution;
  options.max_presence = f.max_presence;
  options.window_frames = f.window_frames;
  TransientSeedReport report;
  ATEX_ASSIGN_OR_RETURN(Gaussians seeds, TransientSeeds(data, init, options, &report));
  if (seeds.size() == 0) {  // nothing moves fast: the model stays as it is (and without windows)
    return StrCat("no fast-object seeds: ", report.transient, " transient (timestep, voxel) pairs of ",
                  report.timesteps, " timesteps");
  }

  ModelState state;
  ATEX_RETURN_IF_ERROR(backend.Save(&state));
  if (state.textures) {
    return MakeError(StatusCode::kInvalidArgument, "fast-object seeds are added in stage 1, before textures");
  }
  Gaussians& g = state.gaussians;
  if (seeds.sh_degree != g.sh_degree) {
    return MakeError(StatusCode::kInternal, "fast-object seeds of SH degree ", seeds.sh_degree, " for a model of ",
                     g.sh_degree);
  }
  const size_t old_count = g.size(), added = seeds.size();
  if (!g.has_time_windows()) g.time_windows.assign(old_count * 2, 0.0f);
  auto append = [](std::vector<float>& to, const std::vector<float>& from) {
    to.insert(to.end(), from.begin(), from.end());
  };
  append(g.positions, seeds.positions);
  append(g.rotations, seeds.rotations);
  append(g.log_scales, seeds.log_scales);
  append(g.opacity_logits, seeds.opacity_logits);
  append(g.sh, seeds.sh);
  append(g.time_windows, seeds.time_windows);
  for (Gaussians* moments : {&state.m_gaussians, &state.v_gaussians}) {
    moments->time_windows.clear();
    moments->Resize(old_count + added);  // new rows are zero: fresh Adam moments
  }
  ATEX_RETURN_IF_ERROR(backend.Load(state));
  return StrCat("added ", added, " fast-object seeds (time-local Gaussians) from ", report.transient,
                " transient (timestep, voxel) pairs of ", report.timesteps, " timesteps x ", report.voxels,
                " voxels; window 1/k = ", f.window_frames, " frames of ", report.frame_interval);
}

}  // namespace atex::train
