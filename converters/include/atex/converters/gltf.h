// glTF 2.0 export and import of AdaTex4D assets.
//
// What is written (format_spec/extensions/README.md has the whole picture):
//   * One mesh with one POINTS primitive carrying the Khronos KHR_gaussian_splatting
//     attributes: POSITION (float, with min/max), KHR_gaussian_splatting:ROTATION (unit
//     quaternion x y z w), :SCALE (linear, exp of our log-scale), :OPACITY (sigmoid of our
//     logit), :SH_DEGREE_l_COEF_n (raw SH coefficients, DC included; colour = SH + 0.5),
//     plus COLOR_0 (RGBA8: the DC colour decoded from sRGB to linear, and the opacity) for
//     point-cloud fallback.
//     kernel "ellipse", colorSpace "srgb_rec709_display". Any player that knows the
//     Khronos extension shows the (canonical, or --time baked) static scene.
//   * Our two extensions nested in the KHR_gaussian_splatting object, listed in
//     extensionsUsed and never in extensionsRequired:
//       ATEX_gaussian_textures     the packed per-Gaussian texture planes
//       ATEX_gaussian_deformation  the raw training parameters and the HexPlane + MLP field
//   * The asset metadata as JSON in the root `extras.atex`.
//   * The world is converted to glTF's +Y up by the rotation of the single node that holds
//     the mesh (the data itself is untouched, so import is bit-exact). The rotation
//     follows the asset's world up axis (UpAxisOf: metadata.up, or for older files the
//     rule of metadata.axes) unless the caller overrides it.
//   * Optional EXT_meshopt_compression (when the build has meshoptimizer): every
//     bufferView is compressed; rotations become normalized int16 with the QUATERNION
//     filter, other floats use the EXPONENTIAL filter (lossy) or none (lossless).
//     The uncompressed data is not stored: the fallback buffer has no URI, so
//     EXT_meshopt_compression is listed in extensionsRequired (as its spec demands).
//   * Optional KHR_mesh_quantization (GltfExportOptions::quantize): normalized integer base
//     attributes, dequantised by the node's scale and translation; alone or with meshopt.
//
// Import (needs tinygltf, ATEX_HAVE_TINYGLTF) reads our files back without loss in
// float mode (positions, raw rotations, log-scales, logits, SH, textures, field and
// metadata bit for bit) and reads other people's KHR_gaussian_splatting files (base
// attributes only; node transforms baked into the data). In our own files the node's rotation
// is the upright turn and is not applied; its uniform scale and translation (a quantised file's
// dequantisation) are. Input is hostile: every index,
// offset, stride and count is checked against the bytes present before use.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "atex/converters/texture_bake.h"
#include "atex/model.h"
#include "atex/status.h"

namespace atex {

// Progress of a long operation: fraction in [0, 1]. Return false to cancel (kCancelled).
using GltfProgress = std::function<bool(double fraction)>;

// Which world direction is "up" in the asset, for the conversion to glTF's +Y up.
enum class UpAxis : uint8_t { kPosY, kNegY, kPosZ, kNegZ, kPosX, kNegX };

// Up axis implied by metadata.axes alone (files without metadata.up): "opencv" (the
// datasets' camera-style world, y down) -> kNegY; "blender" / "z_up" -> kPosZ; "gltf" /
// "opengl" / "y_up" -> kPosY. Unknown names give kInvalidArgument.
StatusOr<UpAxis> GltfUpAxisFor(const std::string& axes);
// The asset's world up axis: metadata.up when recorded, else GltfUpAxisFor(axes)
// (atex/world_up.h). kInvalidArgument when neither says.
StatusOr<UpAxis> UpAxisOf(const Metadata& metadata);
// Parses "+x", "-x", "+y", "-y", "+z", "-z" (metadata.up, command-line override).
StatusOr<UpAxis> ParseUpAxis(const std::string& text);
// The name ParseUpAxis reads ("+y", ...).
std::string UpAxisName(UpAxis up);
// The unit quaternion (x, y, z, w) that rotates an asset with this up axis to +Y up:
// identity for kPosY, 180 degrees about x for kNegY, -90 / +90 degrees about x for
// kPosZ / kNegZ, +90 / -90 degrees about z for kPosX / kNegX. Right-handedness is
// kept (these are proper rotations).
std::array<double, 4> GltfRootRotation(UpAxis up);
// The same rotation as a row-major 3x3 matrix (entries exactly 0, 1 or -1).
std::array<double, 9> UpRotationMatrix(UpAxis up);

// Deforms the canonical Gaussians to `time` (the scene's time units). The command line
// passes libatex's deformation forward pass; tests pass analytic motion.
using DeformFn = std::function<Status(const Asset& asset, double time, Gaussians* deformed)>;

struct GltfExportOptions {
  // Bake the deformation at this time into the base attributes (needs `deform` and an
  // asset with a deformation field). The deformation extension is then omitted.
  std::optional<double> time;
  DeformFn deform;

  bool textures = true;        // write ATEX_gaussian_textures when the asset has textures
  bool deformation = true;     // write the field of ATEX_gaussian_deformation when present
  bool raw_parameters = true;  // write ATEX_gaussian_deformation's raw attributes (bit-exact import)
  bool color_fallback = true;  // write COLOR_0
  std::optional<UpAxis> up;    // override the asset's up axis (UpAxisOf)

  // Bake the textures into plain Gaussians (BakeTextures, texture_bake.h) so that a player that
  // knows only KHR_gaussian_splatting shows their detail: the base attributes hold the baked
  // Gaussians (more of them), ATEX_gaussian_textures is not written, and the raw parameters
  // describe the baked Gaussians. Without `time` the bake uses the canonical Gaussians, and a
  // written deformation field moves each baked Gaussian by its own centre (an approximation of
  // the textured parent's motion). No effect on an asset without textures.
  bool bake_textures = false;
  TextureBakeOptions bake;
  TextureBakeReport* bake_report = nullptr;  // filled when baking, if set

  // KHR_gaussian_splatting_compression_spz_2: the base attributes as one SPZ stream (~20 bytes per
  // Gaussian at SH degree 3; lossy: 24-bit positions, 8-bit scales, rotations, opacity and colour,
  // 4-5-bit SH) instead of float accessors. The extension is then required (no fallback data),
  // the raw parameters are not written (import gives the SPZ-rounded values), and COLOR_0 is
  // omitted. Not with `meshopt` (kInvalidArgument).
  bool spz = false;

  // KHR_mesh_quantization: the base attributes as normalized integers where KHR_gaussian_splatting
  // allows them (lossy; gltf_quantize.h has the layout and error bounds): POSITION int16 in the
  // node's frame (the node's uniform scale and translation map [-1, 1]^3 onto the scene's bounds),
  // ROTATION int8 (int16 with the meshopt QUATERNION filter), SCALE uint16 in the same node units,
  // OPACITY uint16; SH stays float (the extension allows no other type). The extension is then
  // required, the raw parameters are not written (import gives the quantised values). Combines
  // with `meshopt`; not with `spz` (kInvalidArgument).
  bool quantize = false;

  // EXT_meshopt_compression (kUnsupported when the build lacks meshoptimizer).
  bool meshopt = false;
  // Mantissa bits of the EXPONENTIAL filter for positions, scales, opacities, SH and the
  // extension payloads (1..23); 0 keeps those bits exact (filter NONE).
  int meshopt_float_bits = 0;
  int meshopt_rotation_bits = 16;  // QUATERNION filter bits (4..16)

  GltfProgress progress;
};

// A text glTF and the one binary buffer it references (by `bin_uri`).
struct GltfTextFiles {
  std::string json;
  std::vector<uint8_t> bin;
};

// Binary glTF (.glb) bytes. Errors: kInvalidArgument (inconsistent or empty asset, time
// without deformation or deform function), kOutOfRange (NaN/Inf, naming array and
// element), kUnsupported (meshopt without meshoptimizer), kCancelled.
StatusOr<std::vector<uint8_t>> EncodeGlb(const Asset& asset, const GltfExportOptions& options = {});
// Text glTF + buffer; the JSON names the buffer `bin_uri` (a relative file name).
StatusOr<GltfTextFiles> EncodeGltfText(const Asset& asset, const std::string& bin_uri,
                                       const GltfExportOptions& options = {});
// Writes `path` by extension: ".glb", or ".gltf" plus "<stem>.bin" beside it. Both
// files are written atomically (the .bin first).
Status WriteGltfFile(const std::string& path, const Asset& asset, const GltfExportOptions& options = {});

struct GltfImportOptions {
  uint64_t max_decoded_bytes = uint64_t{16} << 30;  // refuse files that expand beyond this
  uint64_t max_gaussians = uint64_t{1} << 28;
  GltfProgress progress;
};

// Reads .glb or .gltf (external buffers resolved next to the file, never outside its
// folder). Errors: kNotFound/kIoError (files), kBadMagic (neither GLB nor JSON),
// kTruncated, kCorrupt (bad indices, offsets, strides, counts; the message names the
// JSON path, e.g. "accessors[3]"), kOutOfRange (NaN/Inf or values outside their range),
// kLimitExceeded, kUnsupported (no tinygltf in this build, sparse accessors, no
// KHR_gaussian_splatting primitive, non-uniform node scale).
StatusOr<Asset> ReadGltfFile(const std::string& path, const GltfImportOptions& options = {});
// From memory. A .gltf that references external files cannot be read this way
// (kUnsupported); data: URIs and GLB's binary chunk can.
StatusOr<Asset> DecodeGltf(const uint8_t* data, size_t size, const GltfImportOptions& options = {});

}  // namespace atex
