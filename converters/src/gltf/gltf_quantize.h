// The quantised base attributes of `atex export --quantize` (KHR_mesh_quantization with the
// normalized integer types KHR_gaussian_splatting allows). Pure encoders: the exporter puts the
// bytes into bufferViews. Internal header.
//
// Layout (every vertex attribute element 4-byte aligned, as glTF requires):
//   POSITION  SHORT normalized VEC3, stride 8 (x, y, z, 2 bytes of padding). Decoded values
//             q in [-1, 1]^3 lie in the frame of the node, whose uniform scale s and translation
//             map them back: asset position = center + s * q (the node's own rotation, the
//             upright turn, comes after; the exporter sets node.translation = R * center).
//             s is the largest half-extent of the positions' bounding box (1 when it is 0), so
//             the error is at most s / 65534 per axis (plus float rounding of the node values).
//   SCALE     UNSIGNED_SHORT normalized VEC3, stride 8, in the same node units: the linear scale
//             divided by s, rounded, kept in [1, 65535]: error at most s / 131070; scales below
//             one step (s / 65535) become one step, scales above s (a splat larger than half the
//             scene) are clipped to s. KHR_gaussian_splatting (since its April 2026 editorial
//             review) lists only float and unsigned integer types for SCALE, whose values are
//             linear and never negative; signed types belonged to the superseded log-space text.
//   OPACITY   UNSIGNED_SHORT normalized SCALAR, stride 4: error at most 1 / 131070.
//   ROTATION  BYTE normalized VEC4 (x, y, z, w), stride 4: each component within 1 / 254 of
//             the unit quaternion (with meshopt the exporter uses the QUATERNION filter instead).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <nlohmann/json.hpp>

#include "atex/model.h"
#include "atex/status.h"

namespace atex::gltf {

// Asset position = center + scale * (decoded normalized value).
struct PositionFrame {
  std::array<float, 3> center = {0, 0, 0};
  float scale = 1;
};

struct QuantizedGeometry {
  PositionFrame frame;
  std::vector<uint8_t> positions;  // [N][8] int16 x, y, z, 0
  std::vector<uint8_t> scales;     // [N][8] uint16 sx, sy, sz, 0
  std::vector<uint8_t> opacities;  // [N][4] uint16, 0
  nlohmann::json position_min, position_max;  // per-component integers, as glTF wants for integer accessors
  size_t clipped_scales = 0;      // components clipped to s
};

// The frame and the quantised positions, scales (linear: exp of the log-scales) and opacities
// (`opacities` [N], already in [0, 1]). kOutOfRange when a position is not finite or the
// bounding box overflows float.
StatusOr<QuantizedGeometry> QuantizeGeometry(const Gaussians& g, const std::vector<float>& opacities);

// `xyzw` [N][4] unit quaternions -> [N][4] int8, normalized (round(127 * c)).
std::vector<uint8_t> QuantizeRotations(const std::vector<float>& xyzw);

// The unit quaternions (x, y, z, w) of the Gaussians' rotations, [N][4]; a zero quaternion,
// which no renderer can use, becomes the identity.
std::vector<float> UnitQuaternionsXyzw(const Gaussians& g);

}  // namespace atex::gltf
