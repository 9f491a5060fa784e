// Format dispatch (by magic bytes for reading, by extension for writing) and
// atomic image writes.
#include <algorithm>
#include <cctype>
#include <filesystem>

#include "atex/file_io.h"
#include "atex/image.h"
#include "data/image_codecs.h"

namespace atex {
namespace image_detail {

Status CheckDimensions(int64_t width, int64_t height, const std::string& what) {
  if (width <= 0 || height <= 0) {
    return MakeError(StatusCode::kCorrupt, what, ": image dimensions ", width, "x", height);
  }
  if (width > kMaxImageSide || height > kMaxImageSide ||
      static_cast<uint64_t>(width) * static_cast<uint64_t>(height) > kMaxImagePixels) {
    return MakeError(StatusCode::kLimitExceeded, what, ": image of ", width, "x", height,
                     " exceeds the decoder limits (", kMaxImageSide, " per side, ", kMaxImagePixels, " pixels)");
  }
  return Status::Ok();
}

}  // namespace image_detail

namespace {

enum class Detected { kPng, kJpeg, kExr, kUnknown };

Detected DetectFormat(const uint8_t* data, size_t size) {
  if (size >= 8 && data[0] == 0x89 && data[1] == 'P' && data[2] == 'N' && data[3] == 'G') return Detected::kPng;
  if (size >= 3 && data[0] == 0xFF && data[1] == 0xD8 && data[2] == 0xFF) return Detected::kJpeg;
  if (size >= 4 && data[0] == 0x76 && data[1] == 0x2f && data[2] == 0x31 && data[3] == 0x01) return Detected::kExr;
  return Detected::kUnknown;
}

StatusOr<ImageFormat> FormatFromExtension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  if (ext == ".png") return ImageFormat::kPng;
  if (ext == ".jpg" || ext == ".jpeg") return ImageFormat::kJpeg;
  if (ext == ".exr") return ImageFormat::kExr;
  return MakeError(StatusCode::kInvalidArgument, path, ": unknown image extension '", ext,
                   "' (.png, .jpg, .jpeg, .exr)");
}

// Images larger than any we could decode: refuse before reading them.
constexpr uint64_t kMaxImageFileBytes = uint64_t{4} << 30;

}  // namespace

bool ImageFormatSupported(ImageFormat format) {
  return format != ImageFormat::kExr || image_detail::ExrSupported();
}

StatusOr<Image> DecodeImage(const uint8_t* data, size_t size, const std::string& what) {
  if (data == nullptr && size != 0) return MakeError(StatusCode::kInvalidArgument, what, ": null image data");
  try {
    switch (DetectFormat(data, size)) {
      case Detected::kPng: return image_detail::DecodePng(data, size, what);
      case Detected::kJpeg: return image_detail::DecodeJpeg(data, size, what);
      case Detected::kExr: return image_detail::DecodeExr(data, size, what);
      case Detected::kUnknown: break;
    }
  } catch (const std::bad_alloc&) {
    return MakeError(StatusCode::kLimitExceeded, what, ": out of memory decoding the image");
  }
  return MakeError(StatusCode::kBadMagic, what, ": not a PNG, JPEG or EXR image (unknown signature)");
}

StatusOr<Image> ReadImage(const std::string& path) {
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, ReadFileBytes(path, kMaxImageFileBytes));
  return DecodeImage(bytes.data(), bytes.size(), path);
}

StatusOr<ImageInfo> ReadImageInfo(const std::string& path) {
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, ReadFileBytes(path, kMaxImageFileBytes));
  return ImageInfoFromBytes(bytes.data(), bytes.size(), path);
}

StatusOr<ImageInfo> ImageInfoFromBytes(const uint8_t* data, size_t size, const std::string& what) {
  switch (DetectFormat(data, size)) {
    case Detected::kPng: return image_detail::PngInfo(data, size, what);
    case Detected::kJpeg: return image_detail::JpegInfo(data, size, what);
    case Detected::kExr: return image_detail::ExrInfo(data, size, what);
    case Detected::kUnknown: break;
  }
  return MakeError(StatusCode::kBadMagic, what, ": not a PNG, JPEG or EXR image (unknown signature)");
}

StatusOr<std::vector<uint8_t>> EncodeImage(const Image& image, ImageFormat format, const ImageEncodeOptions& options) {
  if (image.pixels.size() !=
      size_t(std::max(image.width, 0)) * std::max(image.height, 0) * std::max(image.channels, 0)) {
    return MakeError(StatusCode::kInvalidArgument, "image of ", image.width, "x", image.height, "x", image.channels,
                     " has ", image.pixels.size(), " values");
  }
  try {
    switch (format) {
      case ImageFormat::kPng: return image_detail::EncodePng(image, options.png_bit_depth);
      case ImageFormat::kJpeg: return image_detail::EncodeJpeg(image, options.jpeg_quality);
      case ImageFormat::kExr: return image_detail::EncodeExr(image);
    }
  } catch (const std::bad_alloc&) {
    return MakeError(StatusCode::kLimitExceeded, "out of memory encoding an image");
  }
  return MakeError(StatusCode::kInvalidArgument, "unknown image format");
}

Status WriteImage(const std::string& path, const Image& image, const ImageEncodeOptions& options) {
  ATEX_ASSIGN_OR_RETURN(const ImageFormat format, FormatFromExtension(path));
  StatusOr<std::vector<uint8_t>> bytes = EncodeImage(image, format, options);
  if (!bytes.ok()) return bytes.status().WithContext(path);
  return WriteFileAtomic(path, *bytes);
}

}  // namespace atex
