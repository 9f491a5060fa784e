// Format dispatch for `atex convert` (see atex/converters/convert.h).
#include "atex/converters/convert.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <system_error>

#include "atex/container.h"
#include "atex/converters/drc.h"
#include "atex/converters/exr_atlas.h"
#include "atex/converters/ply.h"
#include "atex/deform.h"
#include "atex/file_io.h"

namespace atex {

namespace {

using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

std::string Lower(std::string_view s) {
  std::string out(s);
  std::transform(out.begin(), out.end(), out.begin(), [](unsigned char c) { return std::tolower(c); });
  return out;
}

uint64_t FileSize(const std::string& path) {
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  return ec ? 0 : static_cast<uint64_t>(size);
}

Status Progress(const ConvertOptions& options, std::string_view stage, double fraction) {
  if (options.progress && !options.progress(stage, fraction)) {
    return MakeError(StatusCode::kCancelled, "conversion cancelled during '", stage, "'");
  }
  return Status::Ok();
}

StatusOr<FileFormat> Resolve(FileFormat format, const std::string& path, const char* role) {
  if (format != FileFormat::kUnknown) return format;
  const FileFormat by_name = FileFormatFromPath(path);
  if (by_name == FileFormat::kUnknown) {
    return MakeError(StatusCode::kInvalidArgument, "cannot tell the format of ", role, " '", path,
                     "' from its extension (.ply, .spz, .atex, .exr, .drc); name it with --from/--to");
  }
  return by_name;
}

// An asset holding static Gaussians read from a splat file.
Asset AssetFromGaussians(Gaussians g, const std::string& path, nlohmann::json source, std::string axes) {
  Asset asset;
  Metadata& m = asset.metadata;
  if (g.size() > 0) {
    for (int k = 0; k < 3; ++k) m.bounds_min[k] = m.bounds_max[k] = g.positions[k];
    for (size_t i = 0; i < g.positions.size(); ++i) {
      m.bounds_min[i % 3] = std::min(m.bounds_min[i % 3], g.positions[i]);
      m.bounds_max[i % 3] = std::max(m.bounds_max[i % 3], g.positions[i]);
    }
  }
  m.texture_mode = "none";
  m.axes = std::move(axes);
  source["file"] = std::filesystem::path(path).filename().string();
  m.extra["source"] = std::move(source);
  asset.gaussians = std::move(g);
  return asset;
}

// The Gaussians to write to a static format: canonical, or deformed to options.time.
StatusOr<Gaussians> GaussiansForOutput(const Asset& asset, const ConvertOptions& options, ConvertReport* report) {
  if (!options.time) return asset.gaussians;
  if (!std::isfinite(*options.time)) return MakeError(StatusCode::kInvalidArgument, "--time is not finite");
  if (!asset.deformation) {
    if (report) report->notes.push_back("static asset: --time has no effect");
    return asset.gaussians;
  }
  Gaussians deformed;
  ATEX_RETURN_IF_ERROR(DeformForward(*asset.deformation, asset.gaussians, *options.time, &deformed,
                                     static_cast<DeformCache*>(nullptr)));
  return deformed;
}

void NoteDropped(const Asset& asset, ConvertReport* report) {
  if (report == nullptr) return;
  if (asset.textures) report->dropped.push_back("textures");
  if (asset.deformation) report->dropped.push_back("deformation");
  if (asset.stats) report->dropped.push_back("stats");
}

std::string TextureMode(const TexturePool& pool) {
  for (size_t i = 1; i < pool.size(); ++i) {
    if (pool.heights[i] != pool.heights[0] || pool.widths[i] != pool.widths[0]) return "adaptive";
  }
  return "uniform";
}

}  // namespace

std::string_view FileFormatName(FileFormat format) {
  switch (format) {
    case FileFormat::kPly: return "ply";
    case FileFormat::kSpz: return "spz";
    case FileFormat::kAtex: return "atex";
    case FileFormat::kExrAtlas: return "exr";
    case FileFormat::kDraco: return "drc";
    case FileFormat::kUnknown: break;
  }
  return "unknown";
}

StatusOr<FileFormat> ParseFileFormat(std::string_view name) {
  const std::string lower = Lower(name);
  for (FileFormat f : {FileFormat::kPly, FileFormat::kSpz, FileFormat::kAtex, FileFormat::kExrAtlas,
                       FileFormat::kDraco}) {
    if (lower == FileFormatName(f)) return f;
  }
  return MakeError(StatusCode::kInvalidArgument, "unknown format '", name, "' (ply, spz, atex, exr, drc)");
}

FileFormat FileFormatFromPath(const std::string& path) {
  std::string ext = Lower(std::filesystem::path(path).extension().string());
  if (!ext.empty()) ext.erase(0, 1);
  auto format = ParseFileFormat(ext);
  return format.ok() ? *format : FileFormat::kUnknown;
}

nlohmann::json ConvertReport::ToJson() const {
  nlohmann::json json = {{"from", FileFormatName(from)},
                         {"to", FileFormatName(to)},
                         {"gaussians", gaussians},
                         {"sh_degree", sh_degree},
                         {"textures", textures},
                         {"deformation", deformation},
                         {"input_bytes", input_bytes},
                         {"output_bytes", output_bytes},
                         {"bytes_per_gaussian", gaussians ? double(output_bytes) / double(gaussians) : 0.0},
                         {"seconds", {{"read", read_seconds}, {"convert", convert_seconds}, {"write", write_seconds}}},
                         {"outputs", outputs},
                         {"dropped", dropped},
                         {"notes", notes}};
  json["time"] = time ? nlohmann::json(*time) : nlohmann::json(nullptr);
  return json;
}

StatusOr<Asset> ReadAssetAs(const std::string& path, FileFormat format_in, const ConvertOptions& options,
                            ConvertReport* report) {
  ATEX_ASSIGN_OR_RETURN(FileFormat format, Resolve(format_in, path, "input"));
  if (report) report->input_bytes += FileSize(path);
  switch (format) {
    case FileFormat::kPly: {
      ATEX_ASSIGN_OR_RETURN(Gaussians g, ReadPlyGaussians(path));
      return AssetFromGaussians(std::move(g), path, {{"format", "ply"}}, "opencv");
    }
    case FileFormat::kSpz: {
      SpzReadOptions read;
      read.axes = options.spz_axes;
      SpzInfo info;
      ATEX_ASSIGN_OR_RETURN(Gaussians g, ReadSpzGaussians(path, read, &info));
      nlohmann::json source = {{"format", "spz"},
                               {"version", info.version},
                               {"stored_axes", info.stored_axes},
                               {"fractional_bits", info.fractional_bits},
                               {"antialiased", info.antialiased}};
      if (info.sh_truncated && report) report->notes.push_back("SPZ SH degree 4 truncated to 3");
      // kOpenCv converts to libatex's RDF world; kStored keeps the file's axes.
      std::string axes = options.spz_axes == SpzAxes::kOpenCv ? "opencv" : Lower(info.stored_axes);
      if (axes == "rub") axes = "opengl";
      return AssetFromGaussians(std::move(g), path, std::move(source), axes);
    }
    case FileFormat::kAtex:
      return ReadAssetFile(path);
    case FileFormat::kExrAtlas: {
      if (options.base_asset.empty()) {
        return MakeError(StatusCode::kInvalidArgument, "an .exr atlas holds textures only: name the asset whose ",
                         "Gaussians it belongs to with --base");
      }
      if (FileFormatFromPath(options.base_asset) == FileFormat::kExrAtlas) {
        return MakeError(StatusCode::kInvalidArgument, "--base must be a .atex, .ply or .spz file");
      }
      ATEX_ASSIGN_OR_RETURN(Asset asset, ReadAssetAs(options.base_asset, FileFormat::kUnknown, options, report));
      ATEX_ASSIGN_OR_RETURN(TexturePool pool, ReadExrAtlas(path));
      if (report) report->input_bytes += FileSize(ExrAtlasSidecarPath(path));
      if (pool.size() != asset.gaussians.size()) {
        return MakeError(StatusCode::kInvalidArgument, "atlas '", path, "' has textures for ", pool.size(),
                         " Gaussians, the base asset '", options.base_asset, "' has ", asset.gaussians.size());
      }
      asset.metadata.texture_mode = TextureMode(pool);
      asset.textures = std::move(pool);
      return asset;
    }
    case FileFormat::kDraco:
      return MakeError(StatusCode::kUnsupported,
                       "a Draco .drc holds points only (no Gaussian shapes); it can be written but not read");
    case FileFormat::kUnknown:
      break;
  }
  return MakeError(StatusCode::kInternal, "unhandled input format");
}

Status WriteAssetAs(const std::string& path, const Asset& asset, FileFormat format_in, const ConvertOptions& options,
                    ConvertReport* report) {
  ATEX_ASSIGN_OR_RETURN(FileFormat format, Resolve(format_in, path, "output"));
  if (options.frames) {
    return MakeError(StatusCode::kUnsupported, "per-frame export (--frames) is reserved and not implemented yet");
  }
  auto written = [&](const std::string& p) {
    if (report == nullptr) return;
    report->outputs.push_back(p);
    report->output_bytes += FileSize(p);
  };
  const auto convert_start = Clock::now();
  switch (format) {
    case FileFormat::kPly:
    case FileFormat::kSpz:
    case FileFormat::kDraco: {
      ATEX_ASSIGN_OR_RETURN(Gaussians g, GaussiansForOutput(asset, options, report));
      NoteDropped(asset, report);
      if (report) report->convert_seconds += SecondsSince(convert_start);
      ATEX_RETURN_IF_ERROR(Progress(options, "write", 0.0));
      const auto write_start = Clock::now();
      if (format == FileFormat::kPly) {
        ATEX_RETURN_IF_ERROR(WritePlyGaussians(path, g));
      } else if (format == FileFormat::kSpz) {
        SpzWriteOptions spz;
        spz.version = options.spz_version;
        spz.axes = options.spz_axes;
        ATEX_RETURN_IF_ERROR(WriteSpzGaussians(path, g, spz));
      } else {
        DracoExportOptions drc;
        drc.position_bits = options.draco_bits;
        drc.colors = drc.opacity = drc.scales = drc.rotations = options.draco_attributes;
        ATEX_RETURN_IF_ERROR(WriteDracoPointCloud(path, g, drc));
      }
      if (report) report->write_seconds += SecondsSince(write_start);
      written(path);
      break;
    }
    case FileFormat::kAtex: {
      const auto write_start = Clock::now();
      ATEX_RETURN_IF_ERROR(WriteAssetFile(path, asset, options.atex));
      if (report) report->write_seconds += SecondsSince(write_start);
      written(path);
      break;
    }
    case FileFormat::kExrAtlas: {
      if (!asset.textures) {
        return MakeError(StatusCode::kInvalidArgument, "the input has no texture pool to write as an .exr atlas");
      }
      const auto write_start = Clock::now();
      ExrAtlasOptions exr;
      exr.width = options.atlas_width;
      ATEX_RETURN_IF_ERROR(WriteExrAtlas(path, *asset.textures, exr));
      if (report) {
        report->write_seconds += SecondsSince(write_start);
        report->notes.push_back("texels rounded to half precision");
      }
      written(path);
      written(ExrAtlasSidecarPath(path));
      break;
    }
    case FileFormat::kUnknown:
      return MakeError(StatusCode::kInternal, "unhandled output format");
  }
  return Progress(options, "write", 1.0);
}

StatusOr<ConvertReport> ConvertFile(const std::string& input, const std::string& output,
                                    const ConvertOptions& options) {
  ConvertReport report;
  ATEX_ASSIGN_OR_RETURN(report.from, Resolve(options.from, input, "input"));
  ATEX_ASSIGN_OR_RETURN(report.to, Resolve(options.to, output, "output"));
  if (options.spz_version != 3 && options.spz_version != 4) {
    return MakeError(StatusCode::kInvalidArgument, "--spz-version ", options.spz_version, " (3 or 4)");
  }
  if (options.frames) {
    return MakeError(StatusCode::kUnsupported, "per-frame export (--frames) is reserved and not implemented yet");
  }
  std::error_code ec;
  if (std::filesystem::equivalent(input, output, ec)) {
    return MakeError(StatusCode::kInvalidArgument, "input and output are the same file: '", input, "'");
  }
  ATEX_RETURN_IF_ERROR(Progress(options, "read", 0.0));
  const auto read_start = Clock::now();
  ATEX_ASSIGN_OR_RETURN(Asset asset, ReadAssetAs(input, report.from, options, &report));
  report.read_seconds = SecondsSince(read_start);
  report.gaussians = asset.gaussians.size();
  report.sh_degree = asset.gaussians.sh_degree;
  report.textures = asset.textures.has_value();
  report.deformation = asset.deformation.has_value();
  report.time = options.time;
  ATEX_RETURN_IF_ERROR(Progress(options, "read", 1.0));
  ATEX_RETURN_IF_ERROR(WriteAssetAs(output, asset, report.to, options, &report));
  return report;
}

}  // namespace atex
