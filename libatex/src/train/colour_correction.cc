#include "atex/train/colour_correction.h"

#include <algorithm>
#include <cmath>

namespace atex::train {

void ColourAffine::Apply(float* rgb, size_t pixels) const {
  for (size_t p = 0; p < pixels; ++p) {
    for (int c = 0; c < 3; ++c) rgb[3 * p + c] = gain[c] * rgb[3 * p + c] + offset[c];
  }
}

void ColourAffine::ScaleGradient(float* grad, size_t pixels) const {
  for (size_t p = 0; p < pixels; ++p) {
    for (int c = 0; c < 3; ++c) grad[3 * p + c] *= gain[c];
  }
}

namespace {

// Sums of one channel's least-squares fit.
struct Moments {
  double n = 0, x = 0, y = 0, xx = 0, xy = 0;
  void Add(double a, double b) { n += 1, x += a, y += b, xx += a * a, xy += a * b; }
};

// (gain, offset) of y ≈ g·x + o; gain 1 when x has (almost) no spread.
std::pair<double, double> Solve(const Moments& m) {
  if (m.n < 1) return {1.0, 0.0};
  const double mx = m.x / m.n, my = m.y / m.n;
  const double var = m.xx / m.n - mx * mx;
  const double cov = m.xy / m.n - mx * my;
  if (!(var > 1e-6)) return {1.0, my - mx};
  const double g = cov / var;
  return {g, my - g * mx};
}

}  // namespace

StatusOr<ColourAffine> FitColourAffine(const std::vector<ImagePair>& pairs, double keep) {
  if (pairs.empty()) return MakeError(StatusCode::kInvalidArgument, "colour fit: no images");
  if (!(keep > 0 && keep <= 1))
    return MakeError(StatusCode::kInvalidArgument, "colour fit: keep ", keep, " outside (0, 1]");
  for (size_t i = 0; i < pairs.size(); ++i) {
    const Image* r = pairs[i].rendered;
    const Image* t = pairs[i].target;
    if (r == nullptr || t == nullptr || r->width != t->width || r->height != t->height || r->channels < 3 ||
        t->channels < 3 || r->pixels.empty()) {
      return MakeError(StatusCode::kInvalidArgument, "colour fit: image pair ", i, " is missing or of unequal shape");
    }
  }
  auto value = [](const Image& im, size_t p, int c) { return double(im.pixels[p * im.channels + c]); };
  auto rendered = [&](const Image& im, size_t p, int c) { return std::clamp(value(im, p, c), 0.0, 1.0); };
  std::array<std::pair<double, double>, 3> fit;
  {
    std::array<Moments, 3> m;
    for (const ImagePair& pair : pairs) {
      const size_t pixels = size_t(pair.rendered->width) * pair.rendered->height;
      for (size_t p = 0; p < pixels; ++p) {
        for (int c = 0; c < 3; ++c) m[c].Add(rendered(*pair.rendered, p, c), value(*pair.target, p, c));
      }
    }
    for (int c = 0; c < 3; ++c) fit[c] = Solve(m[c]);
  }
  if (keep < 1) {
    // Residual of a pixel: the largest over its channels, so an object the model misses drops whole.
    std::vector<float> residuals;
    for (const ImagePair& pair : pairs) {
      const size_t pixels = size_t(pair.rendered->width) * pair.rendered->height;
      for (size_t p = 0; p < pixels; ++p) {
        double worst = 0;
        for (int c = 0; c < 3; ++c) {
          const double e = fit[c].first * rendered(*pair.rendered, p, c) + fit[c].second - value(*pair.target, p, c);
          worst = std::max(worst, std::abs(e));
        }
        residuals.push_back(static_cast<float>(worst));
      }
    }
    std::vector<float> sorted = residuals;
    const size_t at = std::min(sorted.size() - 1, static_cast<size_t>(keep * double(sorted.size())));
    std::nth_element(sorted.begin(), sorted.begin() + at, sorted.end());
    const float limit = sorted[at];
    std::array<Moments, 3> m;
    size_t k = 0;
    for (const ImagePair& pair : pairs) {
      const size_t pixels = size_t(pair.rendered->width) * pair.rendered->height;
      for (size_t p = 0; p < pixels; ++p, ++k) {
        if (residuals[k] > limit) continue;
        for (int c = 0; c < 3; ++c) m[c].Add(rendered(*pair.rendered, p, c), value(*pair.target, p, c));
      }
    }
    for (int c = 0; c < 3; ++c) fit[c] = Solve(m[c]);
  }
  ColourAffine out;
  for (int c = 0; c < 3; ++c) {
    out.gain[c] = static_cast<float>(std::clamp(fit[c].first, double(kMinColourGain), double(kMaxColourGain)));
    out.offset[c] = static_cast<float>(std::clamp(fit[c].second, -double(kMaxColourOffset), double(kMaxColourOffset)));
  }
  return out;
}

void NormaliseColourAffines(std::vector<ColourAffine>* affines) {
  if (affines->empty()) return;
  for (int c = 0; c < 3; ++c) {
    double gain = 0, offset = 0;
    for (const ColourAffine& a : *affines) gain += a.gain[c], offset += a.offset[c];
    gain /= double(affines->size());
    offset /= double(affines->size());
    // With gains g_i and offsets o_i, the average camera maps x to ḡx + ō. Re-expressing the
    // model's colour space so that this is the identity: x' = ḡx + ō, hence
    // g_i x + o_i = (g_i/ḡ) x' + (o_i − g_i ō/ḡ).
    // The re-expression can carry a camera past the bounds that every stored correction obeys
    // (CameraColours::FromJson refuses it, and with it a checkpoint or another rank's copy:
    // a 2-GPU Panoptic run stopped on an offset of -0.256), so it is clamped like a fit.
    for (ColourAffine& a : *affines) {
      const double g = a.gain[c] / gain;
      a.offset[c] = static_cast<float>(
          std::clamp(a.offset[c] - g * offset, -double(kMaxColourOffset), double(kMaxColourOffset)));
      a.gain[c] = static_cast<float>(std::clamp(g, double(kMinColourGain), double(kMaxColourGain)));
    }
  }
}

}  // namespace atex::train
