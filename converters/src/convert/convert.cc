// Format dispatch for `atex convert` (see atex/converters/convert.h).
#include "atex/converters/convert.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "atex/container.h"
#include "atex/converters/drc.h"
#include "atex/converters/exr_atlas.h"
#include "atex/converters/ply.h"
#include "atex/converters/texture_bake.h"
#include "atex/converters/web_splats.h"
#include "atex/deform.h"
#include "atex/file_io.h"
#include "convert/convert_common.h"
#include "convert/convert_frames.h"
#include "convert/convert_names.h"
#include "convert/world_turn.h"

namespace atex {

using convert_detail::CheckFrameRange;
using convert_detail::Clock;
using convert_detail::CheckFramesFolder;
using convert_detail::Lower;
using convert_detail::NoteDropped;
using convert_detail::Progress;
using convert_detail::SecondsSince;
using convert_detail::WriteFrames;

namespace {

uint64_t FileSize(const std::string& path) {
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  return ec ? 0 : static_cast<uint64_t>(size);
}

StatusOr<FileFormat> Resolve(FileFormat format, const std::string& path, const char* role) {
  if (format != FileFormat::kUnknown) return format;
  // The only folder format is a 4DGaussians output; a folder that is not one
  // fails in the importer with a message that says what it looked for.
  std::error_code ec;
  if (std::string_view(role) == "input" && std::filesystem::is_directory(path, ec)) {
    // A folder holding a SOG meta.json is SOG; any other folder a 4DGaussians run.
    return std::filesystem::exists(std::filesystem::path(path) / "meta.json", ec) ? FileFormat::kSog
                                                                                  : FileFormat::kFourDgs;
  }
  const FileFormat by_name = FileFormatFromPath(path);
  if (by_name == FileFormat::kUnknown) {
    return MakeError(
        StatusCode::kInvalidArgument, "cannot tell the format of ", role, " '", path,
        "' from its extension (.ply, .spz, .atex, .exr, .drc, .splat, .ksplat, .sog, meta.json; a folder for a ",
        "4DGaussians run or a SOG); ", "name it with --from/--to");
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
  if (!options.time) {
    if (asset.gaussians.has_time_windows()) {  // their canonical set would show every one at every time
      return MakeError(StatusCode::kInvalidArgument,
                       "the asset has time-local Gaussians (GTWN): give the time to export with --time T");
    }
    return asset.gaussians;
  }
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

std::string TextureMode(const TexturePool& pool) {
  for (size_t i = 1; i < pool.size(); ++i) {
    if (pool.heights[i] != pool.heights[0] || pool.widths[i] != pool.widths[0]) return "adaptive";
  }
  return "uniform";
}

}  // namespace

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
                         {"warnings", warnings},
                         {"notes", notes}};
  json["time"] = time ? nlohmann::json(*time) : nlohmann::json(nullptr);
  json["frames"] = frame_times.empty() ? nlohmann::json(nullptr)
                                       : nlohmann::json({{"count", frame_times.size()}, {"times", frame_times}});
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
    case FileFormat::kSplat:
    case FileFormat::kKsplat:
    case FileFormat::kSog: {
      StatusOr<Gaussians> g = format == FileFormat::kSplat    ? ReadSplatGaussians(path)
                              : format == FileFormat::kKsplat ? ReadKsplatGaussians(path)
                                                              : ReadSogGaussians(path);
      if (!g.ok()) return g.status();
      // These formats store the 3DGS PLY world (y down), as .ply does.
      return AssetFromGaussians(std::move(g).value(), path, {{"format", FileFormatName(format)}}, "opencv");
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
    case FileFormat::kFourDgs: {
      ATEX_ASSIGN_OR_RETURN(Asset asset, ImportFourDGaussians(path, options.fourdgs));
      if (report) {
        // The importer records the iteration folder it chose; count the two files it read.
        const nlohmann::json& extra = asset.metadata.extra;
        const std::filesystem::path dir = extra.value("source", path);
        report->input_bytes +=
            FileSize((dir / "point_cloud.ply").string()) + FileSize((dir / "deformation.pth").string());
        static constexpr const char* kHeadNames[kNumDeformHeads] = {"position", "scale", "rotation", "opacity", "SH"};
        std::string heads;
        for (int h = 0; h < kNumDeformHeads; ++h) {
          if (!asset.deformation || !asset.deformation->config.heads[h]) continue;
          heads += StrCat(heads.empty() ? "" : ", ", kHeadNames[h]);
        }
        const std::string iteration =
            extra.contains("iteration") ? StrCat(" (iteration ", extra["iteration"].dump(), ")") : std::string();
        const nlohmann::json& flags = extra.value("head_flags", nlohmann::json::object());
        report->notes.push_back(StrCat("4DGaussians checkpoint '", dir.string(), "'", iteration,
                                       "; deformation heads: ", heads.empty() ? "none" : heads, " (flags from ",
                                       flags.value("from", std::string("?")), ")"));
      }
      return asset;
    }
    case FileFormat::kUnknown:
      break;
  }
  return MakeError(StatusCode::kInternal, "unhandled input format");
}

Status WriteAssetAs(const std::string& path, const Asset& asset, FileFormat format_in, const ConvertOptions& options,
                    ConvertReport* report) {
  if (options.frames) return WriteFrames(path, asset, format_in, options, report);
  ATEX_ASSIGN_OR_RETURN(FileFormat format, Resolve(format_in, path, "output"));
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
      const bool bake = options.bake_textures && asset.textures.has_value();
      if (bake) {
        TextureBakeReport baked;
        ATEX_ASSIGN_OR_RETURN(g, BakeTextures(g, *asset.textures, {}, &baked));
        if (report) {
          report->notes.push_back(StrCat("textures baked: ", baked.input_gaussians, " Gaussians -> ",
                                         baked.output_gaussians, " (", baked.split, " split, ", baked.folded,
                                         " folded)"));
        }
      }
      NoteDropped(asset, report, /*baked=*/false, /*textures_baked=*/bake);
      if (report) report->convert_seconds += SecondsSince(convert_start);
      ATEX_RETURN_IF_ERROR(Progress(options, "write", 0.0));
      const auto write_start = Clock::now();
      if (format == FileFormat::kPly || (format == FileFormat::kSpz && options.spz_axes == SpzAxes::kOpenCv)) {
        const std::string note = convert::TurnWorldDownY(asset.metadata, &g);
        if (report && !note.empty()) report->notes.push_back(note);
      }
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
    case FileFormat::kFourDgs:
      return MakeError(StatusCode::kUnsupported, "4DGaussians checkpoints can be read, not written");
    case FileFormat::kSplat:
    case FileFormat::kKsplat:
    case FileFormat::kSog:
      return MakeError(StatusCode::kUnsupported, ".", FileFormatName(format), " files can be read, not written");
    case FileFormat::kUnknown:
      return MakeError(StatusCode::kInternal, "unhandled output format");
  }
  return Progress(options, "write", 1.0);
}

StatusOr<ConvertReport> ConvertFile(const std::string& input, const std::string& output,
                                    const ConvertOptions& options) {
  ConvertReport report;
  ATEX_ASSIGN_OR_RETURN(report.from, Resolve(options.from, input, "input"));
  if (options.frames) {
    if (options.bake_textures)
      return MakeError(StatusCode::kInvalidArgument, "--bake-textures is not available with --frames (use --time)");
    // The output is a folder: its name says nothing about the frames' format.
    report.to = options.to == FileFormat::kUnknown ? FileFormat::kPly : options.to;
    if (report.to != FileFormat::kPly && report.to != FileFormat::kSpz) {
      return MakeError(StatusCode::kInvalidArgument, "--frames writes .ply or .spz files, not ",
                       FileFormatName(report.to));
    }
    if (options.time) return MakeError(StatusCode::kInvalidArgument, "--time and --frames exclude each other");
    ATEX_RETURN_IF_ERROR(CheckFrameRange(*options.frames));
    ATEX_RETURN_IF_ERROR(CheckFramesFolder(output));  // before a possibly long read
  } else {
    ATEX_ASSIGN_OR_RETURN(report.to, Resolve(options.to, output, "output"));
  }
  if (report.to == FileFormat::kSplat || report.to == FileFormat::kKsplat || report.to == FileFormat::kSog) {
    return MakeError(StatusCode::kUnsupported, ".", FileFormatName(report.to), " files can be read, not written");
  }
  if (report.to == FileFormat::kFourDgs) {
    return MakeError(StatusCode::kUnsupported, "4DGaussians checkpoints can be read, not written");
  }
  if (options.spz_version != 3 && options.spz_version != 4) {
    return MakeError(StatusCode::kInvalidArgument, "--spz-version ", options.spz_version, " (3 or 4)");
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
