// Axis flips between coordinate conventions that differ only by the sign of
// some axes (RUB, RDF, LUF, ...), applied to positions, quaternions and SH.
// Internal to converters/src/spz.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>

namespace atex::converters::spz {

// x_target = diag(sign) * x_source.
struct AxisFlip {
  std::array<float, 3> sign{1, 1, 1};

  // Composition of two flips (they commute).
  AxisFlip Then(const AxisFlip& other) const {
    return {{sign[0] * other.sign[0], sign[1] * other.sign[1], sign[2] * other.sign[2]}};
  }
  bool IsIdentity() const { return sign[0] > 0 && sign[1] > 0 && sign[2] > 0; }

  // A rotation R becomes M R M with M = diag(sign). The rotation axis is a
  // pseudovector, so quaternion component x picks up sign_y * sign_z, etc.;
  // w is unchanged. Returns the factors for (x, y, z).
  std::array<float, 3> QuaternionSigns() const {
    return {sign[1] * sign[2], sign[0] * sign[2], sign[0] * sign[1]};
  }

  // Sign of SH coefficient k (1..15, 3DGS real basis order) under the flip:
  // each basis function is a polynomial whose parity in x, y, z is fixed.
  float ShSign(int k) const {
    // Parity bits (x, y, z) of basis functions 1..15:
    // y, z, x | xy, yz, 1, xz, 1 | y, xyz, y, z, x, z, x.
    static constexpr uint8_t kParity[16] = {0,     0b010, 0b001, 0b100, 0b110, 0b011, 0b000, 0b101,
                                            0b000, 0b010, 0b111, 0b010, 0b001, 0b100, 0b001, 0b100};
    const uint8_t bits = kParity[k];
    float s = 1.0f;
    if (bits & 0b100) s *= sign[0];
    if (bits & 0b010) s *= sign[1];
    if (bits & 0b001) s *= sign[2];
    return s;
  }
};

// SPZ_ADOBE_coordinate_system values (the order of spz::CoordinateSystem):
// 0 UNSPECIFIED (= RUB), 1 LDB, 2 RDB, 3 LUB, 4 RUB, 5 LDF, 6 RDF, 7 LUF, 8 RUF, 9..16 rotated family.
inline constexpr uint32_t kSpzCoordinateSystemCount = 17;

// Name of a coordinate-system value ("RUB", ...; "?" when unknown).
inline std::string CoordinateSystemName(uint32_t value) {
  static const char* kNames[kSpzCoordinateSystemCount] = {"UNSPECIFIED", "LDB", "RDB", "LUB", "RUB", "LDF",
                                                          "RDF",         "LUF", "RUF", "LFD", "RFD", "LFU",
                                                          "RFU",         "LBD", "RBD", "LBU", "RBU"};
  return value < kSpzCoordinateSystemCount ? kNames[value] : "?";
}

// The flip from a standard-family system (values 0..8) to RDF (libatex's
// OpenCV-style world); empty for the rotated family, which needs a rotation.
inline std::optional<AxisFlip> FlipToRdf(uint32_t value) {
  if (value == 0) value = 4;  // unspecified: the spec's default RUB
  if (value < 1 || value > 8) return std::nullopt;
  const std::string name = CoordinateSystemName(value);
  return AxisFlip{{name[0] == 'R' ? 1.0f : -1.0f, name[1] == 'D' ? 1.0f : -1.0f, name[2] == 'F' ? 1.0f : -1.0f}};
}

}  // namespace atex::converters::spz
