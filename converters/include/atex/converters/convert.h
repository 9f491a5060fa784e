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
//
// Conversions to a format that cannot hold part of the asset (textures or the
// deformation field into .ply/.spz/.drc) drop that part and say so in the
// report. Every output is written atomically. Reserved for later (kUnsupported
// now): per-frame export (`frames`) and importing a 4DGaussians checkpoint
// folder (see fourdgs.h).
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "atex/container.h"
#include "atex/converters/spz.h"
#include "atex/model.h"
#include "atex/status.h"

namespace atex {

enum class FileFormat : uint8_t { kUnknown = 0, kPly, kSpz, kAtex, kExrAtlas, kDraco };

// "ply", "spz", "atex", "exr", "drc" ("unknown" for kUnknown).
std::string_view FileFormatName(FileFormat format);
// The inverse of FileFormatName (case-insensitive); kInvalidArgument for other names.
StatusOr<FileFormat> ParseFileFormat(std::string_view name);
// By the path's extension (case-insensitive); kUnknown when it names no format.
FileFormat FileFormatFromPath(const std::string& path);

// Called between stages with a stage name and the fraction done; returning
// false cancels the conversion (kCancelled).
using ConvertProgress = std::function<bool(std::string_view stage, double fraction)>;

struct ConvertOptions {
  FileFormat from = FileFormat::kUnknown;  // kUnknown: from the input's extension
  FileFormat to = FileFormat::kUnknown;    // kUnknown: from the output's extension
  SpzAxes spz_axes = SpzAxes::kOpenCv;     // for SPZ input and output
  int spz_version = 4;                     // 3 or 4
  int draco_bits = 16;                     // Draco position quantisation bits
  bool draco_attributes = false;           // also colour, opacity, log-scale, rotation
  std::optional<double> time;              // .ply/.spz/.drc output: deform to this scene time
  std::string base_asset;                  // .exr input: the asset whose texture pool the atlas replaces
  int atlas_width = 0;                     // .exr output: 0 picks a square-ish atlas
  WriteOptions atex;                       // .atex output
  bool frames = false;                     // reserved: per-frame export (kUnsupported for now)
  ConvertProgress progress;                // optional
};

struct ConvertReport {
  FileFormat from = FileFormat::kUnknown;
  FileFormat to = FileFormat::kUnknown;
  uint64_t gaussians = 0;
  int sh_degree = 0;
  bool textures = false;     // the input asset had a texture pool
  bool deformation = false;  // ... and a deformation field
  std::optional<double> time;
  uint64_t input_bytes = 0;
  uint64_t output_bytes = 0;  // all files written (the .exr and its sidecar together)
  double read_seconds = 0;
  double convert_seconds = 0;  // deformation to --time, quantisation
  double write_seconds = 0;
  std::vector<std::string> outputs;  // paths written
  std::vector<std::string> dropped;  // parts the output format cannot hold
  std::vector<std::string> notes;

  nlohmann::json ToJson() const;
};

// Reads `path` as `format` (kUnknown: by extension) into an asset. .exr needs
// options.base_asset; .drc cannot be read.
StatusOr<Asset> ReadAssetAs(const std::string& path, FileFormat format, const ConvertOptions& options,
                            ConvertReport* report = nullptr);

// Writes `asset` to `path` as `format` (kUnknown: by extension), atomically.
Status WriteAssetAs(const std::string& path, const Asset& asset, FileFormat format, const ConvertOptions& options,
                    ConvertReport* report = nullptr);

// ReadAssetAs + WriteAssetAs with timings and the report.
StatusOr<ConvertReport> ConvertFile(const std::string& input, const std::string& output,
                                    const ConvertOptions& options = {});

}  // namespace atex
