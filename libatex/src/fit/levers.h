// The structural levers of the fitter (fit.h): subsets of Gaussians, a lower SH
// degree, coarser deformation grids. Each returns a valid asset for a valid input.
#pragma once

#include <cstdint>
#include <vector>

#include "atex/model.h"
#include "atex/status.h"

namespace atex::fit {

// The Gaussians whose keep[i] is non-zero, with their textures and statistics.
Asset SubsetGaussians(const Asset& asset, const std::vector<uint8_t>& keep);

// A copy of `asset`, its large arrays copied on several threads (a fitter candidate copies a
// whole asset of hundreds of megabytes). Without `with_texture_pool`, the copy has no texture
// pool: for a caller that builds a new one.
Asset CopyAsset(const Asset& asset, bool with_texture_pool = true);

// SH degree d → d − 1 (coefficients of band d dropped; the deformation field's SH
// head, when on, loses the matching outputs). kInvalidArgument at degree 0.
Status LowerShDegree(Asset* asset);

// Spatial grid resolution r → max(min_resolution, ceil(r / 2)) on every scale,
// resampled bilinearly (align-corners, as the field samples). False when the grids
// are already at min_resolution (nothing changed) or the asset has no field.
bool CanCoarsenGrid(const Asset& asset, int min_resolution);
Status CoarsenGrid(Asset* asset, int min_resolution);

}  // namespace atex::fit
