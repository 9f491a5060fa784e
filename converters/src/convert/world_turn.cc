// Turning an asset's world to a file format's up axis (see world_turn.h).
#include "convert/world_turn.h"

#include <cmath>

#include "gltf/sh_rotation.h"

namespace atex::convert {

void RotateGaussians(const std::array<double, 9>& r, Gaussians* g) {
  // Rotation matrix -> unit quaternion (w, x, y, z); r is proper, so trace > -1
  // except for 180-degree turns, handled by the largest-diagonal branches.
  double qw, qx, qy, qz;
  const double trace = r[0] + r[4] + r[8];
  if (trace > 0) {
    const double k = 0.5 / std::sqrt(trace + 1.0);
    qw = 0.25 / k, qx = (r[7] - r[5]) * k, qy = (r[2] - r[6]) * k, qz = (r[3] - r[1]) * k;
  } else if (r[0] >= r[4] && r[0] >= r[8]) {
    const double k = 2.0 * std::sqrt(1.0 + r[0] - r[4] - r[8]);
    qw = (r[7] - r[5]) / k, qx = 0.25 * k, qy = (r[1] + r[3]) / k, qz = (r[2] + r[6]) / k;
  } else if (r[4] >= r[8]) {
    const double k = 2.0 * std::sqrt(1.0 + r[4] - r[0] - r[8]);
    qw = (r[2] - r[6]) / k, qx = (r[1] + r[3]) / k, qy = 0.25 * k, qz = (r[5] + r[7]) / k;
  } else {
    const double k = 2.0 * std::sqrt(1.0 + r[8] - r[0] - r[4]);
    qw = (r[3] - r[1]) / k, qx = (r[2] + r[6]) / k, qy = (r[5] + r[7]) / k, qz = 0.25 * k;
  }
  const gltf::ShRotation sh_rotation = gltf::MakeShRotation(r, g->sh_degree);
  const size_t n = g->size(), k_count = size_t(g->sh_coeffs());
  for (size_t i = 0; i < n; ++i) {
    float* p = &g->positions[i * 3];
    const double x = p[0], y = p[1], z = p[2];
    for (int row = 0; row < 3; ++row) p[row] = float(r[row * 3] * x + r[row * 3 + 1] * y + r[row * 3 + 2] * z);
    float* q = &g->rotations[i * 4];
    const double w = q[0], a = q[1], b = q[2], c = q[3];
    q[0] = float(qw * w - qx * a - qy * b - qz * c);
    q[1] = float(qw * a + qx * w + qy * c - qz * b);
    q[2] = float(qw * b - qx * c + qy * w + qz * a);
    q[3] = float(qw * c + qx * b - qy * a + qz * w);
    if (g->sh_degree > 0) gltf::RotateSh(sh_rotation, g->sh_degree, &g->sh[i * k_count * 3]);
  }
}

std::array<double, 9> RotationToDownY(UpAxis up) {
  // UpRotationMatrix takes `up` to +Y; 180 degrees about x then takes +Y to -Y.
  const std::array<double, 9> to_up = UpRotationMatrix(up);
  const std::array<double, 9> flip = {1, 0, 0, 0, -1, 0, 0, 0, -1};
  std::array<double, 9> out{};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      for (int k = 0; k < 3; ++k) out[i * 3 + j] += flip[i * 3 + k] * to_up[k * 3 + j];
    }
  }
  return out;
}

std::string TurnWorldDownY(const Metadata& metadata, Gaussians* g) {
  auto up = UpAxisOf(metadata);
  if (!up.ok() || *up == UpAxis::kNegY) return "";
  RotateGaussians(RotationToDownY(*up), g);
  return StrCat("world turned so that its up axis (", UpAxisName(*up),
                ") is the file's up (-y of the 3DGS PLY convention; +y of SPZ's RUB axes)");
}

}  // namespace atex::convert
