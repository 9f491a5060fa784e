// antimatter15 .splat reading (see atex/converters/web_splats.h).
#include <algorithm>
#include <cmath>

#include "atex/converters/web_splats.h"
#include "atex/file_io.h"
#include "convert/bytes.h"

namespace atex {

namespace {
constexpr size_t kSplatRow = 32;
constexpr double kShC0 = 0.28209479177387814;
}  // namespace

StatusOr<Gaussians> ReadSplatGaussiansFromMemory(const uint8_t* data, size_t size, const WebSplatLimits& limits) {
  using converters::bytes::LoadLE;
  if (data == nullptr && size != 0) return MakeError(StatusCode::kInvalidArgument, ".splat: null data");
  if (size % kSplatRow != 0) {
    return MakeError(StatusCode::kCorrupt, ".splat: ", size, " bytes is not a whole number of 32-byte Gaussians (",
                     size % kSplatRow, " bytes left over at byte ", size - size % kSplatRow, ")");
  }
  const size_t n = size / kSplatRow;
  if (n > limits.max_gaussians) {
    return MakeError(StatusCode::kLimitExceeded, ".splat: ", n, " Gaussians exceed the limit of ",
                     limits.max_gaussians);
  }
  Gaussians g;
  g.sh_degree = 0;
  g.Resize(n);
  for (size_t i = 0; i < n; ++i) {
    const uint8_t* row = data + i * kSplatRow;
    for (int k = 0; k < 3; ++k) {
      const float p = LoadLE<float>(row + 4 * k);
      if (!std::isfinite(p)) {
        return MakeError(StatusCode::kOutOfRange, ".splat: Gaussian ", i, " (byte ", i * kSplatRow + 4 * k,
                         ") has a position that is not finite");
      }
      g.positions[i * 3 + k] = p;
      const float s = LoadLE<float>(row + 12 + 4 * k);
      if (!(s > 0) || !std::isfinite(s)) {
        return MakeError(StatusCode::kCorrupt, ".splat: Gaussian ", i, " (byte ", i * kSplatRow + 12 + 4 * k,
                         ") has scale ", s, ", not a positive finite number");
      }
      g.log_scales[i * 3 + k] = std::log(s);
      g.sh[i * 3 + k] = float((row[24 + k] / 255.0 - 0.5) / kShC0);
    }
    // Alpha byte = sigmoid(logit) x 255; 0 and 255 are clamped so the logit stays finite.
    const double alpha = std::clamp(row[27] / 255.0, 0.5 / 255, 254.5 / 255);
    g.opacity_logits[i] = float(std::log(alpha / (1 - alpha)));
    double q[4], length = 0;
    for (int k = 0; k < 4; ++k) {
      q[k] = (double(row[28 + k]) - 128.0) / 128.0;
      length += q[k] * q[k];
    }
    if (length == 0) q[0] = 1, length = 1;  // a zero rotation: the identity
    length = std::sqrt(length);
    for (int k = 0; k < 4; ++k) g.rotations[i * 4 + k] = float(q[k] / length);
  }
  return g;
}

StatusOr<Gaussians> ReadSplatGaussians(const std::string& path, const WebSplatLimits& limits) {
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, ReadFileBytes(path));
  auto result = ReadSplatGaussiansFromMemory(bytes.data(), bytes.size(), limits);
  if (!result.ok()) return result.status().WithContext(path);
  return result;
}

}  // namespace atex
