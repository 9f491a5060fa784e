// The texture pool of an asset as one OpenEXR image (a "texel atlas") plus a
// JSON sidecar that maps each Gaussian to its block, e.g. for inspection in an
// image viewer or editing in a paint program, and back.
//
// Atlas image: RGBA, 16-bit half float, ZIP compression, `width` texels wide.
// Texel (u, v) of Gaussian i (u along axis_u, v along axis_v; docs/conventions.md
// section 5) is pixel (x_i + u, y_i + v); the channels hold the raw texture
// parameters (before tanh). Blocks are packed in Gaussian order on shelves of
// their own height (1, 2 or 4 rows), so the atlas is dense; pixels that belong
// to no Gaussian are 0.
//
// Sidecar `<atlas>.exr.json`:
//   {"format": "atex-texture-atlas", "version": 1, "atlas_width": W, "atlas_height": H,
//    "pixel_type": "half", "count": N,
//    "x": [N], "y": [N], "h": [N], "w": [N], "axis_u": [N], "axis_v": [N]}
// The EXR header also carries "atexAtlasVersion" (int) and "atexAtlasCount" (int).
//
// Precision: float32 texels are rounded to the nearest half on export (relative
// error <= 2^-11, values beyond +-65504 are refused); values that are exactly
// representable as half (including every texel of an atlas this module wrote)
// come back bit for bit.
//
// Import treats both files as hostile: sizes are checked against limits and each
// other before allocating, every block must lie inside the atlas with dims in
// {1, 2, 4} and two distinct axes in {0, 1, 2}; NaN/Inf texels are refused.
// Needs OpenEXR (ATEX_HAVE_OPENEXR); without it every function returns kUnsupportedCodec.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "atex/model.h"
#include "atex/status.h"

namespace atex {

struct ExrAtlasOptions {
  int width = 0;  // atlas width in texels (>= 4); 0 picks one that makes the atlas roughly square
};

struct ExrAtlasReadOptions {
  uint64_t max_pixels = uint64_t{1} << 27;  // refuse larger atlases (1 GiB of half RGBA)
  uint64_t max_gaussians = uint64_t{1} << 28;
};

// An encoded atlas: the EXR file and its sidecar text.
struct EncodedExrAtlas {
  std::vector<uint8_t> exr;
  std::string sidecar_json;
  int width = 0, height = 0;
};

// The sidecar path that goes with an atlas path ("<atlas>.json").
std::string ExrAtlasSidecarPath(const std::string& exr_path);

// Packs and encodes `pool` (kInvalidArgument for an inconsistent pool,
// kOutOfRange for NaN/Inf or a texel beyond the half range, naming the Gaussian).
StatusOr<EncodedExrAtlas> EncodeExrAtlas(const TexturePool& pool, const ExrAtlasOptions& options = {});

// Decodes an atlas and its sidecar into a texture pool (offsets rebuilt).
StatusOr<TexturePool> DecodeExrAtlas(const uint8_t* exr, size_t exr_size, std::string_view sidecar_json,
                                     const ExrAtlasReadOptions& options = {});

// Writes `exr_path` and ExrAtlasSidecarPath(exr_path), each atomically.
Status WriteExrAtlas(const std::string& exr_path, const TexturePool& pool, const ExrAtlasOptions& options = {});

// Reads `exr_path` and its sidecar.
StatusOr<TexturePool> ReadExrAtlas(const std::string& exr_path, const ExrAtlasReadOptions& options = {});

}  // namespace atex
