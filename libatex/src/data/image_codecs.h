// Per-format codecs behind atex/image.h (not a public header). Each decoder
// checks the limits of image.h before allocating pixels and never throws.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "atex/image.h"
#include "atex/status.h"

namespace atex::image_detail {

// Checks width/height against kMaxImageSide / kMaxImagePixels (kLimitExceeded)
// and against zero (kCorrupt).
Status CheckDimensions(int64_t width, int64_t height, const std::string& what);

StatusOr<Image> DecodePng(const uint8_t* data, size_t size, const std::string& what);
StatusOr<ImageInfo> PngInfo(const uint8_t* data, size_t size, const std::string& what);
StatusOr<std::vector<uint8_t>> EncodePng(const Image& image, int bit_depth);

StatusOr<Image> DecodeJpeg(const uint8_t* data, size_t size, const std::string& what);
StatusOr<ImageInfo> JpegInfo(const uint8_t* data, size_t size, const std::string& what);
StatusOr<std::vector<uint8_t>> EncodeJpeg(const Image& image, int quality);

bool ExrSupported();
StatusOr<Image> DecodeExr(const uint8_t* data, size_t size, const std::string& what);
StatusOr<ImageInfo> ExrInfo(const uint8_t* data, size_t size, const std::string& what);
StatusOr<std::vector<uint8_t>> EncodeExr(const Image& image);

// Float in [0, 1] (clamped, NaN -> 0) to an integer level in [0, max_level], rounded.
inline uint32_t ToLevel(float value, uint32_t max_level) {
  if (!(value > 0.0f)) return 0;  // also NaN
  if (value >= 1.0f) return max_level;
  return static_cast<uint32_t>(value * static_cast<float>(max_level) + 0.5f);
}

}  // namespace atex::image_detail
