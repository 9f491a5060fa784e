// Point sources of the initialisation that come from elsewhere than init.cc's samplers:
// multi-view stereo and external point clouds (atex/init.h, kMvs and kFile). Not a
// public header.
#pragma once

#include <array>
#include <vector>

#include "atex/init.h"
#include "atex/mvs.h"
#include "atex/point_cloud.h"

namespace atex {

// MultiViewStereo over `views` with options.mvs, the depth range from `depth_bounds` when
// they are known ({0, 0} otherwise: [mvs_near, mvs_far] · scene_distance) and
// target_points = mvs_points.
StatusOr<PointCloud> MvsInitCloud(const std::vector<MvsView>& views, const std::array<float, 2>& depth_bounds,
                                  double scene_distance, const InitOptions& options, MvsReport* report);

// The file options.point_cloud_path, cut to options.file_points (an evenly spaced subset:
// point floor(i·N/n) for i < n) when it has more and file_points > 0.
StatusOr<PointCloud> FileInitCloud(const InitOptions& options);

}  // namespace atex
