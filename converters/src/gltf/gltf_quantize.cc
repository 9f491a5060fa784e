#include "gltf/gltf_quantize.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

namespace atex::gltf {
namespace {

constexpr double kShortMax = 32767.0;
constexpr double kUnsignedShortMax = 65535.0;

void PutI16(uint8_t* at, long v) {
  const int16_t x = int16_t(v);
  std::memcpy(at, &x, 2);  // little-endian host (static_assert in gltf_export.cc)
}

}  // namespace

std::vector<float> UnitQuaternionsXyzw(const Gaussians& g) {
  const size_t n = g.size();
  std::vector<float> xyzw(n * 4);
  for (size_t i = 0; i < n; ++i) {
    const float* q = &g.rotations[i * 4];  // (w, x, y, z)
    const double norm =
        std::sqrt(double(q[0]) * q[0] + double(q[1]) * q[1] + double(q[2]) * q[2] + double(q[3]) * q[3]);
    float* out = &xyzw[i * 4];
    if (norm > 0) {
      out[0] = float(q[1] / norm), out[1] = float(q[2] / norm), out[2] = float(q[3] / norm),
      out[3] = float(q[0] / norm);
    } else {
      out[0] = 0, out[1] = 0, out[2] = 0, out[3] = 1;
    }
  }
  return xyzw;
}

std::vector<uint8_t> QuantizeRotations(const std::vector<float>& xyzw) {
  std::vector<uint8_t> out(xyzw.size());
  for (size_t i = 0; i < xyzw.size(); ++i) {
    const long v = std::clamp(std::lround(double(xyzw[i]) * 127.0), -127L, 127L);
    out[i] = uint8_t(int8_t(v));
  }
  return out;
}

StatusOr<QuantizedGeometry> QuantizeGeometry(const Gaussians& g, const std::vector<float>& opacities) {
  const size_t n = g.size();
  if (opacities.size() != n) return MakeError(StatusCode::kInternal, "quantise: ", opacities.size(), " opacities");
  QuantizedGeometry out;
  // The frame: the bounding box's centre (as float, the node's precision) and the largest distance
  // from it, rounded up to a float so that every position maps into [-1, 1].
  std::array<double, 3> lo, hi;
  lo.fill(std::numeric_limits<double>::infinity());
  hi.fill(-std::numeric_limits<double>::infinity());
  for (size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) {
      const double p = g.positions[i * 3 + size_t(k)];
      if (!std::isfinite(p)) {
        return MakeError(StatusCode::kOutOfRange, "quantise: position ", i, " component ", k, " is not finite");
      }
      lo[k] = std::min(lo[k], p);
      hi[k] = std::max(hi[k], p);
    }
  }
  double reach = 0;
  for (int k = 0; k < 3; ++k) {
    out.frame.center[k] = float(0.5 * lo[k] + 0.5 * hi[k]);
    reach = std::max({reach, hi[k] - double(out.frame.center[k]), double(out.frame.center[k]) - lo[k]});
  }
  if (!(reach < double(std::numeric_limits<float>::max())))
    return MakeError(StatusCode::kOutOfRange, "quantise: the positions' bounding box overflows float");
  float s = float(reach);
  if (double(s) < reach) s = std::nextafter(s, std::numeric_limits<float>::infinity());
  if (!(s > 0)) s = 1;  // one point, or all at one place
  out.frame.scale = s;

  out.positions.assign(n * 8, 0);
  out.scales.assign(n * 8, 0);
  out.opacities.assign(n * 4, 0);
  std::array<long, 3> qmin = {32767, 32767, 32767}, qmax = {-32767, -32767, -32767};
  for (size_t i = 0; i < n; ++i) {
    for (size_t k = 0; k < 3; ++k) {
      const double rel = (double(g.positions[i * 3 + k]) - double(out.frame.center[k])) / double(s);
      const long q = std::clamp(std::lround(rel * kShortMax), -32767L, 32767L);
      PutI16(&out.positions[i * 8 + 2 * k], q);
      qmin[k] = std::min(qmin[k], q);
      qmax[k] = std::max(qmax[k], q);

      const double linear = std::exp(double(g.log_scales[i * 3 + k])) / double(s);
      const double steps = std::round(linear * kUnsignedShortMax);
      if (steps > kUnsignedShortMax) ++out.clipped_scales;
      // NaN log-scales are refused by ValidateAsset before export; clamp keeps any value in range.
      const double qs = std::isfinite(steps) ? std::clamp(steps, 1.0, kUnsignedShortMax) : kUnsignedShortMax;
      const uint16_t us = uint16_t(qs);
      std::memcpy(&out.scales[i * 8 + 2 * k], &us, 2);
    }
    const long qo = std::clamp(std::lround(double(opacities[i]) * kUnsignedShortMax), 0L, 65535L);
    const uint16_t o = uint16_t(qo);
    std::memcpy(&out.opacities[i * 4], &o, 2);
  }
  out.position_min = nlohmann::json::array({qmin[0], qmin[1], qmin[2]});
  out.position_max = nlohmann::json::array({qmax[0], qmax[1], qmax[2]});
  return out;
}

}  // namespace atex::gltf
