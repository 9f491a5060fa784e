// Closed-form motion fits for splaTV: temporal opacity (a Gaussian in time), a cubic
// position and a linear rotation, by (weighted) least squares over sampled times.
// Internal header; the maths is independent of the file format.
#pragma once

#include <array>
#include <cstddef>
#include <vector>

namespace atex::splatv {

// opacity(u) ~ peak * exp(-((u - center) / width)^2).
struct TemporalOpacity {
  double peak = 1;    // in [0, 1]
  double center = 0.5;
  double width = 1000;  // "never fades" when the opacity does not change
};

// Fits `alpha` ([S] opacities at times `u` [S]). Tries a Gaussian (weighted least squares
// on log-opacity, weights = opacity) and a constant, and keeps the one with the smaller
// squared error. `center` is clamped to [-1, 2] and `width` to [1e-3, 1000].
TemporalOpacity FitTemporalOpacity(const std::vector<double>& u, const float* alpha, size_t samples);

// Sum over samples of phi(dt) phi(dt)^T, phi = (1, dt, dt^2, dt^3), dt = u_j - center.
std::array<double, 16> CubicGram(const std::vector<double>& u, double center);
// Solves gram * x = rhs for the 4 coefficients of one axis; false when singular.
bool SolveCubic(const std::array<double, 16>& gram, const double rhs[4], double x[4]);
// Same for the line (1, dt): gram 2x2.
bool SolveLine(const std::array<double, 4>& gram, const double rhs[2], double x[2]);
std::array<double, 4> LineGram(const std::vector<double>& u, double center);

}  // namespace atex::splatv
