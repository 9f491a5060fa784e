// Per-frame export of `atex convert --frames` (convert_frames.h).
#include "convert/convert_frames.h"

#include <cstdio>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "atex/converters/ply.h"
#include "atex/converters/spz.h"
#include "atex/deform.h"
#include "atex/file_io.h"
#include "convert/convert_common.h"
#include "convert/convert_names.h"
#include "convert/world_turn.h"

namespace atex::convert_detail {
namespace {

// Per-frame file names sort in time order: frame_0000 ... with more digits
// only when there are more than 10000 frames.
std::string FrameFileName(size_t index, size_t count, FileFormat format) {
  int digits = 4;
  for (size_t n = 10000; n < count; n *= 10) ++digits;
  char name[48];
  std::snprintf(name, sizeof name, "frame_%0*zu.%s", digits, index, format == FileFormat::kSpz ? "spz" : "ply");
  return name;
}

// Checks the request, creates the folder and removes an earlier export's frames.json; returns
// the manifest's path.
StatusOr<std::string> PrepareFramesFolder(const std::string& folder, FileFormat format, const ConvertOptions& options) {
  namespace fs = std::filesystem;
  if (format != FileFormat::kPly && format != FileFormat::kSpz) {
    return MakeError(StatusCode::kInvalidArgument, "--frames writes .ply or .spz files, not ", FileFormatName(format));
  }
  if (options.time) return MakeError(StatusCode::kInvalidArgument, "--time and --frames exclude each other");
  ATEX_RETURN_IF_ERROR(CheckFrameRange(*options.frames));
  ATEX_RETURN_IF_ERROR(CheckFramesFolder(folder));
  std::error_code ec;
  fs::create_directories(folder, ec);
  if (ec) return MakeError(StatusCode::kIoError, "cannot create the frames folder '", folder, "': ", ec.message());
  const std::string manifest_path = (fs::path(folder) / "frames.json").string();
  // A manifest left by an earlier export would describe files this one
  // overwrites; without it the folder reads as incomplete until we finish.
  fs::remove(manifest_path, ec);
  if (ec) return MakeError(StatusCode::kIoError, "cannot remove the old '", manifest_path, "': ", ec.message());
  return manifest_path;
}

// The report's notes on what the frames hold, and on frame files of an earlier, longer export.
void NoteFrames(const Asset& asset, const std::string& folder, const std::vector<double>& times, FileFormat format,
                ConvertReport* report) {
  namespace fs = std::filesystem;
  if (!asset.deformation) {
    report->notes.push_back(
        StrCat("static asset: every one of the ", times.size(), " frames holds the canonical Gaussians"));
  } else {
    report->notes.push_back(StrCat("deformation (every enabled head) baked into ", times.size(), " frames"));
    const Metadata& m = asset.metadata;
    if (times.front() < m.time_min || times.back() > m.time_max) {
      report->notes.push_back(StrCat("frames from ", times.front(), " to ", times.back(),
                                     " reach outside the asset's time range [", m.time_min, ", ", m.time_max,
                                     "]; the motion there is the field's extrapolation, not trained motion"));
    }
  }
  std::error_code ec;
  if (fs::exists(fs::path(folder) / FrameFileName(times.size(), times.size(), format), ec)) {
    report->notes.push_back(StrCat("'", folder, "' still holds frame files of an earlier, longer export after ",
                                   FrameFileName(times.size() - 1, times.size(), format),
                                   "; frames.json lists this export's files only"));
  }
}

// Encodes the Gaussians of one frame as .ply or .spz.
class FrameEncoder {
 public:
  FrameEncoder(const Asset& asset, FileFormat format, const ConvertOptions& options)
      : asset_(asset),
        format_(format),
        // PLY and SPZ (unless its stored axes are asked for) get the world turned to their up axis.
        turn_(format == FileFormat::kPly || options.spz_axes == SpzAxes::kOpenCv) {
    spz_.version = options.spz_version;
    spz_.axes = options.spz_axes;
  }

  StatusOr<std::vector<uint8_t>> Encode(const Gaussians& shown) {
    Gaussians g = shown;
    if (turn_) turn_note_ = convert::TurnWorldDownY(asset_.metadata, &g);
    if (format_ == FileFormat::kPly) return EncodePlyGaussians(g);
    return EncodeSpz(g, spz_);
  }
  // What the last turn of the world did, for the report (empty: nothing).
  const std::string& turn_note() const { return turn_note_; }

 private:
  const Asset& asset_;
  FileFormat format_;
  bool turn_;
  SpzWriteOptions spz_;
  std::string turn_note_;
};

// Writes one file per time into `dir`; returns the manifest's entries (file and time of each).
StatusOr<nlohmann::json> WriteFrameFiles(const std::filesystem::path& dir, const Asset& asset, FileFormat format,
                                         const std::vector<double>& times, FrameEncoder& encoder,
                                         const ConvertOptions& options, ConvertReport* report) {
  // A static asset gives the same bytes at every time: encode them once.
  std::vector<uint8_t> static_bytes;
  if (!asset.deformation) {
    const auto start = Clock::now();
    ATEX_ASSIGN_OR_RETURN(static_bytes, encoder.Encode(asset.gaussians));
    if (report) report->write_seconds += SecondsSince(start);
  }
  Gaussians deformed;
  nlohmann::json entries = nlohmann::json::array();
  for (size_t i = 0; i < times.size(); ++i) {
    const std::string name = FrameFileName(i, times.size(), format);
    const std::string path = (dir / name).string();
    std::vector<uint8_t> frame_bytes;
    if (asset.deformation) {
      const auto convert_start = Clock::now();
      Status deformed_ok =
          DeformForward(*asset.deformation, asset.gaussians, times[i], &deformed, static_cast<DeformCache*>(nullptr));
      if (!deformed_ok.ok()) return deformed_ok.WithContext(StrCat("frame ", i, " (time ", times[i], ")"));
      if (report) report->convert_seconds += SecondsSince(convert_start);
      const auto encode_start = Clock::now();
      auto encoded = encoder.Encode(deformed);
      if (!encoded.ok()) return encoded.status().WithContext(StrCat("frame ", i, " (time ", times[i], ")"));
      frame_bytes = std::move(encoded).value();
      if (report) report->write_seconds += SecondsSince(encode_start);
    }
    const std::vector<uint8_t>& bytes = asset.deformation ? frame_bytes : static_bytes;
    const auto write_start = Clock::now();
    ATEX_RETURN_IF_ERROR(WriteFileAtomic(path, bytes));
    if (report) {
      report->write_seconds += SecondsSince(write_start);
      report->outputs.push_back(path);
      report->output_bytes += bytes.size();
      report->frame_times.push_back(times[i]);
    }
    entries.push_back({{"file", name}, {"time", times[i]}});
    if (options.frame_progress && !options.frame_progress(i + 1, times.size())) {
      return MakeError(StatusCode::kCancelled, "per-frame export cancelled after frame ", i + 1, " of ", times.size(),
                       " (frames.json not written)");
    }
  }
  return entries;
}

// frames.json: the range, the asset's time range and the frames' files and times.
Status WriteManifest(const std::string& manifest_path, const Asset& asset, FileFormat format, size_t count,
                     nlohmann::json entries, const ConvertOptions& options, ConvertReport* report) {
  const FrameRange& range = *options.frames;
  nlohmann::json manifest = {{"generator", "atex convert"},
                             {"format", FileFormatName(format)},
                             {"count", count},
                             {"range", {{"start", range.start}, {"end", range.end}, {"step", range.step}}},
                             {"asset_time_range", {asset.metadata.time_min, asset.metadata.time_max}},
                             {"deformed", asset.deformation.has_value()},
                             {"textures_dropped", asset.textures.has_value()},
                             {"frames", std::move(entries)}};
  if (format == FileFormat::kSpz) {
    manifest["spz"] = {{"version", options.spz_version},
                       {"axes", options.spz_axes == SpzAxes::kOpenCv ? "RUB (converted from opencv)" : "stored"}};
  }
  const std::string text = manifest.dump(1) + "\n";
  const auto write_start = Clock::now();
  ATEX_RETURN_IF_ERROR(WriteFileAtomic(manifest_path, text.data(), text.size()));
  if (report) {
    report->write_seconds += SecondsSince(write_start);
    report->outputs.push_back(manifest_path);
    report->output_bytes += text.size();
  }
  return Status::Ok();
}

}  // namespace

// The output of a per-frame export must be a folder or not exist yet.
Status CheckFramesFolder(const std::string& folder) {
  std::error_code ec;
  const bool is_folder = std::filesystem::is_directory(folder, ec);
  if (!is_folder && std::filesystem::exists(folder, ec)) {
    return MakeError(StatusCode::kInvalidArgument, "--frames writes into a folder; '", folder, "' is a file");
  }
  // `atex convert a.atex --frames 0:1:0.1 out.ply` is far more likely a
  // mistake than a wish for a folder named out.ply.
  if (!is_folder && FileFormatFromPath(folder) != FileFormat::kUnknown) {
    return MakeError(StatusCode::kInvalidArgument, "--frames writes into a folder, but '", folder,
                     "' looks like a file name; name a folder and choose the frames' format with --to ply|spz");
  }
  return Status::Ok();
}

// Per-frame export (see convert.h): one file per time in `folder`, then frames.json.
Status WriteFrames(const std::string& folder, const Asset& asset, FileFormat format_in, const ConvertOptions& options,
                   ConvertReport* report) {
  const FileFormat format = format_in == FileFormat::kUnknown ? FileFormat::kPly : format_in;
  ATEX_ASSIGN_OR_RETURN(const std::string manifest_path, PrepareFramesFolder(folder, format, options));
  const std::vector<double> times = options.frames->Times();
  NoteDropped(asset, report, /*baked=*/true);
  if (report) NoteFrames(asset, folder, times, format, report);

  FrameEncoder encoder(asset, format, options);
  ATEX_RETURN_IF_ERROR(Progress(options, "write", 0.0));
  ATEX_ASSIGN_OR_RETURN(nlohmann::json entries,
                        WriteFrameFiles(std::filesystem::path(folder), asset, format, times, encoder, options, report));
  if (report && !encoder.turn_note().empty()) report->notes.push_back(encoder.turn_note());
  ATEX_RETURN_IF_ERROR(WriteManifest(manifest_path, asset, format, times.size(), std::move(entries), options, report));
  return Progress(options, "write", 1.0);
}

}  // namespace atex::convert_detail
