// Internal to the `atex view` writer: the keyframe bake (view_bake.cc) that the page
// assembly (view_html.cc) embeds.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "atex/converters/view.h"

namespace atex::view {

// The Gaussians the page keeps: every index, or the `max_splats` with the largest
// sigmoid(logit) x exp(sum of log-scales) (ties: lower index), ascending.
std::vector<uint32_t> KeptGaussians(const Gaussians& gaussians, size_t max_splats);

// Which arrays change over time for this asset (the enabled deformation heads).
struct Dynamic {
  bool positions = false, rotations = false, scales = false, colours = false;
};
Dynamic DynamicArrays(const Asset& asset);

// Bytes of the payload arrays for `count` Gaussians and `frames` keyframes.
uint64_t PayloadBytes(const Dynamic& dynamic, size_t count, int frames);

// Deforms the kept Gaussians to each time and quantises them (view.h's layout).
// *first_frame (when not null) gets the kept Gaussians deformed to times[0].
StatusOr<ViewPayload> BakeKeyframes(const Asset& asset, const std::vector<uint32_t>& kept,
                                    const std::vector<double>& times, const ViewOptions& options,
                                    Gaussians* first_frame);

// The world direction of an up axis, e.g. (0, 0, 1) for kPosZ.
std::array<double, 3> ViewUpVector(UpAxis up);

// Per axis the 2nd and 98th percentile of the positions of the Gaussians with opacity
// >= 0.2 (every Gaussian when none is): the box the opening camera frames.
void RobustBox(const Gaussians& gaussians, std::array<double, 3>* lo, std::array<double, 3>* hi);

}  // namespace atex::view
