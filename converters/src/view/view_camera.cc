// The opening camera and keyframe count of `atex view` (atex/converters/view.h).
#include <algorithm>
#include <cmath>
#include <numbers>

#include "atex/converters/view.h"
#include "view/view_bake.h"

namespace atex {
namespace {

double Sigmoid(double x) { return 1.0 / (1.0 + std::exp(-x)); }

std::array<double, 3> Normalised(std::array<double, 3> v) {
  const double n = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  if (n > 0) for (double& x : v) x /= n;
  return v;
}

std::array<double, 3> Cross(const std::array<double, 3>& a, const std::array<double, 3>& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

// A horizontal viewing direction for each up axis (the front of a scene in that convention).
std::array<double, 3> HorizontalForward(UpAxis up) {
  switch (up) {
    case UpAxis::kNegY: return {0, 0, 1};
    case UpAxis::kPosY: return {0, 0, -1};
    case UpAxis::kPosZ: return {0, 1, 0};
    case UpAxis::kNegZ: return {0, -1, 0};
    case UpAxis::kPosX: return {0, 0, 1};
    case UpAxis::kNegX: return {0, 0, -1};
  }
  return {0, 0, 1};
}

}  // namespace

namespace view {

std::array<double, 3> ViewUpVector(UpAxis up) {
  switch (up) {
    case UpAxis::kPosX: return {1, 0, 0};
    case UpAxis::kNegX: return {-1, 0, 0};
    case UpAxis::kPosY: return {0, 1, 0};
    case UpAxis::kNegY: return {0, -1, 0};
    case UpAxis::kPosZ: return {0, 0, 1};
    case UpAxis::kNegZ: return {0, 0, -1};
  }
  return {0, -1, 0};
}

// The robust box of view.h's DefaultViewCamera: per axis the 2nd and 98th percentile of
// the positions of Gaussians with opacity >= 0.2 (every Gaussian when none is).
void RobustBox(const Gaussians& g, std::array<double, 3>* lo, std::array<double, 3>* hi) {
  std::vector<size_t> chosen;
  for (size_t i = 0; i < g.size(); ++i) {
    if (Sigmoid(g.opacity_logits[i]) >= 0.2) chosen.push_back(i);
  }
  if (chosen.empty()) {
    chosen.resize(g.size());
    for (size_t i = 0; i < g.size(); ++i) chosen[i] = i;
  }
  std::vector<float> v(chosen.size());
  for (int c = 0; c < 3; ++c) {
    for (size_t j = 0; j < chosen.size(); ++j) v[j] = g.positions[chosen[j] * 3 + size_t(c)];
    if (v.empty()) {
      (*lo)[size_t(c)] = -1, (*hi)[size_t(c)] = 1;
      continue;
    }
    const size_t a = size_t(0.02 * double(v.size() - 1)), b = size_t(std::ceil(0.98 * double(v.size() - 1)));
    std::nth_element(v.begin(), v.begin() + long(a), v.end());
    (*lo)[size_t(c)] = v[a];
    std::nth_element(v.begin(), v.begin() + long(b), v.end());
    (*hi)[size_t(c)] = v[b];
  }
}

}  // namespace view

int DefaultViewFrames(const Asset& asset) {
  if (!asset.deformation) return 1;
  const int nodes = asset.deformation->config.grid.base_resolution[3];
  return std::clamp(2 * (nodes - 1) + 1, 2, 120);
}

Camera DefaultViewCamera(const Gaussians& gaussians, UpAxis up, int width, int height, std::array<double, 3>* target) {
  std::array<double, 3> lo, hi, centre;
  view::RobustBox(gaussians, &lo, &hi);
  double radius = 0;
  for (int c = 0; c < 3; ++c) {
    centre[size_t(c)] = 0.5 * (lo[size_t(c)] + hi[size_t(c)]);
    radius += 0.25 * (hi[size_t(c)] - lo[size_t(c)]) * (hi[size_t(c)] - lo[size_t(c)]);
  }
  radius = std::max(std::sqrt(radius), 1e-3);
  const double half_fov = 25.0 * std::numbers::pi / 180.0, elevation = 20.0 * std::numbers::pi / 180.0;
  const std::array<double, 3> u = view::ViewUpVector(up), h = HorizontalForward(up);
  std::array<double, 3> forward;
  for (int c = 0; c < 3; ++c)
    forward[size_t(c)] = std::cos(elevation) * h[size_t(c)] - std::sin(elevation) * u[size_t(c)];
  forward = Normalised(forward);
  const double ud = u[0] * forward[0] + u[1] * forward[1] + u[2] * forward[2];
  const std::array<double, 3> down =
      Normalised({ud * forward[0] - u[0], ud * forward[1] - u[1], ud * forward[2] - u[2]});
  const std::array<double, 3> right = Cross(down, forward);  // x = y cross z in a right-handed camera
  const double distance = 1.05 * radius / std::sin(half_fov);
  std::array<double, 3> eye;
  for (int c = 0; c < 3; ++c) eye[size_t(c)] = centre[size_t(c)] - distance * forward[size_t(c)];
  Camera cam;
  cam.width = width, cam.height = height;
  cam.fy = 0.5 * height / std::tan(half_fov);
  cam.fx = cam.fy;
  cam.cx = 0.5 * width, cam.cy = 0.5 * height;
  const std::array<std::array<double, 3>, 3> rows = {right, down, forward};
  for (int r = 0; r < 3; ++r) {
    const auto& a = rows[size_t(r)];
    for (int c = 0; c < 3; ++c) cam.world_to_camera[size_t(r * 4 + c)] = a[size_t(c)];
    cam.world_to_camera[size_t(r * 4 + 3)] = -(a[0] * eye[0] + a[1] * eye[1] + a[2] * eye[2]);
  }
  cam.name = "atex view";
  if (target) *target = centre;
  return cam;
}

}  // namespace atex
