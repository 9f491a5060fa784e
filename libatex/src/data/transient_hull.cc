// Fast-object seeds from per-timestep visual hulls (atex/transient_hull.h).
#include "atex/transient_hull.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <vector>

#include "data/visual_hull.h"

namespace atex {
namespace {

constexpr int kCoarseResolution = 48;
constexpr int kAttemptsPerPoint = 20;

Status ValidateOptions(const InitOptions& init, const TransientSeedOptions& o) {
  if (o.points < 0 || o.hull_resolution < 4 || o.hull_resolution > 512 || !(o.max_presence > 0) ||
      !(o.max_presence < 1) || !(o.window_frames > 0) || !std::isfinite(o.window_frames) || init.min_views < 1 ||
      !(init.hull_keep_fraction > 0) || init.hull_keep_fraction > 1 ||
      !(init.initial_opacity > 0 && init.initial_opacity < 1) || init.knn_neighbors < 1 || init.knn_neighbors > 16 ||
      init.sh_degree < 0 || init.sh_degree > kMaxShDegree) {
    return MakeError(StatusCode::kInvalidArgument,
                     "fast-object seeds: options out of range (points >= 0, hull_resolution 4..512, max_presence "
                     "in (0, 1), window_frames > 0, and the init's min_views, hull_keep_fraction, "
                     "initial_opacity, knn_neighbors, sh_degree)");
  }
  return Status::Ok();
}

struct Timestep {
  double time = 0;
  std::vector<hull::CameraImages> cams;  // masked training views of this timestep
};

// The masked training views of `dataset` by timestep, those with at least init.min_views of
// them; at least two such timesteps, and the median interval between them (rep.timesteps,
// rep.frame_interval).
StatusOr<std::vector<Timestep>> MaskedTimesteps(const Dataset& dataset, const InitOptions& init,
                                                TransientSeedReport& rep) {
  std::map<int, Timestep> by_step;
  for (const View& v : dataset.train_views()) {
    if (v.timestep < 0) {
      return MakeError(StatusCode::kInvalidArgument, dataset.name(),
                       ": fast-object seeds need a multi-view dataset with timesteps");
    }
    if (v.mask.empty() || !dataset.has_masks()) continue;
    hull::CameraImages c;
    c.view = &v;
    ATEX_ASSIGN_OR_RETURN(c.image, dataset.LoadImage(v));
    ATEX_ASSIGN_OR_RETURN(c.mask, dataset.LoadMask(v));
    Timestep& step = by_step[v.timestep];
    step.time = v.camera.time;
    step.cams.push_back(std::move(c));
  }
  std::vector<Timestep> steps;
  for (auto& [index, step] : by_step) {
    if (static_cast<int>(step.cams.size()) >= init.min_views) steps.push_back(std::move(step));
  }
  rep.timesteps = static_cast<int>(steps.size());
  if (steps.size() < 2) {
    return MakeError(StatusCode::kNotFound, dataset.name(), ": fast-object seeds need at least two timesteps with ",
                     init.min_views, " masked training views, found ", steps.size());
  }
  std::vector<double> intervals;
  for (size_t s = 1; s < steps.size(); ++s) intervals.push_back(std::abs(steps[s].time - steps[s - 1].time));
  std::nth_element(intervals.begin(), intervals.begin() + intervals.size() / 2, intervals.end());
  rep.frame_interval = intervals[intervals.size() / 2];
  if (!(rep.frame_interval > 0)) {
    return MakeError(StatusCode::kInvalidArgument, dataset.name(), ": timesteps share one time");
  }
  return steps;
}

// The seeds as Gaussians: positions[s] and colours[s] [n_s][3] of timestep s, each seed
// present around its timestep's time (a time window of options.window_frames frames).
Gaussians SeedGaussians(const std::vector<Timestep>& steps, const std::vector<std::vector<float>>& positions,
                        const std::vector<std::vector<float>>& colours, size_t made, const InitOptions& init,
                        const TransientSeedOptions& options, const TransientSeedReport& rep) {
  Gaussians g;
  g.sh_degree = init.sh_degree;
  g.time_windows.assign(2, 0.0f);  // present, so that Resize keeps it
  g.Resize(made);
  const float logit = float(std::log(init.initial_opacity / (1.0 - init.initial_opacity)));
  const float inverse_width = float(1.0 / (options.window_frames * rep.frame_interval));
  const int coeffs = g.sh_coeffs();
  size_t row = 0;
  for (size_t s = 0; s < steps.size(); ++s) {
    const std::vector<float> log_scales = NearestNeighborLogScales(positions[s], init.knn_neighbors);
    for (size_t p = 0; p < positions[s].size() / 3; ++p, ++row) {
      std::copy_n(&positions[s][3 * p], 3, &g.positions[3 * row]);
      for (int a = 0; a < 3; ++a) {
        g.log_scales[3 * row + a] = log_scales[p];
        g.sh[row * coeffs * 3 + a] = float((colours[s][3 * p + a] - 0.5) / hull::kShC0);
      }
      g.rotations[4 * row] = 1.0f;
      g.opacity_logits[row] = logit;
      g.time_windows[2 * row] = float(steps[s].time);
      g.time_windows[2 * row + 1] = inverse_width;
    }
  }
  return g;
}

}  // namespace

StatusOr<Gaussians> TransientSeeds(const Dataset& dataset, const InitOptions& init, const TransientSeedOptions& options,
                                   TransientSeedReport* report) {
  ATEX_RETURN_IF_ERROR(ValidateOptions(init, options));
  TransientSeedReport local;
  TransientSeedReport& rep = report ? *report : local;
  rep = TransientSeedReport();

  ATEX_ASSIGN_OR_RETURN(std::vector<Timestep> steps, MaskedTimesteps(dataset, init, rep));

  // The union of the per-timestep foreground boxes (coarse carves in the cameras' scene box).
  const hull::SceneFrame scene = hull::EstimateScene(steps[0].cams, dataset);
  const double r = scene.distance;
  const std::array<double, 3> scene_lo{scene.center[0] - r, scene.center[1] - r, scene.center[2] - r};
  const std::array<double, 3> scene_hi{scene.center[0] + r, scene.center[1] + r, scene.center[2] + r};
  std::array<double, 3> lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  for (const Timestep& step : steps) {
    const hull::Grid coarse = hull::Carve(scene_lo, scene_hi, kCoarseResolution, step.cams, init);
    std::array<double, 3> step_lo, step_hi;
    if (!hull::KeptBounds(coarse, 1, &step_lo, &step_hi)) continue;
    for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], step_lo[a]), hi[a] = std::max(hi[a], step_hi[a]);
  }
  if (!(lo[0] < hi[0])) return Gaussians{init.sh_degree};  // no foreground at any time

  // Per-timestep hulls on one fine grid, and each voxel's presence.
  std::vector<hull::Grid> grids;
  for (const Timestep& step : steps) grids.push_back(hull::Carve(lo, hi, options.hull_resolution, step.cams, init));
  const size_t voxels = grids[0].kept.size();
  rep.voxels = voxels;
  for (int a = 0; a < 3; ++a) rep.box_min[a] = float(lo[a]), rep.box_max[a] = float(hi[a]);
  std::vector<uint16_t> presence(voxels, 0);
  for (const hull::Grid& g : grids) {
    for (size_t v = 0; v < voxels; ++v) presence[v] += g.kept[v];
  }
  const double most = options.max_presence * double(steps.size());
  std::vector<std::pair<uint32_t, uint32_t>> transient;  // (timestep, voxel)
  for (size_t s = 0; s < grids.size(); ++s) {
    for (size_t v = 0; v < voxels; ++v) {
      if (grids[s].kept[v] && presence[v] <= most + 1e-9) transient.emplace_back(uint32_t(s), uint32_t(v));
    }
  }
  rep.transient = transient.size();
  if (transient.empty() || options.points == 0) return Gaussians{init.sh_degree};

  // Seeds: uniform over the pairs, jittered in the voxel, re-tested at their timestep.
  hull::Rng rng(init.seed ^ 0x7A11D5EEDull);
  std::vector<std::vector<float>> positions(steps.size()), colours(steps.size());
  const hull::Grid& grid = grids[0];
  const long long attempts = (long long)kAttemptsPerPoint * options.points;
  size_t made = 0;
  for (long long attempt = 0; attempt < attempts && made < size_t(options.points); ++attempt) {
    const auto [s, index] = transient[rng.Index(transient.size())];
    const int i = static_cast<int>(index % grid.dims[0]);
    const int j = static_cast<int>((index / grid.dims[0]) % grid.dims[1]);
    const int k = static_cast<int>(index / (size_t(grid.dims[0]) * grid.dims[1]));
    double x[3];
    grid.Center(i, j, k, x);
    for (int a = 0; a < 3; ++a) x[a] += (rng.Uniform() - 0.5) * grid.voxel[a];
    if (!hull::InsideHull(hull::Vote(steps[s].cams, x), init)) continue;
    const std::array<float, 3> colour = hull::MeanColour(steps[s].cams, x, 1);
    for (int a = 0; a < 3; ++a) {
      positions[s].push_back(float(x[a]));
      colours[s].push_back(colour[a]);
    }
    ++made;
  }

  Gaussians g = SeedGaussians(steps, positions, colours, made, init, options, rep);
  rep.seeds = made;
  return g;
}

}  // namespace atex
