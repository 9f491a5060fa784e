// libFuzzer target: the nerfstudio / instant-ngp transforms.json parser. Beyond "no crash":
// every accepted frame has a finite camera-to-world with the last row (0, 0, 0, 1), sizes in
// range, a positive focal length or field of view, and a finite time when it has one.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "atex/dataset_formats.h"
#include "atex/image.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  auto file = atex::ParseTransformsJson(std::string_view(reinterpret_cast<const char*>(data), size), "fuzz.json");
  if (!file.ok()) return 0;
  for (const atex::TransformsFrame& f : file->frames) {
    for (double v : f.camera_to_world) {
      if (!std::isfinite(v)) __builtin_trap();
    }
    const auto& m = f.camera_to_world;
    if (m[12] != 0 || m[13] != 0 || m[14] != 0 || m[15] != 1) __builtin_trap();
    if (f.width < 0 || f.width > atex::kMaxImageSide || f.height < 0 || f.height > atex::kMaxImageSide) __builtin_trap();
    if (!(f.fx > 0 || f.angle_x > 0)) __builtin_trap();
    if (f.time && !std::isfinite(*f.time)) __builtin_trap();
    if (f.file_path.empty()) __builtin_trap();
  }
  return 0;
}
