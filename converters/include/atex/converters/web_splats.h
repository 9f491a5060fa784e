// Readers of the static splat formats of web viewers, into our Gaussians
// (atex/model.h). All of them store the 3DGS PLY world (x right, y down, z
// forward of the training cameras), so `atex convert` reads them as
// axes "opencv" like a PLY file.
//
//   .splat   antimatter15/splat: 32 bytes per Gaussian, no header: position
//            f32 x 3, scale f32 x 3 (linear, exp of the log-scale), RGBA u8
//            (colour = 0.5 + SH_C0 f_dc, alpha = sigmoid(logit), both x 255),
//            rotation u8 x 4 (w, x, y, z; q x 128 + 128). SH degree 0.
//   .ksplat  mkkellogg/GaussianSplats3D SplatBuffer v0.1: a 4096-byte header
//            (version, section counts, Gaussian counts, compression level 0..2,
//            SH range of level 2), `max_sections` 1024-byte section headers,
//            then per section its bucket lengths, bucket centres and rows.
//            Level 0: f32 centre, scale, rotation (w, x, y, z), SH; levels 1, 2:
//            u16 centre offsets from the bucket centre, f16 scale and rotation,
//            SH f16 (1) or u8 over [sh_min, sh_max] (2). RGBA u8 colour as in
//            .splat. SH degree up to 2 (per channel: band 1, then band 2).
//   SOG      PlayCanvas SOG version 2: meta.json plus lossless WebP images
//            (means_l/means_u 16-bit log-transformed positions, quats smallest
//            three, scales and sh0 through 256-entry codebooks, opacity u8,
//            shN palette + labels), either as a folder (meta.json) or bundled
//            in a .sog zip. Needs libwebp (ATEX_HAVE_WEBP); SogAvailable()
//            says whether this build has it.
// PlayCanvas's compressed PLY is read by ReadPlyGaussians (atex/converters/ply.h).
//
// Input is hostile: sizes and counts are checked against the bytes present
// (and image dimensions against the Gaussian count) before anything is
// allocated; errors are numbered and name the file, section, Gaussian or byte.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "atex/model.h"
#include "atex/status.h"

namespace atex {

struct WebSplatLimits {
  uint64_t max_gaussians = uint64_t{1} << 28;
};

// .splat: kCorrupt when the size is not a multiple of 32 or a scale is not
// positive and finite, kOutOfRange for NaN/Inf positions (naming the Gaussian).
// A zero rotation (all four bytes 128) reads as the identity.
StatusOr<Gaussians> ReadSplatGaussiansFromMemory(const uint8_t* data, size_t size, const WebSplatLimits& limits = {});
StatusOr<Gaussians> ReadSplatGaussians(const std::string& path, const WebSplatLimits& limits = {});

// .ksplat: kBadMagic (version other than 0.x), kUnsupported (compression level
// above 2, SH degree above 2), kCorrupt / kTruncated (counts, sections and
// buckets that disagree with each other or with the bytes present).
StatusOr<Gaussians> ReadKsplatGaussiansFromMemory(const uint8_t* data, size_t size, const WebSplatLimits& limits = {});
StatusOr<Gaussians> ReadKsplatGaussians(const std::string& path, const WebSplatLimits& limits = {});

// SOG: `path` is a .sog bundle (zip) or a meta.json whose images lie beside it.
// kUnsupported without libwebp or for a meta.json without "version": 2.
bool SogAvailable();
StatusOr<Gaussians> ReadSogGaussians(const std::string& path, const WebSplatLimits& limits = {});
// A .sog bundle already in memory.
StatusOr<Gaussians> ReadSogBundleFromMemory(const uint8_t* data, size_t size, const WebSplatLimits& limits = {});

}  // namespace atex
