// Ranges of the deformation configuration that the container can store
// (format_spec/atex.md §7.5). Shared by ValidateAsset and the DCFG reader so that
// whatever validates can be written and whatever is read validates.
#pragma once

#include <cstdint>

namespace atex::limits {

inline constexpr int kMaxChannels = 1024;
inline constexpr int kMaxBaseResolution = 8192;
inline constexpr int kMaxScales = 8;
inline constexpr int kMaxMultires = 64;
inline constexpr int64_t kMaxSpatialResolution = 65536;  // base_resolution * multires
inline constexpr int kMaxMlpWidth = 4096;
inline constexpr int kMaxTrunkLayers = 64;
inline constexpr int kMaxJsonDepth = 64;
// Magnitudes a renderer can use without overflowing float (issue 24: `verify` passed MLP
// weights of 2.7e37 and rotations of 1e30 that `render` then refused). A rotation's squared
// norm must stay finite; the deformation network's grid features and weights are O(1) when
// trained, and 1e6 leaves its sums and products far from overflow.
inline constexpr float kMaxAbsRotation = 1e15f;
inline constexpr float kMaxAbsNetworkValue = 1e6f;

}  // namespace atex::limits
