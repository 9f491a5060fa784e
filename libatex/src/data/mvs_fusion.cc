// Multi-view stereo, steps 5-6 of atex/mvs.h: geometric-consistency fusion of the depth
// maps and voxel-grid subsampling to a target count.
#include <algorithm>
#include <cmath>
#include <cstdint>

#include "data/mvs_internal.h"

namespace atex::mvs {
namespace {

// One fused reference pixel, before the per-reference lists are concatenated.
struct FusedPoint {
  float position[3];
  float colour[3];
  float reprojection;  // px, in the reference camera
};

// Fuses reference r's row y into `out`.
void FuseRow(const std::vector<Frame>& frames, const std::vector<std::vector<float>>& depths, int r, int y,
             const MvsOptions& o, std::vector<FusedPoint>* out) {
  const Frame& ref = frames[r];
  const double max_reproj_sq = o.max_reprojection_px * o.max_reprojection_px;
  for (int x = 0; x < ref.width; ++x) {
    const size_t p = size_t(y) * ref.width + x;
    const double d = depths[r][p];
    if (!(d > 0)) continue;
    double X[3];
    BackProject(ref.camera, x + 0.5, y + 0.5, d, X);
    double sum[3] = {X[0], X[1], X[2]};
    double colour[3] = {ref.rgb[3 * p], ref.rgb[3 * p + 1], ref.rgb[3 * p + 2]};
    int agreeing = 0;
    for (size_t s = 0; s < frames.size(); ++s) {
      if (int(s) == r) continue;
      const Frame& f = frames[s];
      double u, v;
      if (!ProjectToImage(f.camera, X, 1e-6, &u, &v)) continue;
      const int px = std::min(int(u), f.width - 1), py = std::min(int(v), f.height - 1);
      const size_t q = size_t(py) * f.width + px;
      const double ds = depths[s][q];
      if (!(ds > 0)) continue;
      double Y[3], Yr[3];
      BackProject(f.camera, px + 0.5, py + 0.5, ds, Y);
      ToCamera(ref.camera, Y, Yr);
      if (!(Yr[2] > 0) || std::abs(Yr[2] - d) > o.max_relative_depth * d) continue;
      const double du = ref.camera.fx * Yr[0] / Yr[2] + ref.camera.cx - (x + 0.5);
      const double dv = ref.camera.fy * Yr[1] / Yr[2] + ref.camera.cy - (y + 0.5);
      if (du * du + dv * dv > max_reproj_sq) continue;
      ++agreeing;
      for (int a = 0; a < 3; ++a) {
        sum[a] += Y[a];
        colour[a] += f.rgb[3 * q + a];
      }
    }
    if (agreeing < o.min_consistent_views) continue;
    FusedPoint point;
    const double count = agreeing + 1;
    double F[3], Fr[3];
    for (int a = 0; a < 3; ++a) {
      F[a] = sum[a] / count;
      point.position[a] = float(F[a]);
      point.colour[a] = float(colour[a] / count);
    }
    ToCamera(ref.camera, F, Fr);
    const double du = ref.camera.fx * Fr[0] / Fr[2] + ref.camera.cx - (x + 0.5);
    const double dv = ref.camera.fy * Fr[1] / Fr[2] + ref.camera.cy - (y + 0.5);
    point.reprojection = float(std::sqrt(du * du + dv * dv));
    out->push_back(point);
  }
}

uint64_t VoxelKey(const float* x, const double lo[3], double inv_size) {
  uint64_t key = 0;
  for (int a = 0; a < 3; ++a) {
    const uint64_t i = static_cast<uint64_t>(std::clamp((x[a] - lo[a]) * inv_size, 0.0, double((1 << 21) - 1)));
    key |= i << (21 * a);
  }
  return key;
}

size_t OccupiedVoxels(const PointCloud& cloud, const double lo[3], double size, std::vector<uint64_t>* keys) {
  const size_t n = cloud.size();
  keys->resize(n);
#pragma omp parallel for schedule(static)
  for (long long i = 0; i < static_cast<long long>(n); ++i)
    (*keys)[i] = VoxelKey(&cloud.positions[3 * i], lo, 1.0 / size);
  std::sort(keys->begin(), keys->end());
  return static_cast<size_t>(std::unique(keys->begin(), keys->end()) - keys->begin());
}

}  // namespace

PointCloud FuseDepthMaps(const std::vector<Frame>& frames, const std::vector<std::vector<float>>& depths,
                         const MvsOptions& options, MvsReport* report) {
  PointCloud cloud;
  std::vector<float> reprojections;
  report->fused_fraction.assign(frames.size(), 0.0);
  for (size_t r = 0; r < frames.size(); ++r) {
    const int h = frames[r].height;
    std::vector<std::vector<FusedPoint>> rows(h);
#pragma omp parallel for schedule(dynamic, 4)
    for (int y = 0; y < h; ++y) FuseRow(frames, depths, int(r), y, options, &rows[y]);
    size_t kept = 0;
    for (const auto& row : rows) {  // row order: deterministic for any thread count
      for (const FusedPoint& p : row) {
        cloud.positions.insert(cloud.positions.end(), p.position, p.position + 3);
        cloud.colours.insert(cloud.colours.end(), p.colour, p.colour + 3);
        reprojections.push_back(p.reprojection);
      }
      kept += row.size();
    }
    report->fused_fraction[r] = double(kept) / double(frames[r].pixels());
  }
  if (!reprojections.empty()) {
    std::nth_element(reprojections.begin(), reprojections.begin() + reprojections.size() / 2, reprojections.end());
    report->median_reprojection_px = reprojections[reprojections.size() / 2];
  }
  return cloud;
}

PointCloud VoxelSubsample(const PointCloud& cloud, size_t target, double* voxel_size) {
  *voxel_size = 0;
  const size_t n = cloud.size();
  if (n <= target || target == 0) return cloud;
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  for (size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], double(cloud.positions[3 * i + a]));
      hi[a] = std::max(hi[a], double(cloud.positions[3 * i + a]));
    }
  }
  const double extent = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1e-9});
  // Bisection in log space between a voxel too fine for the 21-bit keys and the whole box.
  double fine = extent / double((1 << 21) - 2), coarse = extent * 1.001;
  std::vector<uint64_t> keys;
  for (int iteration = 0; iteration < 30 && coarse / fine > 1.0001; ++iteration) {
    const double mid = std::sqrt(fine * coarse);
    if (OccupiedVoxels(cloud, lo, mid, &keys) <= target) {
      coarse = mid;
    } else {
      fine = mid;
    }
  }
  *voxel_size = coarse;
  // Per-voxel means, in key order.
  std::vector<std::pair<uint64_t, uint32_t>> order(n);
  for (size_t i = 0; i < n; ++i) order[i] = {VoxelKey(&cloud.positions[3 * i], lo, 1.0 / coarse), uint32_t(i)};
  std::sort(order.begin(), order.end());
  PointCloud out;
  const bool colours = cloud.has_colours();
  for (size_t i = 0; i < n;) {
    size_t j = i;
    double sum[6] = {0, 0, 0, 0, 0, 0};
    for (; j < n && order[j].first == order[i].first; ++j) {
      const size_t k = order[j].second;
      for (int a = 0; a < 3; ++a) {
        sum[a] += cloud.positions[3 * k + a];
        if (colours) sum[3 + a] += cloud.colours[3 * k + a];
      }
    }
    const double count = double(j - i);
    for (int a = 0; a < 3; ++a) out.positions.push_back(float(sum[a] / count));
    if (colours) {
      for (int a = 0; a < 3; ++a) out.colours.push_back(float(sum[3 + a] / count));
    }
    i = j;
  }
  return out;
}

}  // namespace atex::mvs
