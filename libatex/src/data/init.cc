// Initial Gaussians without a point cloud: visual hull, view volume, random
// cube (see atex/init.h for the methods and their parameters).
#include "atex/init.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <memory>

#include "data/init_sources.h"
#include "data/visual_hull.h"

namespace atex {
namespace {

using hull::CameraImages;
using hull::Carve;
using hull::Grid;
using hull::HullVotes;
using hull::InsideHull;
using hull::KeptBounds;
using hull::Project;
using hull::Vote;
using hull::Rng;
using hull::kShC0;
using hull::SceneFrame;
using hull::EstimateScene;
using hull::ColourSample;
using hull::SampleColours;
using hull::MeanColour;

constexpr int kCoarseResolution = 48;
constexpr int kAttemptsPerPoint = 50;


Status ValidateInitOptions(const InitOptions& o) {
  if (o.sh_degree < 0 || o.sh_degree > kMaxShDegree) {
    return MakeError(StatusCode::kInvalidArgument, "init: sh_degree ", o.sh_degree, " (0..3)");
  }
  if (o.min_views < 1 || o.hull_resolution < 4 || o.hull_resolution > 1024 || !(o.hull_keep_fraction > 0) ||
      o.hull_keep_fraction > 1 || o.hull_points < 0 || o.volume_points < 0 || o.cube_points < 0 ||
      o.volume_attempts_per_point < 1 || !(o.volume_far > 0.1) || !(o.volume_max_colour_spread >= 0) ||
      !(o.cube_half_extent > 0) || !(o.initial_opacity > 0 && o.initial_opacity < 1) || o.knn_neighbors < 1 ||
      o.knn_neighbors > 16 || o.mvs_points < 0 || !(o.mvs_near > 0) || !(o.mvs_far > o.mvs_near) ||
      o.file_points < 0) {
    return MakeError(
        StatusCode::kInvalidArgument,
        "init: options out of range (min_views >= 1, hull_resolution 4..1024, hull_keep_fraction (0, 1], "
        "point counts >= 0, volume_attempts_per_point >= 1, volume_far > 0.1, "
        "volume_max_colour_spread >= 0, cube_half_extent > 0, initial_opacity (0, 1), knn_neighbors 1..16, "
        "mvs_points >= 0, 0 < mvs_near < mvs_far, file_points >= 0)");
  }
  return Status::Ok();
}

}  // namespace

const char* InitMethodName(InitMethod method) {
  switch (method) {
    case InitMethod::kAuto: return "auto";
    case InitMethod::kVisualHull: return "hull";
    case InitMethod::kViewVolume: return "volume";
    case InitMethod::kHullAndViewVolume: return "hull+volume";
    case InitMethod::kRandomCube: return "cube";
    case InitMethod::kMvs: return "mvs";
    case InitMethod::kMvsAndHull: return "mvs+hull";
    case InitMethod::kFile: return "file";
  }
  return "?";
}

StatusOr<InitMethod> ParseInitMethod(const std::string& name) {
  for (InitMethod m : {InitMethod::kAuto, InitMethod::kVisualHull, InitMethod::kViewVolume,
                       InitMethod::kHullAndViewVolume, InitMethod::kRandomCube, InitMethod::kMvs,
                       InitMethod::kMvsAndHull, InitMethod::kFile}) {
    if (name == InitMethodName(m)) return m;
  }
  return MakeError(StatusCode::kInvalidArgument, "unknown init method '", name,
                   "' (auto, hull, volume, hull+volume, cube, mvs, mvs+hull, file)");
}

// The sampled points of an initialisation.
struct InitPoints {
  std::vector<float> positions;  // [N][3]
  std::vector<float> colours;    // [N][3]
};

// Points drawn inside the visual hull of the masked cameras (hull_points of them), coloured by
// the cameras that see them.
static Status AddHullPoints(const Dataset& dataset, const std::vector<CameraImages>& cams, const SceneFrame& scene,
                            const InitOptions& options, Rng& rng, InitReport& rep, InitPoints& out) {
  std::vector<float>& positions = out.positions;
  std::vector<float>& colours = out.colours;
  // Hull votes count only cameras with masks.
  std::vector<CameraImages> masked_cams;
  for (const CameraImages& c : cams) {
    if (c.mask) masked_cams.push_back(c);
  }
  const double r = scene.distance;
  std::array<double, 3> lo{scene.center[0] - r, scene.center[1] - r, scene.center[2] - r};
  std::array<double, 3> hi{scene.center[0] + r, scene.center[1] + r, scene.center[2] + r};
  const Grid coarse = Carve(lo, hi, kCoarseResolution, masked_cams, options);
  if (!KeptBounds(coarse, 1, &lo, &hi)) {
    return MakeError(StatusCode::kNotFound, dataset.name(),
                     ": init: the visual hull is empty (no voxel lies inside the masks of enough cameras)");
  }
  const Grid fine = Carve(lo, hi, options.hull_resolution, masked_cams, options);
  std::vector<size_t> kept;
  for (size_t i = 0; i < fine.kept.size(); ++i) {
    if (fine.kept[i]) kept.push_back(i);
  }
  if (kept.empty()) {
    return MakeError(StatusCode::kNotFound, dataset.name(), ": init: the refined visual hull is empty");
  }
  rep.hull_voxels = kept.size();
  for (int a = 0; a < 3; ++a) {
    rep.hull_box_min[a] = static_cast<float>(lo[a]);
    rep.hull_box_max[a] = static_cast<float>(hi[a]);
  }
  const long long max_attempts = (long long)kAttemptsPerPoint * options.hull_points;
  for (long long attempt = 0; attempt < max_attempts && rep.hull_points < size_t(options.hull_points); ++attempt) {
    const size_t index = kept[rng.Index(kept.size())];
    const int i = static_cast<int>(index % fine.dims[0]);
    const int j = static_cast<int>((index / fine.dims[0]) % fine.dims[1]);
    const int k = static_cast<int>(index / (size_t(fine.dims[0]) * fine.dims[1]));
    double x[3];
    fine.Center(i, j, k, x);
    for (int a = 0; a < 3; ++a) x[a] += (rng.Uniform() - 0.5) * fine.voxel[a];
    if (!InsideHull(Vote(masked_cams, x), options)) continue;
    const std::array<float, 3> colour = MeanColour(cams, x, 1);
    for (int a = 0; a < 3; ++a) {
      positions.push_back(static_cast<float>(x[a]));
      colours.push_back(colour[a]);
    }
    ++rep.hull_points;
  }
  return Status::Ok();
}

// The points of a point-cloud file (the dataset's or options.point_cloud_path), coloured by the
// file or, without colours, by the cameras.
static Status AddFilePoints(const Dataset& dataset, const std::vector<CameraImages>& cams, const InitOptions& options,
                            InitReport& rep, InitPoints& out) {
  std::vector<float>& positions = out.positions;
  std::vector<float>& colours = out.colours;
  InitOptions file_options = options;
  if (file_options.point_cloud_path.empty()) file_options.point_cloud_path = dataset.point_cloud();
  ATEX_ASSIGN_OR_RETURN(PointCloud cloud, FileInitCloud(file_options));
  for (size_t i = 0; i < cloud.size(); ++i) {
    const double x[3] = {cloud.positions[3 * i], cloud.positions[3 * i + 1], cloud.positions[3 * i + 2]};
    const std::array<float, 3> colour =
        cloud.has_colours() ? std::array<float, 3>{cloud.colours[3 * i], cloud.colours[3 * i + 1],
                                                   cloud.colours[3 * i + 2]}
                            : MeanColour(cams, x, -1);
    positions.insert(positions.end(), x, x + 3);
    colours.insert(colours.end(), colour.begin(), colour.end());
  }
  rep.file_points = cloud.size();
  return Status::Ok();
}

// Points drawn in the cameras' view volumes where the cameras agree on a colour (volume_points
// of them); points of the dataset's background colour only when too few others are found.
static void AddVolumePoints(const Dataset& dataset, const std::vector<CameraImages>& cams, const SceneFrame& scene,
                            int masked, const InitOptions& options, Rng& rng, InitReport& rep, InitPoints& out) {
  std::vector<float>& positions = out.positions;
  std::vector<float>& colours = out.colours;
  const auto bounds = dataset.depth_bounds();
  const double near = bounds[1] > 0 ? bounds[0] : 0.1 * scene.distance;
  const double far = bounds[1] > 0 ? bounds[1] : options.volume_far * scene.distance;
  // Candidates are drawn serially (deterministic) and judged in parallel, batch by batch.
  constexpr size_t kBatch = 16384;
  const long long max_attempts = (long long)options.volume_attempts_per_point * options.volume_points;
  std::vector<std::array<double, 3>> candidates;
  std::vector<ColourSample> samples;
  const std::array<float, 3> background = dataset.background();
  std::vector<std::pair<std::array<double, 3>, std::array<float, 3>>> background_like;  // (position, colour)
  long long drawn = 0;
  while (drawn < max_attempts && rep.volume_points < size_t(options.volume_points)) {
    const size_t batch = static_cast<size_t>(std::min<long long>(kBatch, max_attempts - drawn));
    candidates.resize(batch);
    for (auto& x : candidates) {
      const Camera& cam = cams[rng.Index(cams.size())].view->camera;
      const double u = rng.Uniform(0, cam.width), v = rng.Uniform(0, cam.height);
      const double depth = options.volume_uniform_depth ? rng.Uniform(near, far)
                                                        : 1.0 / rng.Uniform(1.0 / far, 1.0 / near);
      // Camera-space point at z = depth, then to world: x = Wᵀ(p − T).
      const double pc[3] = {(u - cam.cx) / cam.fx * depth, (v - cam.cy) / cam.fy * depth, depth};
      const auto& m = cam.world_to_camera;
      for (int a = 0; a < 3; ++a) {
        x[a] = m[0 + a] * (pc[0] - m[3]) + m[4 + a] * (pc[1] - m[7]) + m[8 + a] * (pc[2] - m[11]);
      }
    }
    drawn += static_cast<long long>(batch);
    samples.assign(batch, ColourSample{});
#pragma omp parallel for schedule(dynamic, 256)
    for (long long i = 0; i < static_cast<long long>(batch); ++i) {
      const HullVotes votes = Vote(cams, candidates[i].data());
      if (votes.seen < options.min_views) continue;
      if (masked >= options.min_views && InsideHull(votes, options)) continue;  // foreground: the hull's job
      samples[i] = SampleColours(cams, candidates[i].data(), masked > 0 ? 0 : -1);
    }
    for (size_t i = 0; i < batch && rep.volume_points < size_t(options.volume_points); ++i) {
      const ColourSample& c = samples[i];
      if (c.count < options.min_views) continue;
      if (options.volume_max_colour_spread > 0) {
        if (c.spread > options.volume_max_colour_spread) continue;
        // Consistently the dataset's background colour (empty space of a synthetic scene
        // on black): such points are used last, only when too few others are found.
        double distance_sq = 0;
        for (int a = 0; a < 3; ++a) distance_sq += (c.mean[a] - background[a]) * (c.mean[a] - background[a]);
        if (std::sqrt(distance_sq / 3.0) <= options.volume_max_colour_spread) {
          if (background_like.size() < size_t(options.volume_points)) {
            background_like.push_back({candidates[i], c.mean});
          }
          continue;
        }
      }
      for (int a = 0; a < 3; ++a) {
        positions.push_back(static_cast<float>(candidates[i][a]));
        colours.push_back(c.mean[a]);
      }
      ++rep.volume_points;
    }
  }
  for (size_t i = 0; i < background_like.size() && rep.volume_points < size_t(options.volume_points); ++i) {
    for (int a = 0; a < 3; ++a) {
      positions.push_back(static_cast<float>(background_like[i].first[a]));
      colours.push_back(background_like[i].second[a]);
    }
    ++rep.volume_points;
  }
  rep.volume_candidates = static_cast<size_t>(drawn);
}

StatusOr<Gaussians> InitializeGaussians(const Dataset& dataset, const InitOptions& options, InitReport* report) {
  ATEX_RETURN_IF_ERROR(ValidateInitOptions(options));
  InitReport local_report;
  InitReport& rep = report ? *report : local_report;
  rep = InitReport();

  // Training views of the first timestep (all training views for time-per-frame datasets).
  const std::vector<const View*> first_views = FirstTimestepViews(dataset.train_views());
  const bool multi_view = !first_views.empty() && first_views[0]->timestep >= 0 && first_views.size() >= 2;

  InitMethod method = options.method;
  if (method == InitMethod::kAuto) {
    method = !dataset.point_cloud().empty() ? InitMethod::kFile
             : !multi_view                ? InitMethod::kRandomCube
             : dataset.has_masks()      ? InitMethod::kHullAndViewVolume
                                        : InitMethod::kViewVolume;
  }
  rep.method = method;
  const bool use_hull = method == InitMethod::kVisualHull || method == InitMethod::kHullAndViewVolume ||
                        method == InitMethod::kMvsAndHull;
  const bool use_mvs = method == InitMethod::kMvs || method == InitMethod::kMvsAndHull;
  if (use_mvs && !multi_view) {
    return MakeError(StatusCode::kInvalidArgument, dataset.name(), ": init '", InitMethodName(method),
                     "' needs a multi-view dataset (several cameras at one timestep)");
  }
  const bool use_volume = method == InitMethod::kViewVolume || method == InitMethod::kHullAndViewVolume;
  Rng rng(options.seed);
  InitPoints points;
  std::vector<float>& positions = points.positions;
  std::vector<float>& colours = points.colours;

  if (method == InitMethod::kRandomCube) {
    const double h = options.cube_half_extent;
    for (int i = 0; i < options.cube_points; ++i) {
      for (int a = 0; a < 3; ++a) positions.push_back(static_cast<float>(rng.Uniform(-h, h)));
      for (int a = 0; a < 3; ++a) colours.push_back(static_cast<float>(rng.Uniform()));
    }
    rep.cube_points = options.cube_points;
  } else {
    if (first_views.empty()) return MakeError(StatusCode::kNotFound, dataset.name(), ": init: no training views");
    std::vector<CameraImages> cams;
    for (const View* v : first_views) {
      CameraImages c;
      c.view = v;
      ATEX_ASSIGN_OR_RETURN(c.image, dataset.LoadImage(*v));
      if (dataset.has_masks() && !v->mask.empty()) {
        ATEX_ASSIGN_OR_RETURN(c.mask, dataset.LoadMask(*v));
      }
      cams.push_back(std::move(c));
    }
    rep.cameras = static_cast<int>(cams.size());
    const int masked =
        static_cast<int>(std::count_if(cams.begin(), cams.end(), [](const auto& c) { return c.mask != nullptr; }));
    if (use_hull && masked < options.min_views) {
      return MakeError(StatusCode::kNotFound, dataset.name(), ": init: the visual hull needs masks in at least ",
                       options.min_views, " cameras of the first timestep, found ", masked);
    }
    const SceneFrame scene = EstimateScene(cams, dataset);
    rep.scene_center = {scene.center[0], scene.center[1], scene.center[2]};
    rep.camera_distance = scene.distance;

    if (use_hull) ATEX_RETURN_IF_ERROR(AddHullPoints(dataset, cams, scene, options, rng, rep, points));

    if (use_mvs) {
      std::vector<MvsView> views;
      for (const CameraImages& c : cams) views.push_back({c.view->camera, c.image});
      ATEX_ASSIGN_OR_RETURN(PointCloud cloud,
                            MvsInitCloud(views, dataset.depth_bounds(), scene.distance, options, &rep.mvs));
      positions.insert(positions.end(), cloud.positions.begin(), cloud.positions.end());
      colours.insert(colours.end(), cloud.colours.begin(), cloud.colours.end());
      rep.mvs_points = cloud.size();
    }

    if (method == InitMethod::kFile) ATEX_RETURN_IF_ERROR(AddFilePoints(dataset, cams, options, rep, points));

    if (use_volume) AddVolumePoints(dataset, cams, scene, masked, options, rng, rep, points);
  }

  const size_t n = positions.size() / 3;
  if (n == 0) {
    return MakeError(StatusCode::kNotFound, dataset.name(), ": init (", InitMethodName(method),
                     ") produced no points; check the cameras, masks and point counts");
  }
  Gaussians g;
  g.sh_degree = options.sh_degree;
  g.Resize(n);
  g.positions = positions;
  const std::vector<float> log_scales = NearestNeighborLogScales(positions, options.knn_neighbors);
  const float opacity_logit = static_cast<float>(std::log(options.initial_opacity / (1.0 - options.initial_opacity)));
  const int k = g.sh_coeffs();
  for (size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      g.log_scales[i * 3 + a] = log_scales[i];
      g.sh[i * k * 3 + a] = static_cast<float>((colours[i * 3 + a] - 0.5) / kShC0);
    }
    g.rotations[i * 4] = 1.0f;
    g.opacity_logits[i] = opacity_logit;
  }
  return g;
}

}  // namespace atex
