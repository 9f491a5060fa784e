#include "splatv/motion_fit.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

namespace atex::splatv {
namespace {

constexpr double kMinWidth = 1e-3, kMaxWidth = 1000;

double SquaredError(const std::vector<double>& u, const float* alpha, size_t samples, const TemporalOpacity& f) {
  double sse = 0;
  for (size_t j = 0; j < samples; ++j) {
    const double d = (u[j] - f.center) / f.width;
    const double e = f.peak * std::exp(-d * d) - alpha[j];
    sse += e * e;
  }
  return sse;
}

}  // namespace

TemporalOpacity FitTemporalOpacity(const std::vector<double>& u, const float* alpha, size_t samples) {
  TemporalOpacity constant;
  double sum = 0, lo = 1, hi = 0;
  for (size_t j = 0; j < samples; ++j) {
    sum += alpha[j];
    lo = std::min(lo, double(alpha[j]));
    hi = std::max(hi, double(alpha[j]));
  }
  constant.peak = samples ? sum / double(samples) : 1.0;
  if (samples < 3 || hi - lo < 1e-4) return constant;

  // Weighted least squares of log(alpha) = a + b u + q u^2 (weights = alpha: the times
  // where the splat is visible matter, log of a faded splat is noise).
  Eigen::Matrix3d gram = Eigen::Matrix3d::Zero();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  for (size_t j = 0; j < samples; ++j) {
    const double w = std::max(double(alpha[j]), 1e-6);
    const Eigen::Vector3d phi(1.0, u[j], u[j] * u[j]);
    gram += w * phi * phi.transpose();
    rhs += w * std::log(std::max(double(alpha[j]), 1e-6)) * phi;
  }
  const Eigen::Vector3d x = gram.ldlt().solve(rhs);
  TemporalOpacity best = constant;
  double best_error = SquaredError(u, alpha, samples, constant);
  if (x.allFinite() && x[2] < -1e-9) {
    TemporalOpacity g;
    g.center = std::clamp(-x[1] / (2 * x[2]), -1.0, 2.0);
    g.width = std::clamp(std::sqrt(-1.0 / x[2]), kMinWidth, kMaxWidth);
    g.peak = std::clamp(std::exp(x[0] - x[1] * x[1] / (4 * x[2])), 0.0, 1.0);
    const double e = SquaredError(u, alpha, samples, g);
    if (std::isfinite(e) && e < best_error) {
      best = g;
      best_error = e;
    }
  }
  // A splat that fades in or out monotonically: a Gaussian centred at the visible end.
  for (double center : {u.front(), u.back()}) {
    TemporalOpacity g;
    g.center = center;
    g.peak = double(alpha[center == u.front() ? 0 : samples - 1]);
    // Width from the half-way point of the opacity change, if there is one.
    double width = kMaxWidth;
    for (size_t j = 0; j < samples; ++j) {
      if (alpha[j] < 0.5 * g.peak && std::abs(u[j] - center) > 0) {
        width = std::min(width, std::abs(u[j] - center) / std::sqrt(std::log(2.0)));
      }
    }
    g.width = std::clamp(width, kMinWidth, kMaxWidth);
    const double e = SquaredError(u, alpha, samples, g);
    if (std::isfinite(e) && e < best_error) {
      best = g;
      best_error = e;
    }
  }
  return best;
}

std::array<double, 16> CubicGram(const std::vector<double>& u, double center) {
  std::array<double, 16> g{};
  for (double t : u) {
    const double dt = t - center;
    const double phi[4] = {1, dt, dt * dt, dt * dt * dt};
    for (int a = 0; a < 4; ++a) {
      for (int b = 0; b < 4; ++b) g[size_t(a * 4 + b)] += phi[a] * phi[b];
    }
  }
  return g;
}

std::array<double, 4> LineGram(const std::vector<double>& u, double center) {
  std::array<double, 4> g{};
  for (double t : u) {
    const double dt = t - center;
    g[0] += 1, g[1] += dt, g[2] += dt, g[3] += dt * dt;
  }
  return g;
}

bool SolveCubic(const std::array<double, 16>& gram, const double rhs[4], double x[4]) {
  Eigen::Matrix4d a;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) a(r, c) = gram[size_t(r * 4 + c)];
  }
  const Eigen::Vector4d b(rhs[0], rhs[1], rhs[2], rhs[3]);
  Eigen::FullPivLU<Eigen::Matrix4d> lu(a);
  if (!lu.isInvertible()) return false;
  const Eigen::Vector4d s = lu.solve(b);
  for (int k = 0; k < 4; ++k) x[k] = s[k];
  return s.allFinite();
}

bool SolveLine(const std::array<double, 4>& gram, const double rhs[2], double x[2]) {
  const double det = gram[0] * gram[3] - gram[1] * gram[2];
  if (!(std::abs(det) > 1e-300)) return false;
  x[0] = (gram[3] * rhs[0] - gram[1] * rhs[1]) / det;
  x[1] = (gram[0] * rhs[1] - gram[2] * rhs[0]) / det;
  return std::isfinite(x[0]) && std::isfinite(x[1]);
}

}  // namespace atex::splatv
