// The training loss: its value against the public metrics, its gradient against
// central finite differences in double precision, float/double agreement.
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "atex/metrics.h"

namespace atex {
namespace {

struct Pair {
  int width, height;
  std::vector<double> rendered;  // [H][W][3]
  std::vector<float> target;     // [H][W][3]
};

// Random target; rendered = target + a perturbation of at least 0.02 in
// magnitude so that no |r − t| kink lies within a finite-difference step.
Pair MakePair(int width, int height, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Pair p{width, height, {}, {}};
  const size_t n = size_t(width) * height * 3;
  p.target.resize(n);
  p.rendered.resize(n);
  for (size_t i = 0; i < n; ++i) {
    p.target[i] = static_cast<float>(u(rng));
    const double delta = (0.02 + 0.2 * u(rng)) * (u(rng) < 0.5 ? -1 : 1);
    p.rendered[i] = p.target[i] + delta;
  }
  return p;
}

Image ToImage(const std::vector<double>& v, int w, int h) {
  Image image(w, h, 3);
  for (size_t i = 0; i < v.size(); ++i) image.pixels[i] = static_cast<float>(v[i]);
  return image;
}

TEST(PhotometricLoss, ValueMatchesL1AndSsim) {
  // Rendered values exactly representable in float, so the float Image path sees the same numbers.
  Pair p = MakePair(24, 18, 1);
  for (double& v : p.rendered) v = static_cast<float>(v);
  const Image rendered = ToImage(p.rendered, p.width, p.height);
  Image target(p.width, p.height, 3);
  target.pixels = p.target;
  double l1 = 0;
  for (size_t i = 0; i < p.target.size(); ++i) l1 += std::abs(p.rendered[i] - p.target[i]);
  l1 /= double(p.target.size());
  const double ssim = *Ssim(rendered, target);
  const double loss = PhotometricLoss<double>(p.rendered.data(), p.target.data(), p.width, p.height, 0.2, nullptr);
  EXPECT_NEAR(loss, 0.8 * l1 + 0.2 * (1 - ssim), 1e-12);
}

void CheckGradient(double lambda) {
  const Pair p = MakePair(13, 11, 7);
  std::vector<double> grad(p.rendered.size());
  PhotometricLoss<double>(p.rendered.data(), p.target.data(), p.width, p.height, lambda, grad.data());
  std::vector<double> x = p.rendered;
  const double h = 1e-6;
  double max_abs_grad = 0;
  for (double g : grad) max_abs_grad = std::max(max_abs_grad, std::abs(g));
  ASSERT_GT(max_abs_grad, 0);
  std::mt19937 rng(3);
  // Every element near a corner and a border, plus a random sample.
  std::vector<size_t> indices = {0, 1, 2, 3 * 12, 3 * (13 * 5 + 6) + 1, p.rendered.size() - 1};
  for (int i = 0; i < 60; ++i) indices.push_back(rng() % p.rendered.size());
  for (size_t i : indices) {
    x[i] = p.rendered[i] + h;
    const double plus = PhotometricLoss<double>(x.data(), p.target.data(), p.width, p.height, lambda, nullptr);
    x[i] = p.rendered[i] - h;
    const double minus = PhotometricLoss<double>(x.data(), p.target.data(), p.width, p.height, lambda, nullptr);
    x[i] = p.rendered[i];
    const double fd = (plus - minus) / (2 * h);
    EXPECT_NEAR(grad[i], fd, 1e-5 * max_abs_grad) << "element " << i << " lambda " << lambda;
  }
}

TEST(PhotometricLoss, GradientMatchesFiniteDifferences) {
  CheckGradient(0.2);
  CheckGradient(1.0);  // SSIM term alone
  CheckGradient(0.0);  // L1 alone
}

TEST(PhotometricLoss, FloatAgreesWithDouble) {
  const Pair p = MakePair(40, 30, 11);
  std::vector<float> rendered_f(p.rendered.begin(), p.rendered.end());
  std::vector<double> rendered_d(rendered_f.begin(), rendered_f.end());
  std::vector<float> grad_f(rendered_f.size());
  std::vector<double> grad_d(rendered_f.size());
  const float loss_f =
      PhotometricLoss<float>(rendered_f.data(), p.target.data(), p.width, p.height, 0.2, grad_f.data());
  const double loss_d =
      PhotometricLoss<double>(rendered_d.data(), p.target.data(), p.width, p.height, 0.2, grad_d.data());
  EXPECT_NEAR(loss_f, loss_d, 1e-5);
  double max_grad = 0, max_diff = 0;
  for (size_t i = 0; i < grad_d.size(); ++i) {
    max_grad = std::max(max_grad, std::abs(grad_d[i]));
    max_diff = std::max(max_diff, std::abs(grad_d[i] - grad_f[i]));
  }
  EXPECT_LT(max_diff, 1e-3 * max_grad);
}

TEST(PhotometricLoss, ZeroAtTheTargetWithZeroGradient) {
  const Pair p = MakePair(16, 12, 5);
  std::vector<double> rendered(p.target.begin(), p.target.end());
  std::vector<double> grad(rendered.size(), 1.0);
  const double loss = PhotometricLoss<double>(rendered.data(), p.target.data(), p.width, p.height, 0.2, grad.data());
  EXPECT_NEAR(loss, 0.0, 1e-12);
  for (double g : grad) EXPECT_NEAR(g, 0.0, 1e-12);  // SSIM is maximal, L1 uses sign(0) = 0
}

}  // namespace
}  // namespace atex
