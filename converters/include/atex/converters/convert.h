// `atex convert IN OUT`: conversion between the file formats libatex reads and
// writes, chosen by extension or named explicitly.
//
//   format  read                                   write
//   .ply    INRIA 3DGS PLY (ply.h)                 Gaussians (canonical or at --time)
//   .spz    SPZ v1-v4 (spz.h)                      SPZ v3/v4 (--spz-version)
//   .atex   our container (atex/container.h)      the whole asset
//   .exr    texel atlas + sidecar (exr_atlas.h):   the texture pool
//           replaces the texture pool of the
//           --base asset
//   .drc    -                                      Draco point cloud (drc.h) of the
//                                                  centres (canonical or at --time)
//   .splat  antimatter15 .splat (web_splats.h)     -
//   .ksplat GaussianSplats3D .ksplat, levels 0-2   -
//   .sog    PlayCanvas SOG v2: a .sog bundle, a    -
//           meta.json, or a folder holding one
//           (needs libwebp)
//   (PlayCanvas .compressed.ply is read as .ply)
//   4dgs    a 4DGaussians output folder            -
//           (fourdgs.h): the run folder (the
//           highest point_cloud/iteration_N,
//           or --iteration) or one iteration
//           folder; any input that is a folder
//
// Per-frame export (`--frames START:END:STEP OUTDIR`): the Gaussians deformed
// by the whole field (every enabled head, opacity and SH included) at each
// time START, START+STEP, ... up to END (inclusive within a millionth of a
// step), one file per time (OUTDIR/frame_0000.ply, ...; .ply or .spz, chosen
// by `to`, .ply by default) and OUTDIR/frames.json listing each file's time.
// Each file is written atomically; frames.json is written last, so a folder
// whose manifest is missing holds an interrupted export. A static asset
// writes the canonical Gaussians at every time (with a note).
//
// Up axis: .ply and .spz outputs (SPZ with the default SpzAxes::kOpenCv) turn
// the asset's world so that its up axis (metadata.up, atex/world_up.h) is the
// file's up: -y of the 3DGS PLY convention, +y of SPZ's RUB axes (positions,
// quaternions and SH coefficients rotate; a note in the report says so). Assets
// whose up axis is -y or unknown are written unrotated. The readers of .ply,
// .spz, .splat, .ksplat and SOG give axes "opencv" (up -y, the 3DGS PLY world).
//
// Conversions to a format that cannot hold part of the asset (textures or the
// deformation field into .ply/.spz/.drc) drop that part and say so in the
// report (`dropped`; losing the textures, which changes the rendered image,
// is also a `warnings` entry). Every output is written atomically.
#pragma once

#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "atex/container.h"
#include "atex/converters/fourdgs.h"
#include "atex/converters/spz.h"
#include "atex/model.h"
#include "atex/status.h"

namespace atex {

// kFourDgs: a 4DGaussians output folder; kSplat, kKsplat, kSog: web viewers'
// static formats (all read only).
enum class FileFormat : uint8_t { kUnknown = 0, kPly, kSpz, kAtex, kExrAtlas, kDraco, kFourDgs, kSplat, kKsplat, kSog };

// "ply", "spz", "atex", "exr", "drc", "4dgs", "splat", "ksplat", "sog" ("unknown" for kUnknown).
std::string_view FileFormatName(FileFormat format);
// The inverse of FileFormatName (case-insensitive); kInvalidArgument for other names.
StatusOr<FileFormat> ParseFileFormat(std::string_view name);
// By the path's extension (case-insensitive; a file named meta.json is kSog);
// kUnknown when it names no format.
// (An input that is a folder is read as kFourDgs by ReadAssetAs/ConvertFile;
// this function does not look at the file system.)
FileFormat FileFormatFromPath(const std::string& path);

// Called between stages with a stage name and the fraction done; returning
// false cancels the conversion (kCancelled).
using ConvertProgress = std::function<bool(std::string_view stage, double fraction)>;
// Per-frame export: called after frame `done` (1-based) of `total` is written;
// returning false cancels the export (kCancelled; the frames already written
// stay, frames.json is not written).
using FrameProgress = std::function<bool(size_t done, size_t total)>;

// The scene times of a per-frame export: start, start + step, ... while
// <= end + kFrameTolerance * step. The last time is snapped to `end` when it
// lies within that tolerance, so 0:1:0.1 gives 11 times ending at exactly 1.
// When start and step have at most 9 decimals, each time is the double
// nearest its decimal value (0.3, not 0.1 + 0.1 + 0.1).
inline constexpr size_t kMaxFrames = 100000;
inline constexpr double kFrameTolerance = 1e-6;
struct FrameRange {
  double start = 0;
  double end = 0;
  double step = 1;

  std::vector<double> Times() const;
};

// Parses "START:END:STEP" (decimal numbers, e.g. "0:1:0.1"). kInvalidArgument
// naming the problem for: not three ':'-separated numbers, a part that is not
// a finite number, STEP <= 0, END < START, or more than kMaxFrames times.
StatusOr<FrameRange> ParseFrameRange(std::string_view text);

struct ConvertOptions {
  FileFormat from = FileFormat::kUnknown;  // kUnknown: a folder is 4dgs, else the input's extension
  FileFormat to = FileFormat::kUnknown;    // kUnknown: from the output's extension (.ply for frames)
  SpzAxes spz_axes = SpzAxes::kOpenCv;     // for SPZ input and output
  int spz_version = 4;                     // 3 or 4
  int draco_bits = 16;                     // Draco position quantisation bits
  bool draco_attributes = false;           // also colour, opacity, log-scale, rotation
  std::optional<double> time;              // .ply/.spz/.drc output: deform to this scene time
  // .ply/.spz/.drc output: bake the textures into plain Gaussians (BakeTextures, texture_bake.h)
  // instead of dropping them. Not with `frames` (kInvalidArgument).
  bool bake_textures = false;
  std::string base_asset;                  // .exr input: the asset whose texture pool the atlas replaces
  int atlas_width = 0;                     // .exr output: 0 picks a square-ish atlas
  WriteOptions atex;                       // .atex output
  FourDgsImportOptions fourdgs;            // 4dgs input: iteration, head switches
  // Per-frame export into the output folder (see the top of this file);
  // excludes `time`. `to` must then be kUnknown (.ply), kPly or kSpz.
  std::optional<FrameRange> frames;
  ConvertProgress progress;                // optional
  FrameProgress frame_progress;            // optional, per-frame export only
};

struct ConvertReport {
  FileFormat from = FileFormat::kUnknown;
  FileFormat to = FileFormat::kUnknown;
  uint64_t gaussians = 0;
  int sh_degree = 0;
  bool textures = false;     // the input asset had a texture pool
  bool deformation = false;  // ... and a deformation field
  std::optional<double> time;
  std::vector<double> frame_times;  // per-frame export: the time of outputs[i] (frames.json is outputs.back())
  uint64_t input_bytes = 0;
  uint64_t output_bytes = 0;  // all files written (the .exr and its sidecar together)
  double read_seconds = 0;
  double convert_seconds = 0;  // deformation to --time / every frame
  double write_seconds = 0;
  std::vector<std::string> outputs;  // paths written
  std::vector<std::string> dropped;   // parts the output format cannot hold
  std::vector<std::string> warnings;  // losses that change what the output renders (textures dropped)
  std::vector<std::string> notes;

  nlohmann::json ToJson() const;
};

// Reads `path` as `format` (kUnknown: a folder is kFourDgs, else by extension)
// into an asset. .exr needs options.base_asset; .drc cannot be read.
StatusOr<Asset> ReadAssetAs(const std::string& path, FileFormat format, const ConvertOptions& options,
                            ConvertReport* report = nullptr);

// Writes `asset` to `path` as `format` (kUnknown: by extension), atomically.
// With options.frames, `path` is the output folder (created if missing) and
// `format` the frames' format (kUnknown: .ply).
Status WriteAssetAs(const std::string& path, const Asset& asset, FileFormat format, const ConvertOptions& options,
                    ConvertReport* report = nullptr);

// ReadAssetAs + WriteAssetAs with timings and the report. Options are checked
// before anything is read.
StatusOr<ConvertReport> ConvertFile(const std::string& input, const std::string& output,
                                    const ConvertOptions& options = {});

}  // namespace atex
