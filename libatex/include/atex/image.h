// Float images and their files (PNG, JPEG through Debian's libpng/libjpeg;
// EXR through OpenEXR where built in).
//
// Decoders treat their input as hostile: dimensions are checked against
// kMaxImageSide / kMaxImagePixels and against what the compressed bytes
// present can possibly hold before any pixel buffer is allocated; codec errors
// (libpng/libjpeg longjmp, OpenEXR exceptions) come back as Status values whose
// message names the file (or `what`). Nothing is printed.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "atex/status.h"

namespace atex {

struct Image {
  int width = 0;
  int height = 0;
  int channels = 0;           // 1, 3 or 4
  std::vector<float> pixels;  // [height][width][channels], display-referred values in [0, 1]

  Image() = default;
  Image(int w, int h, int c, float fill = 0.0f) : width(w), height(h), channels(c), pixels(size_t(w) * h * c, fill) {}
  float& at(int x, int y, int c) { return pixels[(size_t(y) * width + x) * channels + c]; }
  float at(int x, int y, int c) const { return pixels[(size_t(y) * width + x) * channels + c]; }
  bool empty() const { return pixels.empty(); }
  size_t bytes() const { return pixels.size() * sizeof(float); }
};

// Decoder safety limits: larger images are refused with kLimitExceeded.
inline constexpr int kMaxImageSide = 1 << 15;                   // 32768 pixels per side
inline constexpr uint64_t kMaxImagePixels = uint64_t{1} << 27;  // 134 M pixels

enum class ImageFormat { kPng, kJpeg, kExr };

// False only for EXR in a build without OpenEXR (then EXR calls return kUnsupportedCodec).
bool ImageFormatSupported(ImageFormat format);

struct ImageInfo {
  int width = 0;
  int height = 0;
  int channels = 0;   // as ReadImage would return them: 1, 3 or 4
  int bit_depth = 0;  // bits per stored sample (8 or 16 for PNG/JPEG; 16/32 for EXR)
  ImageFormat format = ImageFormat::kPng;
};

// Reads PNG (1/2/4/8/16-bit grey, grey+alpha, RGB, RGBA, palette with or
// without transparency), JPEG (grey or colour; CMYK refused) or EXR (R,G,B[,A]
// or Y[,A] channels, any pixel type), chosen by content (magic bytes).
// Channels: grey -> 1, colour -> 3, anything with alpha -> 4 (grey+alpha is
// expanded to RGBA). 8/16-bit samples map to [0, 1]; EXR values are returned
// as stored (linear, not clamped).
StatusOr<Image> ReadImage(const std::string& path);
// Decodes PNG, JPEG or EXR bytes already in memory (e.g. from a zip member);
// `what` names them in errors.
StatusOr<Image> DecodeImage(const uint8_t* data, size_t size, const std::string& what);
// Dimensions and channels from the header only (no pixel decoding).
StatusOr<ImageInfo> ReadImageInfo(const std::string& path);
// The same for bytes in memory. For EXR the header is checked by our own scan before
// OpenEXR sees it (forged sizes are refused before OpenEXR allocates buffers from them),
// so this is the safe first step for any reader that hands EXR bytes to OpenEXR.
StatusOr<ImageInfo> ImageInfoFromBytes(const uint8_t* data, size_t size, const std::string& what);

// Encodes to a format: PNG 8-bit (or 16-bit with png_bit_depth = 16), JPEG at
// `jpeg_quality` (alpha dropped), EXR half float with ZIP compression. Values
// are clamped to [0, 1] for PNG/JPEG (NaN -> 0); EXR keeps them.
struct ImageEncodeOptions {
  int png_bit_depth = 8;  // 8 or 16
  int jpeg_quality = 95;  // 1..100
};
StatusOr<std::vector<uint8_t>> EncodeImage(const Image& image, ImageFormat format,
                                           const ImageEncodeOptions& options = {});
// Writes by extension: .png (8-bit), .jpg/.jpeg (quality 95), .exr (half float).
// Written to a temporary file in the same folder and renamed.
Status WriteImage(const std::string& path, const Image& image, const ImageEncodeOptions& options = {});

// Downscales by an integer factor with a box filter: output pixel (i, j) is the
// mean of input pixels [f·i, f·i + f) × [f·j, f·j + f). The output is
// floor(W/f) × floor(H/f); the remainder columns/rows on the right and bottom
// are cropped (so pixel centres keep the x' = x/f relation of the intrinsics:
// fx' = fx/f, cx' = cx/f). kInvalidArgument if f < 1 or the result is empty.
StatusOr<Image> DownscaleImage(const Image& image, int factor);

// A 3-channel RGB copy: grey is replicated; alpha (4 channels) is composited
// over `background`: rgb·a + background·(1 − a).
Image ToRgb(const Image& image, const std::array<float, 3>& background = {0, 0, 0});

}  // namespace atex
