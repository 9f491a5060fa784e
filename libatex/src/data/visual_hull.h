// Visual-hull carving shared by the initialisation (init.cc, first timestep) and the
// fast-object seeding (transient_hull.cc, every timestep). Not a public header.
#pragma once

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

#include "atex/camera.h"
#include "atex/dataset.h"
#include "atex/image.h"
#include "atex/init.h"

namespace atex::hull {

inline constexpr double kShC0 = 0.28209479177387814;

// Deterministic uniform numbers (the standard distributions are not portable).
class Rng {
 public:
  explicit Rng(uint64_t seed) : state_(seed ^ 0x9E3779B97F4A7C15ull) {}
  uint64_t Next() {  // splitmix64
    uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  double Uniform() { return double(Next() >> 11) * 0x1.0p-53; }  // [0, 1)
  double Uniform(double lo, double hi) { return lo + (hi - lo) * Uniform(); }
  size_t Index(size_t n) { return static_cast<size_t>(Uniform() * double(n)) % n; }

 private:
  uint64_t state_;
};

struct CameraImages {
  const View* view = nullptr;
  std::shared_ptr<const Image> image;  // [H][W][3]
  std::shared_ptr<const Image> mask;   // [H][W][1] in {0, 1}, or null
};

// Pixel hit by a world point, or false when behind the camera or outside the image.
inline bool Project(const Camera& cam, const double x[3], int* px, int* py) {
  double u, v;
  if (!ProjectToImage(cam, x, 1e-6, &u, &v)) return false;
  *px = static_cast<int>(u);
  *py = static_cast<int>(v);
  return true;
}

// Counts of the hull rule at a point: cameras that see it, and those whose mask contains it.
struct HullVotes {
  int seen = 0;
  int inside = 0;
};

inline HullVotes Vote(const std::vector<CameraImages>& cams, const double x[3]) {
  HullVotes votes;
  for (const CameraImages& c : cams) {
    int px, py;
    if (!Project(c.view->camera, x, &px, &py)) continue;
    ++votes.seen;
    if (c.mask && c.mask->at(px, py, 0) > 0.5f) ++votes.inside;
  }
  return votes;
}

inline bool InsideHull(const HullVotes& v, const InitOptions& o) {
  return v.seen >= o.min_views && v.inside >= o.hull_keep_fraction * v.seen - 1e-9;
}

struct Grid {
  std::array<double, 3> lo{}, voxel{};
  std::array<int, 3> dims{};
  std::vector<uint8_t> kept;  // [dims z][dims y][dims x]

  void Center(int i, int j, int k, double out[3]) const {
    out[0] = lo[0] + (i + 0.5) * voxel[0];
    out[1] = lo[1] + (j + 0.5) * voxel[1];
    out[2] = lo[2] + (k + 0.5) * voxel[2];
  }
};

inline Grid Carve(const std::array<double, 3>& lo, const std::array<double, 3>& hi, int resolution,
                  const std::vector<CameraImages>& cams, const InitOptions& options) {
  Grid grid;
  grid.lo = lo;
  const double longest = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
  for (int a = 0; a < 3; ++a) {
    grid.dims[a] = std::clamp(static_cast<int>(std::ceil((hi[a] - lo[a]) / longest * resolution)), 1, resolution);
    grid.voxel[a] = (hi[a] - lo[a]) / grid.dims[a];
  }
  const long long total = (long long)grid.dims[0] * grid.dims[1] * grid.dims[2];
  grid.kept.assign(total, 0);
#pragma omp parallel for schedule(dynamic, 256)
  for (long long index = 0; index < total; ++index) {
    const int i = static_cast<int>(index % grid.dims[0]);
    const int j = static_cast<int>((index / grid.dims[0]) % grid.dims[1]);
    const int k = static_cast<int>(index / (static_cast<long long>(grid.dims[0]) * grid.dims[1]));
    double x[3];
    grid.Center(i, j, k, x);
    grid.kept[index] = InsideHull(Vote(cams, x), options) ? 1 : 0;
  }
  return grid;
}

// Bounds of the kept voxels, grown by `margin` voxels and clipped to the grid. False if none is kept.
inline bool KeptBounds(const Grid& grid, int margin, std::array<double, 3>* lo, std::array<double, 3>* hi) {
  std::array<int, 3> mn{INT32_MAX, INT32_MAX, INT32_MAX}, mx{-1, -1, -1};
  for (int k = 0; k < grid.dims[2]; ++k) {
    for (int j = 0; j < grid.dims[1]; ++j) {
      for (int i = 0; i < grid.dims[0]; ++i) {
        if (!grid.kept[(size_t(k) * grid.dims[1] + j) * grid.dims[0] + i]) continue;
        const int c[3] = {i, j, k};
        for (int a = 0; a < 3; ++a) {
          mn[a] = std::min(mn[a], c[a]);
          mx[a] = std::max(mx[a], c[a]);
        }
      }
    }
  }
  if (mx[0] < 0) return false;
  for (int a = 0; a < 3; ++a) {
    (*lo)[a] = grid.lo[a] + std::max(0, mn[a] - margin) * grid.voxel[a];
    (*hi)[a] = grid.lo[a] + std::min(grid.dims[a], mx[a] + 1 + margin) * grid.voxel[a];
  }
  return true;
}

struct SceneFrame {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  double distance = 1;  // median camera distance to the centre
};

// The point nearest (least squares) to every optical axis, and the median
// camera distance to it. For near-parallel axes (forward-facing rigs) the
// centre is placed in front of the cameras at the middle of the depth bounds.
inline SceneFrame EstimateScene(const std::vector<CameraImages>& cams, const Dataset& dataset) {
  Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero(), mean_origin = Eigen::Vector3d::Zero(),
                  mean_axis = Eigen::Vector3d::Zero();
  for (const CameraImages& c : cams) {
    const auto& m = c.view->camera.world_to_camera;
    const auto center = c.view->camera.Center();
    const Eigen::Vector3d o(center[0], center[1], center[2]);
    const Eigen::Vector3d d = Eigen::Vector3d(m[8], m[9], m[10]).normalized();  // camera z axis in world
    const Eigen::Matrix3d p = Eigen::Matrix3d::Identity() - d * d.transpose();
    a += p;
    b += p * o;
    mean_origin += o;
    mean_axis += d;
  }
  mean_origin /= double(cams.size());
  SceneFrame scene;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(a);
  const Eigen::Vector3d values = eigen.eigenvalues();  // ascending
  if (cams.size() >= 2 && values[0] > 1e-3 * values[2]) {
    scene.center = a.ldlt().solve(b);
  } else {
    const auto bounds = dataset.depth_bounds();
    const double depth = bounds[1] > 0 ? 0.5 * (bounds[0] + bounds[1]) : 1.0;
    scene.center = mean_origin + depth * mean_axis.normalized();
  }
  std::vector<double> distances;
  for (const CameraImages& c : cams) {
    const auto center = c.view->camera.Center();
    distances.push_back((Eigen::Vector3d(center[0], center[1], center[2]) - scene.center).norm());
  }
  std::nth_element(distances.begin(), distances.begin() + distances.size() / 2, distances.end());
  scene.distance = std::max(distances[distances.size() / 2], 1e-6);
  return scene;
}

// Colours a point projects to. `want_mask`: 1 = only pixels inside masks, 0 = only
// outside, −1 = any (cameras without masks always count). Their mean, their RMS
// distance to the mean (0 for a point on a Lambertian surface seen without
// occlusion; large for a point in empty space, whose cameras see different
// things) and their number.
struct ColourSample {
  std::array<float, 3> mean{0.5f, 0.5f, 0.5f};
  double spread = 0;
  int count = 0;
};

inline ColourSample SampleColours(const std::vector<CameraImages>& cams, const double x[3], int want_mask) {
  double sum[3] = {0, 0, 0}, sum_sq = 0;
  int count = 0;
  for (const CameraImages& c : cams) {
    int px, py;
    if (!Project(c.view->camera, x, &px, &py)) continue;
    if (want_mask >= 0 && c.mask && (c.mask->at(px, py, 0) > 0.5f) != (want_mask == 1)) continue;
    for (int ch = 0; ch < 3; ++ch) {
      const double value = c.image->at(px, py, ch);
      sum[ch] += value;
      sum_sq += value * value;
    }
    ++count;
  }
  ColourSample out;
  out.count = count;
  if (count == 0) return out;
  double mean_sq = 0;
  for (int ch = 0; ch < 3; ++ch) {
    out.mean[ch] = static_cast<float>(sum[ch] / count);
    mean_sq += (sum[ch] / count) * (sum[ch] / count);
  }
  out.spread = std::sqrt(std::max(0.0, (sum_sq / count - mean_sq) / 3.0));
  return out;
}

// Mean colour of the pixels a point projects to (`want_mask` as SampleColours),
// falling back to any pixel, then to grey.
inline std::array<float, 3> MeanColour(const std::vector<CameraImages>& cams, const double x[3], int want_mask) {
  ColourSample c = SampleColours(cams, x, want_mask);
  if (c.count == 0 && want_mask >= 0) c = SampleColours(cams, x, -1);
  return c.count > 0 ? c.mean : std::array<float, 3>{0.5f, 0.5f, 0.5f};
}

}  // namespace atex::hull
