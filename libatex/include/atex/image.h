// Float images and their files (PNG, JPEG through Debian's libpng/libjpeg;
// EXR through OpenEXR where built in).
#pragma once

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
};

// Reads PNG (8/16-bit, grey/RGB/RGBA, palette) or JPEG by content, EXR by extension.
StatusOr<Image> ReadImage(const std::string& path);
// Decodes PNG or JPEG bytes already in memory (e.g. from a zip member).
StatusOr<Image> DecodeImage(const uint8_t* data, size_t size, const std::string& what);
// Writes by extension: .png (8-bit), .jpg/.jpeg (quality 95), .exr (half float).
// Written to a temporary file in the same folder and renamed.
Status WriteImage(const std::string& path, const Image& image);

}  // namespace atex
