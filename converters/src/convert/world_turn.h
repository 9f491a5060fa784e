// Turning an asset's world so that its up axis (metadata.up, atex/world_up.h) is the
// up axis a file format's readers assume. Internal to converters/.
#pragma once

#include <array>
#include <string>

#include "atex/converters/gltf.h"
#include "atex/model.h"
#include "atex/status.h"

namespace atex::convert {

// Rotates Gaussians by the proper rotation `r` (row-major 3x3; entries 0/±1 here):
// positions r·p, quaternions q_r ⊗ q (w, x, y, z; their length is kept), scales
// unchanged, SH coefficients rotated band by band so that colours follow.
void RotateGaussians(const std::array<double, 9>& r, Gaussians* g);

// The rotation that takes the world's `up` to -Y (the 3DGS PLY / OpenCV convention
// of atex's readers: y down). Identity for kNegY.
std::array<double, 9> RotationToDownY(UpAxis up);

// For a PLY or SPZ writer: when the asset's world up axis is known and is not -Y,
// rotates `g` so that it is (and the SPZ writer's RDF -> RUB conversion then makes it
// +Y). Returns a note for the report ("" when nothing was turned). An asset whose
// up axis is unknown (no metadata.up and an unrecognised axes name) is left as is.
std::string TurnWorldDownY(const Metadata& metadata, Gaussians* g);

}  // namespace atex::convert
