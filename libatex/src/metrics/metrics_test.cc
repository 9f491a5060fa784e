// PSNR/SSIM/DSSIM against closed forms, a brute-force 2-D reference, and (when
// present) values computed by scikit-image/scipy (tests/fixtures/ssim).
#include <cmath>
#include <fstream>
#include <limits>
#include <random>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "atex/metrics.h"
#include "core/test_support.h"

namespace atex {
namespace {

constexpr double kC1 = 0.0001;  // (0.01·1)²
constexpr double kC2 = 0.0009;  // (0.03·1)²

// The 1-D window written out independently of the library: exp(−k²/4.5), normalised. [11]
std::vector<double> Taps() {
  std::vector<double> g(11);
  double sum = 0;
  for (int k = -5; k <= 5; ++k) sum += g[k + 5] = std::exp(-k * k / 4.5);
  for (double& v : g) v /= sum;
  return g;
}

Image Constant(int w, int h, int c, float value) { return Image(w, h, c, value); }

Image Random(int w, int h, int c, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  Image image(w, h, c);
  for (float& v : image.pixels) v = u(rng);
  return image;
}

// Straightforward 121-tap zero-padded SSIM, O(HW·121): an independent reference.
double BruteForceSsimSame(const Image& a, const Image& b, double c1, double c2) {
  const std::vector<double> g = Taps();
  double sum = 0;
  for (int y = 0; y < a.height; ++y) {
    for (int x = 0; x < a.width; ++x) {
      for (int c = 0; c < a.channels; ++c) {
        double mx = 0, my = 0, exx = 0, eyy = 0, exy = 0;
        for (int dy = -5; dy <= 5; ++dy) {
          for (int dx = -5; dx <= 5; ++dx) {
            const int xx = x + dx, yy = y + dy;
            if (xx < 0 || yy < 0 || xx >= a.width || yy >= a.height) continue;
            const double w = g[dx + 5] * g[dy + 5];
            const double va = a.at(xx, yy, c), vb = b.at(xx, yy, c);
            mx += w * va;
            my += w * vb;
            exx += w * va * va;
            eyy += w * vb * vb;
            exy += w * va * vb;
          }
        }
        const double sx = exx - mx * mx, sy = eyy - my * my, sxy = exy - mx * my;
        sum += (2 * mx * my + c1) * (2 * sxy + c2) / ((mx * mx + my * my + c1) * (sx + sy + c2));
      }
    }
  }
  return sum / (double(a.width) * a.height * a.channels);
}

TEST(Psnr, KnownValueAndIdentity) {
  const Image a = Constant(8, 6, 3, 0.5f), b = Constant(8, 6, 3, 0.6f);
  // MSE = 0.01 -> 20 dB (float rounding of 0.6 - 0.5 allows a tiny error).
  EXPECT_NEAR(*Psnr(a, b), 20.0, 1e-5);
  EXPECT_NEAR(*Psnr(a, b, 2.0), 20.0 + 20.0 * std::log10(2.0), 1e-5);
  EXPECT_TRUE(std::isinf(*Psnr(a, a)));
}

TEST(Metrics, SizeMismatchAndNaNAreErrors) {
  const Image a = Constant(8, 6, 3, 0.5f);
  EXPECT_EQ(Psnr(a, Constant(8, 7, 3, 0.5f)).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(Ssim(a, Constant(8, 6, 1, 0.5f)).status().code(), StatusCode::kInvalidArgument);
  Image nan = a;
  nan.pixels[5] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(Ssim(a, nan).status().code(), StatusCode::kOutOfRange);
  SsimOptions valid;
  valid.padding = SsimPadding::kValid;
  EXPECT_EQ(Ssim(a, a, valid).status().code(), StatusCode::kInvalidArgument);  // 8x6 < 11x11
}

TEST(Ssim, IdenticalImagesGiveOne) {
  const Image a = Random(23, 17, 3, 1);
  EXPECT_NEAR(*Ssim(a, a), 1.0, 1e-12);
  SsimOptions valid;
  valid.padding = SsimPadding::kValid;
  EXPECT_NEAR(*Ssim(a, a, valid), 1.0, 1e-12);
}

TEST(Ssim, ConstantImagesValidPaddingClosedForm) {
  // Inside the image both windows are constant: σ = 0, so S = (2ab + C1)/(a² + b² + C1).
  const double a = 0.3, b = 0.7;
  SsimOptions valid;
  valid.padding = SsimPadding::kValid;
  const double expected = (2 * a * b + kC1) / (a * a + b * b + kC1);
  const double got = *Ssim(Constant(20, 15, 3, float(a)), Constant(20, 15, 3, float(b)), valid);
  EXPECT_NEAR(got, expected, 1e-6);  // inputs are float: a, b rounded to 24 bits
  // Data range 2 changes C1 only.
  valid.data_range = 2.0;
  const double c1_r2 = 0.0004;
  EXPECT_NEAR(*Ssim(Constant(20, 15, 1, float(a)), Constant(20, 15, 1, float(b)), valid),
              (2 * a * b + c1_r2) / (a * a + b * b + c1_r2), 1e-6);
}

TEST(Ssim, ConstantImagesSamePaddingClosedFormAtBorders) {
  // Zero padding: the window mass inside the image is s = sx(i)·sy(j), so for
  // constant images m = a·s, σx² = a²·s(1 − s), σxy = ab·s(1 − s).
  const int w = 14, h = 9;
  const float fa = 0.4f, fb = 0.9f;
  const double a = fa, b = fb;
  const std::vector<double> g = Taps();
  auto mass = [&](int i, int n) {
    double s = 0;
    for (int k = -5; k <= 5; ++k) {
      if (i + k >= 0 && i + k < n) s += g[k + 5];
    }
    return s;
  };
  double sum = 0;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const double s = mass(x, w) * mass(y, h);
      const double var = s * (1 - s);
      sum += (2 * a * b * s * s + kC1) * (2 * a * b * var + kC2) /
             (((a * a + b * b) * s * s + kC1) * ((a * a + b * b) * var + kC2));
    }
  }
  const double expected = sum / (w * h);
  EXPECT_NEAR(*Ssim(Constant(w, h, 1, fa), Constant(w, h, 1, fb)), expected, 1e-9);
  EXPECT_LT(expected, 0.9);  // the borders matter: not the interior value alone
}

TEST(Ssim, LinearRampValidPaddingClosedForm) {
  // x = α·i + β along columns, y = κ·x. A symmetric normalised window keeps the
  // mean (μx = x at the centre) and the variance is α²·v with v = Σ g(k)·k².
  const double alpha = 0.02, beta = 0.1, kappa = 0.6;
  const int w = 30, h = 13;
  Image x(w, h, 1), y(w, h, 1);
  for (int j = 0; j < h; ++j) {
    for (int i = 0; i < w; ++i) {
      x.at(i, j, 0) = float(alpha * i + beta);
      y.at(i, j, 0) = float(kappa * (alpha * i + beta));
    }
  }
  const std::vector<double> g = Taps();
  double v = 0;
  for (int k = -5; k <= 5; ++k) v += g[k + 5] * k * k;
  double sum = 0;
  int count = 0;
  for (int j = 5; j < h - 5; ++j) {
    for (int i = 5; i < w - 5; ++i) {
      const double mu = alpha * i + beta;
      const double var = alpha * alpha * v;
      sum += (2 * kappa * mu * mu + kC1) * (2 * kappa * var + kC2) /
             ((mu * mu * (1 + kappa * kappa) + kC1) * ((1 + kappa * kappa) * var + kC2));
      ++count;
    }
  }
  SsimOptions valid;
  valid.padding = SsimPadding::kValid;
  EXPECT_NEAR(*Ssim(x, y, valid), sum / count, 2e-6);  // float inputs
}

TEST(Ssim, SamePaddingMatchesBruteForceReference) {
  const Image a = Random(19, 12, 3, 7), b = Random(19, 12, 3, 8);
  EXPECT_NEAR(*Ssim(a, b), BruteForceSsimSame(a, b, kC1, kC2), 1e-12);
  Image c = a;  // a correlated pair gives a mid-range value
  for (size_t i = 0; i < c.pixels.size(); ++i) c.pixels[i] = 0.7f * a.pixels[i] + 0.3f * b.pixels[i];
  const double reference = BruteForceSsimSame(a, c, kC1, kC2);
  EXPECT_GT(reference, 0.3);
  EXPECT_NEAR(*Ssim(a, c), reference, 1e-12);
}

TEST(Dssim, DefinitionsAndCompareImages) {
  const Image a = Random(16, 16, 3, 3), b = Random(16, 16, 3, 4);
  SsimOptions r2;
  r2.data_range = 2.0;
  EXPECT_NEAR(*Dssim(a, b, 1.0), (1.0 - *Ssim(a, b)) / 2, 1e-15);
  EXPECT_NEAR(*Dssim(a, b, 2.0), (1.0 - *Ssim(a, b, r2)) / 2, 1e-15);
  // A larger data range means larger constants and a higher SSIM on the same pair.
  EXPECT_LT(*Dssim(a, b, 2.0), *Dssim(a, b, 1.0));
  const ImageMetrics m = *CompareImages(a, b);
  EXPECT_NEAR(m.psnr, *Psnr(a, b), 1e-12);
  EXPECT_NEAR(m.ssim, *Ssim(a, b), 1e-15);
  EXPECT_NEAR(m.dssim2, *Dssim(a, b, 2.0), 1e-15);
  EXPECT_NEAR(m.psnr, -10 * std::log10(m.mse), 1e-12);
}

// Values from scikit-image / scipy (tests/fixtures/ssim/make_ssim_refs.py). The
// images are defined by a formula that the generator and this test share.
Image FormulaImage(int w, int h, bool second) {
  Image image(w, h, 3);
  for (int j = 0; j < h; ++j) {
    for (int i = 0; i < w; ++i) {
      for (int c = 0; c < 3; ++c) {
        double v = 0.5 + 0.4 * std::sin(0.37 * i + 0.91 * j + 1.3 * c);
        if (second) v = std::min(1.0, std::max(0.0, v + 0.15 * std::cos(0.23 * i - 0.57 * j + 0.7 * c)));
        image.at(i, j, c) = static_cast<float>(v);
      }
    }
  }
  return image;
}

TEST(Ssim, MatchesScikitImageReferenceValues) {
  const std::filesystem::path path = testing::SourceDir() / "tests/fixtures/ssim/ssim_refs.json";
  if (!std::filesystem::exists(path)) {
    GTEST_SKIP() << "no reference values (run tests/fixtures/ssim/make_ssim_refs.py to create " << path << ")";
  }
  std::ifstream in(path);
  const nlohmann::json refs = nlohmann::json::parse(in);
  int checked = 0;
  for (const auto& c : refs.at("cases")) {
    const Image a = FormulaImage(c.at("width"), c.at("height"), false);
    const Image b = FormulaImage(c.at("width"), c.at("height"), true);
    SsimOptions options;
    options.data_range = c.at("data_range");
    options.padding = c.at("padding") == "valid" ? SsimPadding::kValid : SsimPadding::kSame;
    EXPECT_NEAR(*Ssim(a, b, options), c.at("ssim").get<double>(), 1e-6) << c.dump();
    if (c.contains("psnr")) {
      EXPECT_NEAR(*Psnr(a, b), c.at("psnr").get<double>(), 1e-6);
    }
    ++checked;
  }
  EXPECT_GT(checked, 0);
}

}  // namespace
}  // namespace atex
