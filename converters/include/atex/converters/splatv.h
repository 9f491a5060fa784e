// splaTV (.splatv) export: our deformation baked into per-Gaussian closed-form
// motion that antimatter15/splaTV's viewer plays (the format of its hybrid.js).
//
// File layout (little-endian):
//   u32 magic 0x674b, u32 n = length of the JSON that follows,
//   JSON: an array of chunk descriptors, here one:
//     {"type": "splat", "size": S, "texwidth": 4096, "texheight": H, "cameras": [...],
//      "atex": {...}}   (the "atex" member is ours; the viewer ignores it)
//   the chunk's S = 4096 * H * 16 bytes: an RGBA32UI texture, 1024 Gaussians per row,
//   4 texels = 16 words = 64 bytes per Gaussian:
//     word 0..2  position xyz (f32)                      word 3  half2(rot.w, rot.x)
//     word 4     half2(rot.y, rot.z)                     word 5  half2(scale.x, scale.y)
//     word 6     half2(scale.z, 0)                       word 7  RGBA8 colour, alpha = opacity
//     word 8..12 half2 pairs of 9 motion coefficients: d1.xyz, d2.xyz, d3.xyz (+ 1 unused)
//     word 13,14 half2 pairs of omega (w, x, y, z)      word 15 half2(trbf_center, trbf_scale)
//   Quaternions are (w, x, y, z) like ours; scales are linear (exp of log-scale).
// At viewer time u in [0, 1] (our [time_min, time_max] mapped linearly), with
// dt = u - trbf_center:
//   position = xyz + d1*dt + d2*dt^2 + d3*dt^3
//   rotation = normalize(rot + omega*dt)
//   opacity  = alpha * exp(-(dt / trbf_scale)^2)  (the viewer drops splats below 0.02)
// Scale and colour are static in splaTV: the time average of our deformed log-scale and
// DC colour is stored; textures and view-dependent SH are not representable.
//
// The fit samples the deformation at `samples` uniform times; per Gaussian the temporal
// opacity is a weighted least-squares Gaussian in time, the position a least-squares cubic
// and the rotation a least-squares line, all around the fitted temporal centre. The report
// measures the error of the stored (half-precision) values at the sample times exactly as
// the viewer evaluates them.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "atex/converters/gltf.h"  // DeformFn, GltfProgress
#include "atex/model.h"
#include "atex/status.h"

namespace atex {

// A camera as splaTV's JSON lists it: OpenCV axes (x right, y down, z forward),
// `rotation` the camera-to-world matrix (row-major), `position` the camera centre.
struct SplatvCamera {
  int width = 1280, height = 720;
  double fx = 1000, fy = 1000;
  std::array<double, 3> position{0, 0, 0};
  std::array<double, 9> rotation{1, 0, 0, 0, 1, 0, 0, 0, 1};
  std::string name = "atex";
};

struct SplatvOptions {
  int samples = 32;                  // deformation samples over the time range (>= 4)
  DeformFn deform;                   // default: libatex's DeformForward
  std::vector<SplatvCamera> cameras; // empty: one camera that frames the scene from its front
  std::optional<UpAxis> up;          // for the default camera; default: the asset's up axis (UpAxisOf)
  // When > 0, renders this many times (evenly over the range) from cameras[0] with libatex's
  // reference renderer and reports the PSNR of the baked scene (SplatvFitReport::psnr_*).
  int psnr_times = 0;
  GltfProgress progress;
};

struct SplatvFitReport {
  size_t gaussians = 0;
  int samples = 0;
  double scene_extent = 0;            // diagonal of the AABB the relative errors divide by
  double position_rms = 0;            // world units, over Gaussians x samples
  double position_rms_relative = 0;   // position_rms / scene_extent
  double position_max_relative = 0;
  double rotation_rms_deg = 0;        // angle between fitted and true rotation
  double rotation_max_deg = 0;
  double opacity_rms = 0;             // |fitted - true| opacity in [0, 1]
  double opacity_max = 0;
  double log_scale_rms = 0;           // static scale vs our time-varying one (not representable)
  double motion_rms_relative = 0;     // how far the Gaussians move: RMS distance from their mean
                                      // position over time / scene_extent (the scale of the task)
  // With SplatvOptions::psnr_times > 0 (else 0): mean PSNR (dB) of the baked scene rendered by
  // libatex against the asset itself at the same times and camera:
  double psnr_full_db = 0;    // against the full asset (SH of every degree, textures): the whole cost
  double psnr_motion_db = 0;  // against the asset with DC colour and no textures: the motion fit's cost
  int psnr_frames = 0;
  nlohmann::json ToJson() const;
};

struct SplatvResult {
  std::vector<uint8_t> bytes;
  SplatvFitReport report;
};

// Coefficients beyond half precision are clamped to +-65504 (the report then shows the
// error). Errors: kInvalidArgument (invalid or empty asset, samples outside 4..100000),
// kCancelled, and the deformation's or renderer's own errors.
StatusOr<SplatvResult> EncodeSplatv(const Asset& asset, const SplatvOptions& options = {});
// Writes atomically; fills *report when not null.
Status WriteSplatvFile(const std::string& path, const Asset& asset, const SplatvOptions& options = {},
                       SplatvFitReport* report = nullptr);

// ---------------------------------------------------------------------------
// Reading, with the viewer's rules (for tests and tools). Hostile input is refused
// with kBadMagic / kTruncated / kCorrupt.
struct SplatvFile {
  nlohmann::json chunks;          // the descriptor array
  size_t splat_chunk = 0;         // index of the "splat" chunk
  int texwidth = 0, texheight = 0;
  size_t count = 0;               // Gaussians the viewer draws: floor(size / 64)
  std::vector<uint32_t> words;    // [count][16]
};
StatusOr<SplatvFile> DecodeSplatv(const uint8_t* data, size_t size);

// One Gaussian at viewer time u, evaluated as the viewer's vertex shader does.
struct SplatvSample {
  std::array<float, 3> position;
  std::array<float, 4> rotation;  // (w, x, y, z), normalised
  std::array<float, 3> scale;
  float opacity = 0;              // 0 where the viewer culls (temporal opacity < 0.02)
  std::array<uint8_t, 4> rgba;
};
SplatvSample EvaluateSplatv(const SplatvFile& file, size_t index, double u);

}  // namespace atex
