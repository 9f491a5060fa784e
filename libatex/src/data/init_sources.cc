// Multi-view stereo and external point clouds as initialisation sources (init_sources.h).
#include "data/init_sources.h"

namespace atex {

StatusOr<PointCloud> MvsInitCloud(const std::vector<MvsView>& views, const std::array<float, 2>& depth_bounds,
                                  double scene_distance, const InitOptions& options, MvsReport* report) {
  MvsOptions mvs = options.mvs;
  if (depth_bounds[1] > depth_bounds[0] && depth_bounds[0] > 0) {
    mvs.near_depth = depth_bounds[0];
    mvs.far_depth = depth_bounds[1];
  } else {
    mvs.near_depth = options.mvs_near * scene_distance;
    mvs.far_depth = options.mvs_far * scene_distance;
  }
  mvs.target_points = static_cast<size_t>(options.mvs_points);
  return MultiViewStereo(views, mvs, report);
}

StatusOr<PointCloud> FileInitCloud(const InitOptions& options) {
  if (options.point_cloud_path.empty()) {
    return MakeError(StatusCode::kInvalidArgument, "init: method 'file' needs a point cloud path");
  }
  ATEX_ASSIGN_OR_RETURN(PointCloud cloud, ReadPointCloud(options.point_cloud_path));
  const size_t n = cloud.size(), wanted = static_cast<size_t>(options.file_points);
  if (wanted == 0 || n <= wanted) return cloud;
  PointCloud subset;
  for (size_t i = 0; i < wanted; ++i) {
    const size_t k = static_cast<size_t>((unsigned __int128)i * n / wanted);
    subset.positions.insert(subset.positions.end(), &cloud.positions[3 * k], &cloud.positions[3 * k + 3]);
    if (cloud.has_colours())
      subset.colours.insert(subset.colours.end(), &cloud.colours[3 * k], &cloud.colours[3 * k + 3]);
  }
  return subset;
}

}  // namespace atex
