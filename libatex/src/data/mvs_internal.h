// Shared pieces of the multi-view stereo (mvs.cc: depth maps; mvs_fusion.cc: fusion and
// subsampling). Not a public header.
#pragma once

#include <array>
#include <vector>

#include "atex/camera.h"
#include "atex/mvs.h"

namespace atex::mvs {

// A camera at the MVS resolution with its grey and colour pixels.
struct Frame {
  Camera camera;
  int width = 0, height = 0;
  std::vector<float> grey;  // [H][W]
  std::vector<float> rgb;   // [H][W][3]
  std::array<double, 3> center{};

  size_t pixels() const { return size_t(width) * height; }
};

// Camera-space point of world point x (x_c = W·x + T).
inline void ToCamera(const Camera& cam, const double x[3], double out[3]) {
  const auto& m = cam.world_to_camera;
  for (int r = 0; r < 3; ++r) out[r] = m[4 * r] * x[0] + m[4 * r + 1] * x[1] + m[4 * r + 2] * x[2] + m[4 * r + 3];
}

// World point at `depth` (camera z) on the ray through continuous pixel position (u, v).
inline void BackProject(const Camera& cam, double u, double v, double depth, double out[3]) {
  const double pc[3] = {(u - cam.cx) / cam.fx * depth, (v - cam.cy) / cam.fy * depth, depth};
  const auto& m = cam.world_to_camera;
  for (int a = 0; a < 3; ++a) {
    out[a] = m[0 + a] * (pc[0] - m[3]) + m[4 + a] * (pc[1] - m[7]) + m[8 + a] * (pc[2] - m[11]);
  }
}

// Step 5 of atex/mvs.h: the fused points of every reference pixel with enough agreeing
// views (not subsampled). depths[c] is camera c's depth map [H][W], 0 = none.
PointCloud FuseDepthMaps(const std::vector<Frame>& frames, const std::vector<std::vector<float>>& depths,
                         const MvsOptions& options, MvsReport* report);

// Step 6: per-voxel means on the smallest cubic grid with at most `target` occupied voxels
// (the cloud unchanged when it has at most `target` points). *voxel_size = 0 then.
PointCloud VoxelSubsample(const PointCloud& cloud, size_t target, double* voxel_size);

}  // namespace atex::mvs
