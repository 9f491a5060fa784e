// Multi-view stereo from calibrated cameras: a coloured point cloud of every textured
// surface the cameras see (floor, walls, people), for the initialisation (atex/init.h,
// methods "mvs" and "mvs+hull"). CPU with OpenMP; no CUDA.
//
// 1. Images are box-downscaled by the smallest integer factor that brings their longer
//    side to at most max_image_side (intrinsics scaled to match, image.h DownscaleImage),
//    and turned to grey (0.299 R + 0.587 G + 0.114 B).
// 2. Neighbours: for each reference camera, an anchor point on its optical axis (the
//    median, over the other cameras, of the depth of the axes' closest approach; clamped
//    to [near, far]); every other camera that sees the anchor, whose optical axis is
//    within 80° of the reference's, and whose triangulation angle at the anchor lies in
//    [min_angle_deg, max_angle_deg] is scored by exp(−(θ − preferred_angle_deg)²/(2σ²))
//    (σ = preferred/2 below the preferred angle, = preferred above it); the best
//    `neighbors` are used.
// 3. Plane sweep: fronto-parallel planes of the reference camera, uniform in inverse depth
//    over [near_depth, far_depth]: `depth_planes` of them, or with depth_planes = 0 as many
//    as make the anchor's image in the neighbours move by at most plane_step_px from one
//    plane to the next (so a match is never stepped over; in [16, max_depth_planes]). Each neighbour image is warped
//    onto the plane by its homography (bilinear); photo-consistency is the ZNCC of the grey values over a
//    (2·window_radius + 1)² window (box sums), −1 where the window leaves the neighbour or the warped window is flat. A
//    pixel's score at a plane is the mean of its best `best_neighbors` ZNCCs (occlusion: the others may see something
//    else).
// 4. Winner takes all, with the depth refined by a parabola through the scores of the
//    neighbouring planes (in inverse depth). A depth is kept when the score is at least
//    min_zncc, the reference window's grey standard deviation is at least min_texture,
//    the winner is not on the first or last plane, and the cost ratio (1 − best)/(1 −
//    second best), the second best taken more than 2 planes away, is at most
//    max_cost_ratio (an ambiguous match is dropped).
// 5. Fusion: a reference pixel's point X is projected into every other camera; where that
//    camera has a depth at the pixel hit, its point Y is projected back into the
//    reference, and the two agree when Y lands within max_reprojection_px of the pixel
//    centre and its depth is within max_relative_depth (relative) of the reference's.
//    The pixel is kept when at least min_consistent_views other cameras agree; its point
//    is the mean of X and the agreeing Ys, its colour the mean of their pixels' colours.
// 6. Subsampling: when more than target_points points are fused, they are averaged per
//    voxel of a cubic grid whose voxel size is the smallest (bisection in log space) that
//    leaves at most target_points occupied voxels.
// The result is a deterministic function of the inputs and options.
#pragma once

#include <functional>
#include <memory>
#include <vector>

#include "atex/camera.h"
#include "atex/image.h"
#include "atex/point_cloud.h"
#include "atex/status.h"

namespace atex {

struct MvsOptions {
  int max_image_side = 320;          // longer side after the integer box downscale
  double near_depth = 0;             // world units, > 0 (required)
  double far_depth = 0;              // world units, > near_depth (required)
  int depth_planes = 0;              // 0 = from plane_step_px
  double plane_step_px = 1.0;
  int max_depth_planes = 512;
  int neighbors = 6;                 // neighbour cameras per reference (1..16)
  int best_neighbors = 3;            // ZNCCs averaged per pixel and plane (1..neighbors)
  double min_angle_deg = 3;          // triangulation angle at the anchor, neighbour selection
  double preferred_angle_deg = 15;
  double max_angle_deg = 60;
  int window_radius = 2;             // ZNCC window (2r + 1)², r in 1..5
  double min_zncc = 0.5;
  double min_texture = 0.01;         // grey standard deviation over the window, images in [0, 1]
  double max_cost_ratio = 0.9;       // (0, 1]; 1 = off
  int min_consistent_views = 2;      // other cameras whose depth maps agree (>= 1)
  double max_reprojection_px = 1.0;  // at the MVS resolution
  double max_relative_depth = 0.01;
  size_t target_points = 0;          // 0 = keep every fused point
  bool keep_depth_maps = false;      // return the step-4 depth maps in MvsReport (tests, inspection)
};

// One calibrated image: RGB [H][W][3] in [0, 1] of the camera's size.
struct MvsView {
  Camera camera;
  std::shared_ptr<const Image> image;
};

struct MvsReport {
  int cameras = 0;
  int width = 0, height = 0;                 // MVS resolution of the first camera
  int downscale = 1;                         // the integer factor of step 1 (first camera)
  std::vector<std::vector<int>> neighbours;  // [camera] the chosen neighbour indices
  std::vector<int> depth_planes;             // [camera] planes swept
  std::vector<double> depth_fraction;        // [camera] pixels with a kept depth (step 4)
  std::vector<double> fused_fraction;        // [camera] pixels kept by fusion (step 5)
  std::vector<std::vector<float>> depth_maps;  // [camera][H][W] camera z, 0 = none (keep_depth_maps only)
  size_t fused_points = 0;                   // before subsampling
  size_t output_points = 0;
  double voxel_size = 0;                     // of step 6; 0 when no subsampling was needed
  double median_reprojection_px = 0;         // fused points in their reference cameras
  double seconds_depth = 0, seconds_fusion = 0, seconds_total = 0;
};

// Called after each reference camera's depth map (done, total); returning false cancels
// (kCancelled). May be empty.
using MvsProgress = std::function<bool(int done, int total)>;

// The fused, coloured cloud (step 6 output). kInvalidArgument for fewer than 2 views,
// options out of range or an image whose size is not its camera's; kNotFound when no
// point survives fusion.
StatusOr<PointCloud> MultiViewStereo(const std::vector<MvsView>& views, const MvsOptions& options,
                                     MvsReport* report = nullptr, const MvsProgress& progress = {});

// The camera of `camera`'s image after an integer box downscale by `factor`
// (DownscaleImage's size and pixel-centre relation).
Camera DownscaledCamera(const Camera& camera, int factor);

// The smallest integer factor that brings max(width, height) to at most max_side.
int DownscaleFactorFor(const Camera& camera, int max_side);

// Fraction of `camera`'s pixels onto which at least one point projects (beyond a near
// plane of 1e-6, no occlusion test), at the resolution of DownscaleFactorFor(camera,
// max_side): how much of a view the cloud can seed.
double PointCoverage(const std::vector<float>& positions, const Camera& camera, int max_side);

}  // namespace atex
