// libFuzzer target: DecodeImage (PNG through libpng, JPEG through libjpeg, EXR
// through OpenEXR, chosen by magic bytes). Properties checked beyond "no
// crash": an accepted image has a valid shape within the decoder limits, and
// PNG/JPEG samples lie in [0, 1].
#include <cstddef>
#include <cstdint>

#include "atex/image.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  auto image = atex::DecodeImage(data, size, "fuzz");
  if (!image.ok()) return 0;
  const bool exr = size >= 4 && data[0] == 0x76 && data[1] == 0x2f;
  if (image->width <= 0 || image->height <= 0 || image->width > atex::kMaxImageSide ||
      image->height > atex::kMaxImageSide) {
    __builtin_trap();
  }
  if (image->channels != 1 && image->channels != 3 && image->channels != 4) __builtin_trap();
  if (image->pixels.size() != size_t(image->width) * image->height * image->channels) __builtin_trap();
  if (!exr) {
    for (float v : image->pixels) {
      if (!(v >= 0.0f && v <= 1.0f)) __builtin_trap();
    }
  }
  return 0;
}
