// `atex view`: one self-contained HTML file that plays a 4D asset in a browser (WebGL2),
// with orbit controls, a time slider and a play button; no server, no network (file://).
//
// The browser cannot run the deformation field cheaply, so the writer bakes it: the
// Gaussians are deformed with libatex's CPU deformation (DeformForward) at K keyframe
// times spread evenly over [time_min, time_max], quantised, and embedded as base64 in a
// JSON <script> element; the page interpolates linearly between the two keyframes around
// the shown time (positions, log-scales, colours and opacities linearly; rotations by a
// normalised linear blend of sign-aligned quaternions). A parameter whose deformation head
// is off is stored once (static). The renderer is our WebGL2 EWA splatter
// (converters/src/view/view_template.html, compiled into the library): the projection,
// low-pass filter, alpha cut and compositing of docs/conventions.md §4-5.
//
// Payload (the JSON element id="atex-view-data"; arrays frame-major [F][N][c], F = 1 or K,
// each base64 of its bytes, compressed unless ViewOptions::compress is off):
//   positions   u16 x3  unorm in the box position_lo .. position_hi (all keyframes)
//   rotations   i8  x4  snorm/127 (w, x, y, z), unit, each keyframe's sign aligned to the one before
//   log_scales  f16 x3  natural log of the standard deviations
//   colours     u8  x4  rgb: colour_range[0] + v/255 * (colour_range[1] - colour_range[0]);
//                       a: v/255 * opacity_scale (the opacity times the texture's factor)
// The JSON: {"format": "atex-view", "version": 1, title, count, times, up ("+z"), up_vector,
// background, near (the cull plane, 0.2), camera {width, height, fx, fy, cx, cy,
// world_to_camera[16]}, target (orbit centre), position_lo, position_hi, colour_range,
// opacity_scale, approximations, source, arrays: {positions | rotations | log_scales |
// colours: {type, components, frames, encoding ("raw" or view_codec.h's
// "delta-planes-deflate"), data (base64)}}}.
// Approximations (listed in the payload's "approximations" and the report's warnings):
//   - colour is the DC term only (view-dependent SH of degree >= 1 is dropped);
//   - a texture becomes its average: colour + 0.1 * mean tanh(texel rgb), opacity *
//     mean exp(0.1 * tanh(texel a)) (the texture terms of conventions §5, averaged over the
//     plane instead of sampled where the ray crosses it);
//   - motion between keyframes is interpolated, not evaluated.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "atex/camera.h"
#include "atex/converters/gltf.h"  // DeformFn, GltfProgress, UpAxis
#include "atex/model.h"
#include "atex/status.h"

namespace atex {

// WebGL2's guaranteed minimums bound the page: 256 layers of a 2D-array texture (one per
// keyframe) and 2048 x 2048 texels per layer (one per Gaussian).
inline constexpr int kViewMaxFrames = 256;
inline constexpr size_t kViewMaxSplats = size_t{2048} * 2048;
inline constexpr uint64_t kViewDefaultMaxBytes = uint64_t{64} << 20;  // the HTML file

struct ViewOptions {
  // Keyframes. 0: the default rule (DefaultViewFrames); always capped so that the HTML fits
  // max_bytes (the report's notes say so). Static assets always get 1.
  int frames = 0;
  // 0: every Gaussian. Else keep the `max_splats` with the largest opacity x volume
  // (sigmoid(logit) x exp(sum of log-scales), canonical), in their original order.
  size_t max_splats = 0;
  uint64_t max_bytes = kViewDefaultMaxBytes;  // cap on the HTML's size (kBudgetTooSmall below 2 keyframes)
  // The camera the page opens with (OpenCV axes; its width x height is the reference size
  // whose vertical field of view the page keeps). Default: one that frames the Gaussians
  // from slightly above, upright (DefaultViewCamera).
  std::optional<Camera> camera;
  std::optional<UpAxis> up;   // default: the asset's up axis (UpAxisOf); unknown: -y (3DGS)
  // Compress each array (delta over keyframes, byte planes, deflate: view_codec.h); the page
  // inflates it with the browser's DecompressionStream (Chrome 80, Firefox 113, Safari 16.4).
  // false: plain base64 for older browsers.
  bool compress = true;
  std::string title = "atex view";
  DeformFn deform;            // default: libatex's DeformForward
  GltfProgress progress;      // fraction of the keyframes baked; false cancels (kCancelled)
};

struct ViewReport {
  size_t gaussians = 0;           // in the asset
  size_t kept = 0;                // in the page
  std::vector<double> times;      // keyframe scene times
  int frames_requested = 0;       // before the size cap (0 for static assets)
  std::vector<std::string> dynamic;  // the arrays stored per keyframe ("positions", ...)
  uint64_t payload_bytes = 0;     // binary bytes of the arrays before compression and base64
  uint64_t stored_bytes = 0;      // ... after compression (= payload_bytes without), before base64
  uint64_t html_bytes = 0;
  std::string up;                 // "+z", ...
  Camera camera;                  // the opening camera
  std::array<double, 3> target{0, 0, 0};  // the orbit centre
  std::vector<std::string> warnings;  // approximations that change the picture
  std::vector<std::string> notes;
  nlohmann::json ToJson() const;
};

// The baked keyframes as the page reads them (also what DecodeViewHtml gives back).
struct ViewPayload {
  size_t count = 0;                 // N
  std::vector<double> times;        // K keyframe times (1 for a static asset)
  std::array<float, 3> position_lo{0, 0, 0}, position_hi{0, 0, 0};
  std::array<float, 2> colour_range{0, 1};
  float opacity_scale = 1;
  int position_frames = 1, rotation_frames = 1, scale_frames = 1, colour_frames = 1;  // 1 or K
  std::vector<uint16_t> positions;  // [position_frames][N][3]
  std::vector<int8_t> rotations;    // [rotation_frames][N][4]
  std::vector<uint16_t> log_scales; // [scale_frames][N][3] binary16
  std::vector<uint8_t> colours;     // [colour_frames][N][4]
  nlohmann::json header;            // everything else of the JSON (camera, up, background, ...)

  // Dequantised values of Gaussian i in keyframe k (k is clamped to the stored frames).
  std::array<float, 3> Position(size_t k, size_t i) const;
  std::array<float, 4> Rotation(size_t k, size_t i) const;  // (w, x, y, z), not renormalised
  std::array<float, 3> LogScale(size_t k, size_t i) const;
  std::array<float, 4> ColourOpacity(size_t k, size_t i) const;  // rgb, opacity
};

// Keyframes of the default rule: the HexPlane time axis is sampled linearly between its
// base_resolution[3] grid nodes, so the features (though not the MLP's output) are
// piecewise linear in time; 2 * (nodes - 1) + 1 frames sample every node and every
// midpoint when the asset maps [time_min, time_max] onto the grid (native assets).
// Clamped to 2 .. 120; 1 for a static asset.
int DefaultViewFrames(const Asset& asset);

// A camera of `width` x `height` pixels, 50 degrees vertical field of view, looking at the
// centre of the Gaussians' robust box (2nd..98th percentile per axis of the Gaussians with
// opacity >= 0.2) from 20 degrees above the horizon, `up` up, far enough back that the
// box's bounding sphere fits. *target (when not null) gets the box centre.
Camera DefaultViewCamera(const Gaussians& gaussians, UpAxis up, int width, int height,
                         std::array<double, 3>* target = nullptr);

// Bakes and builds the page. Errors: kInvalidArgument (invalid or empty asset, frames
// outside 0..kViewMaxFrames, a camera without positive size and focal lengths),
// kLimitExceeded (more than kViewMaxSplats Gaussians kept: set max_splats),
// kBudgetTooSmall (max_bytes below the template plus two keyframes, or one for a static
// asset; the keyframes are chosen by their uncompressed size, so a compressed page is
// usually well under max_bytes), kCancelled, and the deformation's own errors.
StatusOr<std::string> EncodeViewHtml(const Asset& asset, const ViewOptions& options = {},
                                     ViewReport* report = nullptr);
// EncodeViewHtml, written atomically.
Status WriteViewHtml(const std::string& path, const Asset& asset, const ViewOptions& options = {},
                     ViewReport* report = nullptr);

// Reads the payload back out of a page EncodeViewHtml wrote (kBadMagic: no payload element;
// kCorrupt: bad JSON, base64, array sizes or values).
StatusOr<ViewPayload> DecodeViewHtml(std::string_view html);

// The page template compiled into the library (for tests).
std::string_view ViewTemplate();

}  // namespace atex
