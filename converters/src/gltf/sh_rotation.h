// Rotation of real spherical-harmonic colour coefficients (the 3DGS basis of
// docs/conventions.md §2), needed when a foreign glTF node rotates its splats and
// the rotation is baked into the data. Internal header.
#pragma once

#include <array>
#include <vector>

namespace atex::gltf {

// Per band l = 1..3, the (2l+1)x(2l+1) matrix M_l with c'_l = M_l c_l, so that the
// rotated coefficients evaluated at R·d equal the original ones evaluated at d.
// Computed by least squares over a fixed set of directions (exact up to rounding,
// because each band is closed under rotation). `r` is row-major 3x3.
struct ShRotation {
  std::array<std::vector<double>, 4> band;  // band[l]: [(2l+1)][(2l+1)] row-major; band[0] unused
};
ShRotation MakeShRotation(const std::array<double, 9>& r, int degree);

// Rotates `sh` ([K][3], K = (degree+1)^2, coefficient-major) in place.
void RotateSh(const ShRotation& rotation, int degree, float* sh);

// The 3DGS real SH basis at unit direction (x, y, z): out[k], k < (degree+1)^2.
void EvaluateShBasis(double x, double y, double z, int degree, double* out);

}  // namespace atex::gltf
