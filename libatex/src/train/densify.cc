#include "atex/train/densify.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include <Eigen/Geometry>

#include "atex/train/schedule.h"

namespace atex::train {

namespace {

float MaxScale(const Gaussians& g, size_t i) {
  const float* s = &g.log_scales[i * 3];
  return std::exp(std::max({s[0], s[1], s[2]}));
}

float Sigmoid(float x) { return 1.0f / (1.0f + std::exp(-x)); }

}  // namespace

StatusOr<GaussianEdit> PlanDensification(const Gaussians& canonical, const DensifyStats& stats,
                                         const DensifyConfig& config, double extent, bool prune_screen_size,
                                         uint64_t seed, DensifyReport* report,
                                         const std::vector<uint16_t>* observing_cameras) {
  const size_t n = canonical.size();
  if (stats.grad_norm_sum.size() != n || stats.visible_count.size() != n || stats.max_radius.size() != n) {
    return MakeError(StatusCode::kInvalidArgument, "densification statistics have ", stats.grad_norm_sum.size(),
                     " entries for ", n, " Gaussians");
  }
  const bool check_observers = config.min_observing_cameras > 0;
  if (check_observers && (!observing_cameras || observing_cameras->size() != n)) {
    return MakeError(StatusCode::kInvalidArgument, "min_observing_cameras is ", config.min_observing_cameras,
                     " but the observer counts have ", observing_cameras ? observing_cameras->size() : 0,
                     " entries for ", n, " Gaussians");
  }
  auto under_observed = [&](size_t i) {
    return check_observers && (*observing_cameras)[i] < config.min_observing_cameras;
  };
  const double size_limit = config.percent_dense * extent;
  const size_t room = config.max_gaussians > n ? config.max_gaussians - n : 0;

  // Decide per Gaussian: 0 keep, 1 clone (keep + copy), 2 split (replace by two), and pruning.
  std::vector<uint8_t> action(n, 0);
  size_t added = 0;
  for (size_t i = 0; i < n && added < room; ++i) {
    const float count = stats.visible_count[i];
    if (count <= 0) continue;
    const double grad = stats.grad_norm_sum[i] / count;
    if (!(grad >= config.grad_threshold)) continue;
    action[i] = MaxScale(canonical, i) <= size_limit ? 1 : 2;
    ++added;  // a clone adds one, a split adds two and removes one
  }
  auto prune = [&](size_t i) {
    if (Sigmoid(canonical.opacity_logits[i]) < config.min_opacity) return true;
    if (under_observed(i)) return true;
    if (prune_screen_size) {
      if (config.max_screen_radius > 0 && stats.max_radius[i] > config.max_screen_radius) return true;
      if (config.max_world_scale_fraction > 0 && MaxScale(canonical, i) > config.max_world_scale_fraction * extent) {
        return true;
      }
    }
    return false;
  };

  GaussianEdit edit;
  DensifyReport local;
  local.before = n;
  SplitMix64 rng(seed ^ 0xD1B54A32D192ED03ull);
  std::vector<float> positions, log_scales;
  std::vector<uint8_t> reset;
  auto keep = [&](size_t i, bool fresh) {
    edit.source.push_back(static_cast<uint32_t>(i));
    positions.insert(positions.end(), &canonical.positions[i * 3], &canonical.positions[i * 3] + 3);
    log_scales.insert(log_scales.end(), &canonical.log_scales[i * 3], &canonical.log_scales[i * 3] + 3);
    reset.push_back(fresh ? 1 : 0);
  };
  // Originals first (in order), then the new Gaussians, as 3DGS appends them.
  std::vector<size_t> clones, splits;
  for (size_t i = 0; i < n; ++i) {
    if (action[i] == 2) {
      splits.push_back(i);
      ++local.split;
      continue;  // the parent is replaced by its two children
    }
    if (action[i] == 1) {
      clones.push_back(i);
      ++local.cloned;
    }
    if (prune(i)) {
      ++local.pruned;
      continue;
    }
    keep(i, false);
  }
  for (size_t i : clones) {
    if (prune(i)) continue;  // a clone of a pruned Gaussian would be pruned too
    keep(i, true);
  }
  for (size_t i : splits) {
    if (Sigmoid(canonical.opacity_logits[i]) < config.min_opacity || under_observed(i)) {
      ++local.pruned;  // 3DGS prunes after densifying: both children would go at once
      continue;
    }
    const float* q = &canonical.rotations[i * 4];
    Eigen::Quaternionf rotation(q[0], q[1], q[2], q[3]);
    if (rotation.norm() == 0.0f) rotation = Eigen::Quaternionf::Identity();
    rotation.normalize();
    const float* ls = &canonical.log_scales[i * 3];
    const Eigen::Vector3f scale(std::exp(ls[0]), std::exp(ls[1]), std::exp(ls[2]));
    const Eigen::Vector3f mean(canonical.positions[i * 3], canonical.positions[i * 3 + 1],
                               canonical.positions[i * 3 + 2]);
    for (int child = 0; child < 2; ++child) {
      const Eigen::Vector3f xi(rng.Normal(), rng.Normal(), rng.Normal());
      const Eigen::Vector3f position = mean + rotation * scale.cwiseProduct(xi);
      edit.source.push_back(static_cast<uint32_t>(i));
      positions.insert(positions.end(), {position.x(), position.y(), position.z()});
      for (int k = 0; k < 3; ++k) log_scales.push_back(ls[k] - std::log(1.6f));
      reset.push_back(1);
    }
  }
  edit.positions = std::move(positions);
  edit.log_scales = std::move(log_scales);
  edit.reset_moments = std::move(reset);
  local.after = edit.source.size();
  if (report) *report = local;
  return edit;
}

std::vector<uint16_t> CountObservingCameras(const Gaussians& canonical, const std::vector<Camera>& cameras,
                                            float near_plane) {
  const size_t n = canonical.size();
  std::vector<uint16_t> count(n, 0);
  for (const Camera& camera : cameras) {
    for (size_t i = 0; i < n; ++i) {
      const double x[3] = {canonical.positions[i * 3], canonical.positions[i * 3 + 1], canonical.positions[i * 3 + 2]};
      double u, v;
      if (ProjectToImage(camera, x, near_plane, &u, &v) && count[i] < UINT16_MAX) ++count[i];
    }
  }
  return count;
}

GaussianEdit PlanPrune(const Gaussians& canonical, const std::vector<uint8_t>& remove) {
  GaussianEdit edit;
  for (size_t i = 0; i < canonical.size(); ++i) {
    if (i < remove.size() && remove[i]) continue;
    edit.source.push_back(static_cast<uint32_t>(i));
  }
  return edit;
}

}  // namespace atex::train
