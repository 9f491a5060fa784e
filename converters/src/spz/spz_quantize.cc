// SPZ quantisation and dequantisation of every attribute (see atex/converters/spz.h).
#include <algorithm>
#include <cmath>

#include "convert/bytes.h"
#include "convert/gaussian_checks.h"
#include "spz/spz_packed.h"

namespace atex::converters::spz {

namespace {

constexpr float kColorScale = 0.15f;  // SPZ stores f_dc * 0.15 so that out-of-gamut DC values survive
constexpr float kSqrt1_2 = 0.707106781186547524401f;
constexpr int32_t kMaxFixed = (1 << 23) - 1;

uint8_t ToU8(float x) { return static_cast<uint8_t>(std::clamp(std::round(x), 0.0f, 255.0f)); }

float Sigmoid(float x) { return 1.0f / (1.0f + std::exp(-x)); }

// round(128 x) + 128 kept to `bits` bits by rounding to a multiple of 2^(8 - bits); 0 stays exact.
uint8_t QuantizeSh(float x, int bits) {
  const int bucket = 1 << (8 - bits);
  int q = static_cast<int>(std::round(x * 128.0f) + 128.0f);
  q = (q + bucket / 2) / bucket * bucket;
  return static_cast<uint8_t>(std::clamp(q, 0, 255));
}

// Largest fractional-bit count <= requested at which every |coordinate| fits 24 bits.
StatusOr<int> ChooseFractionalBits(const Gaussians& g, const SpzWriteOptions& options) {
  float max_abs = 0;
  size_t max_index = 0;
  for (size_t i = 0; i < g.positions.size(); ++i) {
    const float a = std::fabs(g.positions[i]);
    if (a > max_abs) {
      max_abs = a;
      max_index = i;
    }
  }
  for (int bits = options.fractional_bits; bits >= 0; --bits) {
    if (std::round(max_abs * static_cast<float>(1 << bits)) <= kMaxFixed) return bits;
    if (!options.reduce_fractional_bits_to_fit) break;
  }
  return MakeError(StatusCode::kOutOfRange, "SPZ writer: position of Gaussian ", max_index / 3, " (component ",
                   max_index % 3, ", value ", g.positions[max_index], ") does not fit 24-bit fixed point with ",
                   options.reduce_fractional_bits_to_fit ? 0 : options.fractional_bits, " fractional bits");
}

// q = (x, y, z, w), unit. Largest |component| index in 2 bits, then for each other
// component in x, y, z, w order: sign bit + 9-bit magnitude of |c| / sqrt(1/2).
void PackSmallestThree(const float q[4], uint8_t out[4]) {
  int largest = 0;
  for (int i = 1; i < 4; ++i) {
    if (std::fabs(q[i]) > std::fabs(q[largest])) largest = i;
  }
  // -q is the same rotation: make the dropped component positive.
  const bool negate = q[largest] < 0;
  uint32_t packed = static_cast<uint32_t>(largest);
  for (int i = 0; i < 4; ++i) {
    if (i == largest) continue;
    const uint32_t sign = (q[i] < 0) != negate ? 1u : 0u;
    const uint32_t magnitude = static_cast<uint32_t>(511.0f * (std::fabs(q[i]) / kSqrt1_2) + 0.5f);
    packed = (packed << 10) | (sign << 9) | std::min(magnitude, 511u);
  }
  bytes::StoreLE(out, packed);
}

void UnpackSmallestThree(const uint8_t in[4], float q[4]) {
  uint32_t packed = bytes::LoadLE<uint32_t>(in);
  const int largest = static_cast<int>(packed >> 30);
  float sum_squares = 0;
  for (int i = 3; i >= 0; --i) {
    if (i == largest) continue;
    const uint32_t magnitude = packed & 511u;
    const uint32_t sign = (packed >> 9) & 1u;
    packed >>= 10;
    q[i] = kSqrt1_2 * static_cast<float>(magnitude) / 511.0f;
    if (sign) q[i] = -q[i];
    sum_squares += q[i] * q[i];
  }
  // Hostile bytes can make the three exceed unit length: clamp instead of a NaN.
  q[largest] = std::sqrt(std::max(0.0f, 1.0f - sum_squares));
}

// q = (x, y, z, w), unit: stores x, y, z with w made non-negative.
void PackFirstThree(const float q[4], uint8_t out[3]) {
  const float s = q[3] < 0 ? -127.5f : 127.5f;
  for (int k = 0; k < 3; ++k) out[k] = ToU8(q[k] * s + 127.5f);
}

void UnpackFirstThree(const uint8_t in[3], float q[4]) {
  float sum = 0;
  for (int k = 0; k < 3; ++k) {
    q[k] = static_cast<float>(in[k]) * (1.0f / 127.5f) - 1.0f;
    sum += q[k] * q[k];
  }
  q[3] = std::sqrt(std::max(0.0f, 1.0f - sum));
}

}  // namespace

StatusOr<PackedSpz> PackGaussians(const Gaussians& g, const SpzWriteOptions& options, const AxisFlip& to_file) {
  ATEX_RETURN_IF_ERROR(CheckGaussianShapes(g, "SPZ writer"));
  ATEX_RETURN_IF_ERROR(CheckGaussiansFinite(g, "SPZ writer"));
  if (options.version != 3 && options.version != 4) {
    return MakeError(StatusCode::kInvalidArgument, "SPZ writer: version ", options.version, " (writes 3 or 4)");
  }
  if (options.sh1_bits < 1 || options.sh1_bits > 8 || options.sh_rest_bits < 1 || options.sh_rest_bits > 8) {
    return MakeError(StatusCode::kInvalidArgument, "SPZ writer: SH bits ", options.sh1_bits, "/",
                     options.sh_rest_bits, " outside 1..8");
  }
  if (options.fractional_bits < 0 || options.fractional_bits > kMaxFractionalBits) {
    return MakeError(StatusCode::kInvalidArgument, "SPZ writer: fractional_bits ", options.fractional_bits,
                     " outside 0..", kMaxFractionalBits);
  }
  const size_t n = g.size();
  if (n == 0) {
    return MakeError(StatusCode::kInvalidArgument,
                     "SPZ writer: no Gaussians (SPZ readers, the reference one included, refuse empty files)");
  }
  if (n > 0xffffffffu) {
    return MakeError(StatusCode::kLimitExceeded, "SPZ writer: ", n, " Gaussians exceed the u32 count field");
  }
  PackedSpz packed;
  packed.version = options.version;
  packed.num_points = static_cast<uint32_t>(n);
  packed.sh_degree = g.sh_degree;
  packed.flags = options.antialiased ? kFlagAntialiased : 0;
  ATEX_ASSIGN_OR_RETURN(packed.fractional_bits, ChooseFractionalBits(g, options));

  packed.positions.resize(n * 9);
  packed.alphas.resize(n);
  packed.colors.resize(n * 3);
  packed.scales.resize(n * 3);
  packed.rotations.resize(n * packed.rotation_bytes());
  const int dim = StoredShDim(g.sh_degree);
  packed.sh.resize(n * static_cast<size_t>(dim) * 3);

  const float fixed_scale = static_cast<float>(1 << packed.fractional_bits);
  const auto qsign = to_file.QuaternionSigns();
  const int k_count = g.sh_coeffs();
  float sh_signs[16];
  for (int k = 1; k < 16; ++k) sh_signs[k] = to_file.ShSign(k);

  for (size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) {
      const float p = to_file.sign[k] * g.positions[i * 3 + k];
      const int32_t fixed = static_cast<int32_t>(std::round(p * fixed_scale));
      uint8_t* out = &packed.positions[(i * 3 + k) * 3];
      out[0] = static_cast<uint8_t>(fixed & 0xff);
      out[1] = static_cast<uint8_t>((fixed >> 8) & 0xff);
      out[2] = static_cast<uint8_t>((fixed >> 16) & 0xff);
    }
    for (int k = 0; k < 3; ++k) packed.scales[i * 3 + k] = ToU8((g.log_scales[i * 3 + k] + 10.0f) * 16.0f);

    // Ours is (w, x, y, z); SPZ works on (x, y, z, w).
    const float* r = &g.rotations[i * 4];
    float q[4] = {qsign[0] * r[1], qsign[1] * r[2], qsign[2] * r[3], r[0]};
    const float norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (!(norm > 0) || !std::isfinite(norm)) {
      return MakeError(StatusCode::kOutOfRange, "SPZ writer: rotation of Gaussian ", i,
                       " has zero length; no orientation to store");
    }
    for (float& c : q) c /= norm;
    if (packed.uses_smallest_three()) {
      PackSmallestThree(q, &packed.rotations[i * 4]);
    } else {
      PackFirstThree(q, &packed.rotations[i * 3]);
    }

    packed.alphas[i] = ToU8(Sigmoid(g.opacity_logits[i]) * 255.0f);
    const float* sh = &g.sh[i * static_cast<size_t>(k_count) * 3];  // [K][3]
    for (int c = 0; c < 3; ++c) packed.colors[i * 3 + c] = ToU8(sh[c] * (kColorScale * 255.0f) + 0.5f * 255.0f);
    uint8_t* out_sh = packed.sh.data() + i * static_cast<size_t>(dim) * 3;  // not [] : may be empty
    for (int k = 1; k < k_count; ++k) {
      const int bits = k <= 3 ? options.sh1_bits : options.sh_rest_bits;
      for (int c = 0; c < 3; ++c) out_sh[(k - 1) * 3 + c] = QuantizeSh(sh_signs[k] * sh[k * 3 + c], bits);
    }
  }
  return packed;
}

Gaussians UnpackGaussians(const PackedSpz& packed, const AxisFlip& from_file) {
  const size_t n = packed.num_points;
  const int stored_dim = StoredShDim(packed.sh_degree);
  Gaussians g;
  g.sh_degree = std::min(packed.sh_degree, kMaxShDegree);
  g.Resize(n);
  const int k_count = g.sh_coeffs();
  const auto qsign = from_file.QuaternionSigns();
  float sh_signs[16];
  for (int k = 1; k < 16; ++k) sh_signs[k] = from_file.ShSign(k);
  const float fixed_step = 1.0f / static_cast<float>(1 << packed.fractional_bits);

  for (size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) {
      float p;
      if (packed.uses_half_positions()) {
        p = bytes::HalfToFloat(bytes::LoadLE<uint16_t>(&packed.positions[(i * 3 + k) * 2]));
      } else {
        const uint8_t* in = &packed.positions[(i * 3 + k) * 3];
        int32_t fixed = in[0] | (in[1] << 8) | (in[2] << 16);
        if (fixed & 0x800000) fixed -= 1 << 24;  // sign extension
        p = static_cast<float>(fixed) * fixed_step;
      }
      g.positions[i * 3 + k] = from_file.sign[k] * p;
    }
    for (int k = 0; k < 3; ++k) g.log_scales[i * 3 + k] = packed.scales[i * 3 + k] / 16.0f - 10.0f;

    float q[4];  // (x, y, z, w)
    if (packed.uses_smallest_three()) {
      UnpackSmallestThree(&packed.rotations[i * 4], q);
    } else {
      UnpackFirstThree(&packed.rotations[i * 3], q);
    }
    float* r = &g.rotations[i * 4];
    r[0] = q[3];
    for (int k = 0; k < 3; ++k) r[1 + k] = qsign[k] * q[k];

    // Clamped away from 0 and 1 so that the logit stays finite.
    const float alpha = std::clamp(packed.alphas[i] / 255.0f, 1.0f / 255.0f, 254.0f / 255.0f);
    g.opacity_logits[i] = std::log(alpha / (1.0f - alpha));

    float* sh = &g.sh[i * static_cast<size_t>(k_count) * 3];
    for (int c = 0; c < 3; ++c) sh[c] = (packed.colors[i * 3 + c] / 255.0f - 0.5f) / kColorScale;
    const uint8_t* in_sh = packed.sh.data() + i * static_cast<size_t>(stored_dim) * 3;  // may be empty
    for (int k = 1; k < k_count; ++k) {
      for (int c = 0; c < 3; ++c) sh[k * 3 + c] = sh_signs[k] * ((in_sh[(k - 1) * 3 + c] - 128.0f) / 128.0f);
    }
  }
  return g;
}

}  // namespace atex::converters::spz
