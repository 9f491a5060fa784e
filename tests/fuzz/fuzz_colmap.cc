// libFuzzer target: the COLMAP sparse-model readers (cameras.bin, images.bin and their
// text forms) on the same bytes. Beyond "no crash": every accepted camera has its model's
// parameter count, finite parameters and a size in range; every accepted image has a
// non-empty name and a world-to-camera that is finite wherever ColmapWorldToCamera accepts it.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "atex/dataset_formats.h"
#include "atex/image.h"

namespace {

void CheckCameras(const std::vector<atex::ColmapCamera>& cameras) {
  for (const atex::ColmapCamera& c : cameras) {
    std::string name;
    int count = 0;
    if (!atex::ColmapModelInfo(c.model_id, &name, &count) || name != c.model || c.params.size() != size_t(count)) {
      __builtin_trap();
    }
    if (c.width < 1 || c.height < 1 || c.width > uint64_t(atex::kMaxImageSide) || c.height > uint64_t(atex::kMaxImageSide)) {
      __builtin_trap();
    }
    for (double p : c.params) {
      if (!std::isfinite(p)) __builtin_trap();
    }
    auto k = atex::ColmapPinholeIntrinsics(c, "fuzz");
    if (k.ok() && !((*k)[0] > 0 && (*k)[1] > 0)) __builtin_trap();
  }
}

void CheckImages(const std::vector<atex::ColmapImage>& images) {
  for (const atex::ColmapImage& image : images) {
    if (image.name.empty()) __builtin_trap();
    auto m = atex::ColmapWorldToCamera(image, "fuzz");
    if (!m.ok()) continue;
    for (double v : *m) {
      if (!std::isfinite(v)) __builtin_trap();
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  if (auto c = atex::ParseColmapCamerasBinary(data, size, "cameras.bin"); c.ok()) CheckCameras(*c);
  if (auto c = atex::ParseColmapCamerasText(text, "cameras.txt"); c.ok()) CheckCameras(*c);
  if (auto i = atex::ParseColmapImagesBinary(data, size, "images.bin"); i.ok()) CheckImages(*i);
  if (auto i = atex::ParseColmapImagesText(text, "images.txt"); i.ok()) CheckImages(*i);
  return 0;
}
