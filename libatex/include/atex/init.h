// Initial Gaussians: from the dataset's images (visual hull, view volume, multi-view
// stereo), from an external point cloud, or a random cube.
//
// Methods (InitMethod):
//   kVisualHull   Carve a voxel grid with the foreground masks of the training
//                 cameras at the first timestep: a voxel is kept when it projects
//                 into at least `min_views` images and lies inside the mask in at
//                 least `hull_keep_fraction` of them. The carving box comes from
//                 the cameras (the point nearest to all optical axes ± the median
//                 camera distance), refined by a coarse pass to the kept voxels'
//                 bounds. Points are sampled uniformly in kept voxels and re-tested
//                 with the same rule.
//   kViewVolume   Random points in the volume the cameras see: a random training
//                 camera, a random pixel and a random depth (uniform in depth, or
//                 in disparity, between 0.1·D and volume_far·D, D = the median
//                 camera distance to the scene centre, or the dataset's depth
//                 bounds when it has them), kept when at least `min_views` cameras
//                 see it and the colours they see agree: the RMS distance of those
//                 colours to their mean is at most volume_max_colour_spread
//                 (photo-consistency, as in voxel colouring: a point on a surface
//                 looks alike from every camera, a point in empty space does not;
//                 occlusion is ignored), and whose mean colour is not the
//                 dataset's background colour (within the same threshold: such a
//                 point is empty space of a scene on a plain background; these
//                 fill up only when too few other points are found). With masks,
//                 points that pass the hull rule are rejected (they are foreground)
//                 and colours come from pixels outside the masks (background).
//                 Without the consistency test most
//                 points would float in empty space, where training turns them into
//                 view-specific floaters (on Panoptic: −2.7 dB on held-out cameras
//                 after 300 steps, BENCHMARKS.md).
//   kHullAndViewVolume  Both (the default for multi-view datasets with masks,
//                 e.g. Panoptic: people from the hull, the studio from the volume).
//   kRandomCube   Uniform points in [−h, h]³ (h = cube_half_extent, 1.3 for the
//                 D-NeRF synthetic scenes as 4DGaussians uses) with uniformly
//                 random colours: the default for monocular datasets (D-NeRF,
//                 the lego .npz), whose single moving camera cannot carve a hull.
//   kMvs          Multi-view stereo (atex/mvs.h) on the first-timestep training
//                 images: plane sweep with windowed ZNCC, depth fusion by geometric
//                 consistency, voxel subsampling to mvs_points. Covers every textured
//                 surface the cameras see (floor, walls, people), with its colours.
//                 Depth range: the dataset's depth bounds, else [mvs_near·D,
//                 mvs_far·D] with D the median camera distance to the scene centre.
//                 Multi-view datasets only (kInvalidArgument otherwise).
//   kMvsAndHull   kMvs plus the visual hull (hull_points), for people that the
//                 stereo misses (thin limbs, low texture). Needs masks.
//   kFile         An external point cloud (point_cloud_path: PLY, COLMAP
//                 points3D.txt/.bin; atex/point_cloud.h), at most file_points of
//                 them (an evenly spaced subset when larger; 0 = all). Points without
//                 colours get the mean colour of the pixels they project to.
//                 With no point_cloud_path, the dataset's own point cloud
//                 (Dataset::point_cloud(): COLMAP points3D, nerfstudio ply_file_path).
//   kAuto         kFile with the dataset's point cloud when it has one (COLMAP,
//                 nerfstudio with ply_file_path), else kHullAndViewVolume if the
//                 dataset is multi-view with masks, kViewVolume if multi-view without
//                 masks (N3DV), else kRandomCube.
//
// Every Gaussian gets: colour = the mean of the pixels it projects to in the
// first-timestep training images (hull and volume points, file points without
// colours; the fused colour for stereo points, the file's colour where it has one;
// random for the cube),
// SH DC = (colour − 0.5)/C0 with higher coefficients zero; log-scale = log of
// the RMS distance to its 3 nearest neighbours (3DGS; squared distances clamped
// below at 1e-7), the same on all three axes; rotation identity (1, 0, 0, 0);
// opacity logit(initial_opacity). The result is a deterministic function of the
// dataset and the options (seed).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "atex/dataset.h"
#include "atex/model.h"
#include "atex/mvs.h"
#include "atex/status.h"

namespace atex {

enum class InitMethod { kAuto, kVisualHull, kViewVolume, kHullAndViewVolume, kRandomCube, kMvs, kMvsAndHull, kFile };

// "auto", "hull", "volume", "hull+volume", "cube", "mvs", "mvs+hull", "file".
const char* InitMethodName(InitMethod method);
StatusOr<InitMethod> ParseInitMethod(const std::string& name);

struct InitOptions {
  InitMethod method = InitMethod::kAuto;
  uint64_t seed = 6666;
  int sh_degree = 3;                // of the returned Gaussians (0..3)
  int min_views = 3;                // cameras that must see a hull voxel / volume point
  // Visual hull.
  int hull_resolution = 128;        // voxels along the longest side of the refined box
  double hull_keep_fraction = 0.9;  // of the cameras that see a voxel, inside their masks
  int hull_points = 60000;
  // View volume.
  int volume_points = 30000;
  int volume_attempts_per_point = 1000;    // candidates drawn per wanted point, at most
  double volume_far = 2.5;                 // farthest depth, in median camera distances (no depth bounds)
  bool volume_uniform_depth = true;        // false: uniform in disparity (denser near the cameras)
  double volume_max_colour_spread = 0.03;  // photo-consistency: reject points whose colours spread more (0 = off)
  // Multi-view stereo. mvs.near_depth/far_depth are set from the scene (below); the
  // other fields of `mvs` are used as given, target_points = mvs_points.
  int mvs_points = 30000;
  double mvs_near = 0.2;  // in median camera distances D (no depth bounds)
  double mvs_far = 2.5;
  MvsOptions mvs;
  // External point cloud.
  std::string point_cloud_path;
  int file_points = 0;    // 0 = every point of the file
  // Random cube.
  float cube_half_extent = 1.3f;
  int cube_points = 100000;
  float initial_opacity = 0.1f;     // in (0, 1)
  int knn_neighbors = 3;            // for the initial scales (1..16)
};

// What InitializeGaussians did (for logs and tests).
struct InitReport {
  InitMethod method = InitMethod::kAuto;  // the method actually used
  int cameras = 0;                        // training views of the first timestep used
  size_t hull_voxels = 0;                 // kept voxels of the refined grid
  std::array<float, 3> hull_box_min{0, 0, 0}, hull_box_max{0, 0, 0};
  size_t hull_points = 0, volume_points = 0, cube_points = 0;
  size_t volume_candidates = 0;  // view-volume candidates drawn (accepted or not)
  size_t mvs_points = 0, file_points = 0;
  MvsReport mvs;                 // filled by kMvs / kMvsAndHull
  std::array<double, 3> scene_center{0, 0, 0};  // nearest point to the optical axes (multi-view)
  double camera_distance = 0;                    // median camera distance to scene_center
};

StatusOr<Gaussians> InitializeGaussians(const Dataset& dataset, const InitOptions& options = {},
                                        InitReport* report = nullptr);

// log(sqrt(mean squared distance to the k nearest other points)) per point,
// through a k-d tree (O(N log N)); squared distances are clamped below at 1e-7.
// positions: [N][3]; returns [N]. With fewer than k+1 points the available
// neighbours are used; a lone point gets the clamp value, log(sqrt(1e-7)).
std::vector<float> NearestNeighborLogScales(const std::vector<float>& positions, int k = 3);

}  // namespace atex
