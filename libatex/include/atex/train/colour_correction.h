// Per-training-camera colour correction (issue 20; Dynamic 3D Gaussians learn the same
// per-camera scale and offset on CMU Panoptic).
//
// The cameras of a multi-view rig differ in colour response (white balance, gain, sensor).
// A model trained on their raw images explains those differences with view-dependent colour
// and semi-transparent mass that only some views see, which does not carry over to a held-out
// camera. With the correction, the loss compares each training view's target with
//
//   rendered'_c = gain_c · rendered_c + offset_c        (c = R, G, B; per training camera)
//
// so the model keeps one colour space, that of the rig's average camera. The corrections are
// fitted in closed form from the current model (FitColourAffine, trimmed least squares over the
// camera's pixels), then normalised over the cameras (mean gain 1, mean offset 0 per channel,
// up to the bounds below, which the normalised values keep too), alternating with training
// (TrainConfig::camera_colour). Test views render without any correction: a held-out camera's
// response is unknown, the average is the best guess.
#pragma once

#include <array>
#include <cstddef>
#include <vector>

#include "atex/image.h"
#include "atex/status.h"

namespace atex::train {

struct ColourAffine {
  std::array<float, 3> gain{1, 1, 1};
  std::array<float, 3> offset{0, 0, 0};
  bool IsIdentity() const {
    return gain == std::array<float, 3>{1, 1, 1} && offset == std::array<float, 3>{0, 0, 0};
  }
  // rgb: [pixels][3], transformed in place.
  void Apply(float* rgb, size_t pixels) const;
  // d/d(rendered) of the corrected image: grad [pixels][3] scaled by gain, in place.
  void ScaleGradient(float* grad, size_t pixels) const;
};

// Gains outside this range are clamped: a camera that much off is a broken frame, not a response.
inline constexpr float kMinColourGain = 0.5f, kMaxColourGain = 2.0f;
inline constexpr float kMaxColourOffset = 0.25f;

// Least-squares target ≈ gain · rendered + offset per channel over the pixels of `pairs`
// (rendered, target images of one camera, [H][W][>=3], equal shapes), then refitted on the
// pixels whose residual is within the `keep` quantile (0 < keep <= 1) of the first fit's, so
// that what the model gets wrong (a moving object, a floater) does not bend the colour fit.
// Rendered values are clamped to [0, 1] first. kInvalidArgument for mismatched shapes, no
// pairs or keep outside (0, 1]; a channel with (almost) no spread in the render keeps gain 1 and
// fits the offset only. Gains are clamped to [kMinColourGain, kMaxColourGain], offsets to
// ±kMaxColourOffset.
struct ImagePair {
  const Image* rendered = nullptr;
  const Image* target = nullptr;
};
StatusOr<ColourAffine> FitColourAffine(const std::vector<ImagePair>& pairs, double keep = 0.9);

// Fixes the gauge of a set of per-camera corrections: per channel, divides every gain by the
// cameras' mean gain and subtracts the mean offset, so that the average camera is the identity
// (the colour space the model renders test views in). The results are clamped to the bounds
// above, like a fit's, so every one of them can be stored and read back; a clamped camera leaves
// the mean slightly off the identity (its offset is re-expressed with its unclamped gain).
// Empty: nothing to do.
void NormaliseColourAffines(std::vector<ColourAffine>* affines);

}  // namespace atex::train
