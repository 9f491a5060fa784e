// Reads an .atex with the installed library and renders one orbit view at the middle of
// its time range; prints the version and the covered pixels. Fails when nothing is covered.
//   atex_consumer ASSET.atex
#include <cstdio>

#include "atex/container.h"
#include "atex/converters/convert.h"
#include "atex/deform.h"
#include "atex/fit.h"
#include "atex/render.h"
#include "atex/version.h"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: atex_consumer ASSET.atex\n");
    return 2;
  }
  auto asset = atex::ReadAssetFile(argv[1]);
  if (!asset.ok()) {
    std::fprintf(stderr, "%s\n", asset.status().ToString().c_str());
    return 1;
  }
  atex::Camera camera = atex::fit::OrbitProbes(*asset, 1, 64, 48).front().camera;
  camera.time = 0.5 * (asset->metadata.time_min + asset->metadata.time_max);
  atex::Gaussians deformed = asset->gaussians;
  if (asset->deformation) {
    const atex::Status s = atex::DeformForward(*asset->deformation, asset->gaussians, camera.time, &deformed, nullptr);
    if (!s.ok()) {
      std::fprintf(stderr, "%s\n", s.ToString().c_str());
      return 1;
    }
  }
  auto out = atex::RenderForward(camera, deformed, asset->textures ? &*asset->textures : nullptr,
                                 atex::RenderSettings{});
  if (!out.ok()) {
    std::fprintf(stderr, "%s\n", out.status().ToString().c_str());
    return 1;
  }
  int covered = 0;
  for (float a : out->alpha) covered += a > 0.5f;
  std::printf("atex %s (format %d.%d): %zu Gaussians, %dx%d view, %d covered pixels, converters know '%s'\n",
              atex::kVersion, atex::kFormatVersionMajor, atex::kFormatVersionMinor, asset->gaussians.size(),
              out->width, out->height, covered, std::string(atex::FileFormatName(atex::FileFormat::kSpz)).c_str());
  return covered > 0 ? 0 : 1;
}
