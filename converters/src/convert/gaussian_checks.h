// Shape and value checks that every writer in converters/ runs on its input
// Gaussians before encoding anything. Internal header.
#pragma once

#include <string_view>

#include "atex/model.h"
#include "atex/status.h"

namespace atex::converters {

// kInvalidArgument if the arrays of `g` disagree with N = g.size() or the SH
// degree is outside 0..3; the message names the array and its expected size.
Status CheckGaussianShapes(const Gaussians& g, std::string_view what);

// kOutOfRange naming the array and element index of the first NaN/Inf value.
Status CheckGaussiansFinite(const Gaussians& g, std::string_view what);

}  // namespace atex::converters
