#include "gltf/sh_rotation.h"

#include <cmath>

#include <Eigen/Dense>

namespace atex::gltf {

void EvaluateShBasis(double x, double y, double z, int degree, double* out) {
  out[0] = 0.28209479177387814;
  if (degree < 1) return;
  const double c1 = 0.4886025119029199;
  out[1] = -c1 * y;
  out[2] = c1 * z;
  out[3] = -c1 * x;
  if (degree < 2) return;
  const double xx = x * x, yy = y * y, zz = z * z;
  out[4] = 1.0925484305920792 * x * y;
  out[5] = -1.0925484305920792 * y * z;
  out[6] = 0.31539156525252005 * (2 * zz - xx - yy);
  out[7] = -1.0925484305920792 * x * z;
  out[8] = 0.5462742152960396 * (xx - yy);
  if (degree < 3) return;
  out[9] = -0.5900435899266435 * y * (3 * xx - yy);
  out[10] = 2.890611442640554 * x * y * z;
  out[11] = -0.4570457994644658 * y * (4 * zz - xx - yy);
  out[12] = 0.3731763325901154 * z * (2 * zz - 3 * xx - 3 * yy);
  out[13] = -0.4570457994644658 * x * (4 * zz - xx - yy);
  out[14] = 1.445305721320277 * z * (xx - yy);
  out[15] = -0.5900435899266435 * x * (xx - 3 * yy);
}

ShRotation MakeShRotation(const std::array<double, 9>& r, int degree) {
  // 32 directions on a Fibonacci sphere: well spread, fixed, enough for band 3 (7 unknowns).
  constexpr int kDirections = 32;
  const double golden = M_PI * (3.0 - std::sqrt(5.0));
  Eigen::MatrixXd at_d(kDirections, 16), at_rt_d(kDirections, 16);
  for (int j = 0; j < kDirections; ++j) {
    const double z = 1.0 - 2.0 * (j + 0.5) / kDirections;
    const double radius = std::sqrt(1.0 - z * z);
    const double phi = golden * j;
    const double d[3] = {radius * std::cos(phi), radius * std::sin(phi), z};
    // R^T d: the direction in the original frame that lands on d after rotation.
    const double e[3] = {r[0] * d[0] + r[3] * d[1] + r[6] * d[2], r[1] * d[0] + r[4] * d[1] + r[7] * d[2],
                         r[2] * d[0] + r[5] * d[1] + r[8] * d[2]};
    double basis[16] = {}, rotated[16] = {};
    EvaluateShBasis(d[0], d[1], d[2], 3, basis);
    EvaluateShBasis(e[0], e[1], e[2], 3, rotated);
    for (int k = 0; k < 16; ++k) {
      at_d(j, k) = basis[k];
      at_rt_d(j, k) = rotated[k];
    }
  }
  ShRotation out;
  for (int l = 1; l <= degree; ++l) {
    const int first = l * l, size = 2 * l + 1;
    // Solve Y(D) M = Y(R^T D) for M (least squares), band block only.
    const Eigen::MatrixXd y = at_d.middleCols(first, size);
    const Eigen::MatrixXd y_rot = at_rt_d.middleCols(first, size);
    const Eigen::MatrixXd m = y.colPivHouseholderQr().solve(y_rot);  // c' = M c with f'(d) = sum c'_k Y_k(d)
    out.band[l].resize(size_t(size * size));
    for (int a = 0; a < size; ++a) {
      for (int b = 0; b < size; ++b) out.band[l][size_t(a * size + b)] = m(a, b);
    }
  }
  return out;
}

void RotateSh(const ShRotation& rotation, int degree, float* sh) {
  for (int l = 1; l <= degree; ++l) {
    const int first = l * l, size = 2 * l + 1;
    double rotated[7][3] = {};
    for (int a = 0; a < size; ++a) {
      for (int b = 0; b < size; ++b) {
        const double m = rotation.band[l][size_t(a * size + b)];
        for (int c = 0; c < 3; ++c) rotated[a][c] += m * sh[(first + b) * 3 + c];
      }
    }
    for (int a = 0; a < size; ++a) {
      for (int c = 0; c < 3; ++c) sh[(first + a) * 3 + c] = float(rotated[a][c]);
    }
  }
}

}  // namespace atex::gltf
