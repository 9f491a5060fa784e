// Multi-view stereo on CMU Panoptic basketball's first timestep (atex/mvs.h, the
// initialisation "mvs"): time, fused points, median reprojection error, and how much
// of each training and test camera the fused cloud covers (PointCoverage at the
// stereo resolution, before subsampling to the 30,000 points of the init).
//   build/bench/bench_mvs [--benchmark_format=json]
//   MVS_SIDE=320 (stereo resolution), MVS_POINTS=30000, MVS_PLY=FILE (writes the subsampled
//   cloud), $ATEX_DATA_DIR (default ../shared/data)
// Counters: points (after subsampling), fused (before), reproj_px (median), planes
// (mean per camera), depth/fused fraction (mean over cameras), coverage of the training
// cameras (mean, min) and of each test camera (test_<id>), for the fused and for the
// subsampled cloud.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "atex/dataset.h"
#include "atex/mvs.h"

namespace {

int EnvInt(const char* name, int fallback) {
  const char* v = std::getenv(name);
  return v && *v ? std::atoi(v) : fallback;
}

void BM_MvsPanopticFirstTimestep(benchmark::State& state) {
  const char* env = std::getenv("ATEX_DATA_DIR");
  const std::filesystem::path root = std::filesystem::path(env ? env : "../shared/data") / "panoptic_basketball";
  if (!std::filesystem::exists(root / "train_meta.json")) {
    state.SkipWithError("Panoptic data not found (set ATEX_DATA_DIR)");
    return;
  }
  atex::DatasetOptions dopt;
  dopt.max_timesteps = 1;
  auto dataset = atex::OpenDataset(root.string(), dopt);
  if (!dataset.ok()) {
    state.SkipWithError(dataset.status().ToString().c_str());
    return;
  }
  std::vector<atex::MvsView> views;
  for (const atex::View* v : atex::FirstTimestepViews((*dataset)->train_views())) {
    auto image = (*dataset)->LoadImage(*v);
    if (!image.ok()) {
      state.SkipWithError(image.status().ToString().c_str());
      return;
    }
    views.push_back({v->camera, *image});
  }
  // The init's depth range: [0.2, 2.5] x the median camera distance to the point nearest
  // to all optical axes (atex/init.h); here the camera distance to the cameras' mean, a
  // close stand-in on the dome.
  std::array<double, 3> mean{0, 0, 0};
  for (const auto& v : views) {
    const auto c = v.camera.Center();
    for (int a = 0; a < 3; ++a) mean[a] += c[a] / views.size();
  }
  std::vector<double> distances;
  for (const auto& v : views) {
    const auto c = v.camera.Center();
    distances.push_back(std::hypot(c[0] - mean[0], c[1] - mean[1], c[2] - mean[2]));
  }
  std::nth_element(distances.begin(), distances.begin() + distances.size() / 2, distances.end());
  const double d = distances[distances.size() / 2];
  atex::MvsOptions options;
  options.max_image_side = EnvInt("MVS_SIDE", 320);
  options.near_depth = 0.2 * d;
  options.far_depth = 2.5 * d;
  atex::MvsReport report;
  atex::PointCloud fused, cloud;
  for (auto _ : state) {
    options.target_points = 0;
    auto all = atex::MultiViewStereo(views, options, &report);
    if (!all.ok()) {
      state.SkipWithError(all.status().ToString().c_str());
      return;
    }
    fused = std::move(*all);
  }
  options.target_points = static_cast<size_t>(EnvInt("MVS_POINTS", 30000));
  cloud = *atex::MultiViewStereo(views, options);
  if (const char* ply = std::getenv("MVS_PLY"); ply && *ply) (void)atex::WritePlyPoints(ply, cloud);
  state.counters["fused"] = double(fused.size());
  state.counters["points"] = double(cloud.size());
  state.counters["reproj_px"] = report.median_reprojection_px;
  double planes = 0, depth = 0, kept = 0;
  for (int c = 0; c < report.cameras; ++c) {
    planes += report.depth_planes[c] / double(report.cameras);
    depth += report.depth_fraction[c] / report.cameras;
    kept += report.fused_fraction[c] / report.cameras;
  }
  state.counters["planes"] = planes;
  state.counters["depth_frac"] = depth;
  state.counters["fused_frac"] = kept;
  state.counters["depth_s"] = report.seconds_depth;
  state.counters["fusion_s"] = report.seconds_fusion;
  for (const auto& [name, points] : {std::pair{std::string("cov"), &fused}, std::pair{std::string("cov30k"), &cloud}}) {
    double sum = 0, low = 1;
    for (const auto& v : views) {
      const double c = atex::PointCoverage(points->positions, v.camera, options.max_image_side);
      sum += c / views.size();
      low = std::min(low, c);
    }
    state.counters[name + "_train_mean"] = sum;
    state.counters[name + "_train_min"] = low;
    for (const atex::View& v : (*dataset)->test_views()) {
      state.counters[name + "_test_" + std::to_string(v.camera_id)] =
          atex::PointCoverage(points->positions, v.camera, options.max_image_side);
    }
  }
}
BENCHMARK(BM_MvsPanopticFirstTimestep)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
