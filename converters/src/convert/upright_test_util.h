// Test helpers for the "exports open upright" checks: the world's up direction
// as a dataset's cameras show it (independent of any metadata), and the linear
// map a third-party reader applied to positions. Header-only, tests only.
#pragma once

#include <array>
#include <cmath>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "atex/dataset.h"

namespace atex::converters::testing {

// Mean of the training cameras' up vectors (each camera's -y axis in world
// coordinates), normalised: the direction a viewer of the dataset sees as up.
inline StatusOr<std::array<double, 3>> CamerasUpVector(const std::string& dataset_path) {
  ATEX_ASSIGN_OR_RETURN(auto data, OpenDataset(dataset_path));
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const auto& view : data->train_views()) {
    const auto& m = view.camera.world_to_camera;
    sum -= Eigen::Vector3d(m[4], m[5], m[6]).normalized();
  }
  if (sum.norm() == 0) return MakeError(StatusCode::kInvalidArgument, "no cameras in ", dataset_path);
  sum.normalize();
  return std::array<double, 3>{sum.x(), sum.y(), sum.z()};
}

// The 3x3 matrix M minimising sum |out_i - M in_i|^2 over corresponding points
// (`in`, `out`: [N][3], centred first so translations do not matter).
inline Eigen::Matrix3d FitLinearMap(const std::vector<float>& in, const std::vector<double>& out) {
  const size_t n = in.size() / 3;
  Eigen::Vector3d mean_in = Eigen::Vector3d::Zero(), mean_out = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    mean_in += Eigen::Vector3d(in[i * 3], in[i * 3 + 1], in[i * 3 + 2]);
    mean_out += Eigen::Vector3d(out[i * 3], out[i * 3 + 1], out[i * 3 + 2]);
  }
  mean_in /= double(n), mean_out /= double(n);
  Eigen::Matrix3d a = Eigen::Matrix3d::Zero(), b = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d p = Eigen::Vector3d(in[i * 3], in[i * 3 + 1], in[i * 3 + 2]) - mean_in;
    const Eigen::Vector3d q = Eigen::Vector3d(out[i * 3], out[i * 3 + 1], out[i * 3 + 2]) - mean_out;
    a += p * p.transpose();
    b += q * p.transpose();
  }
  return b * a.inverse();
}

}  // namespace atex::converters::testing
