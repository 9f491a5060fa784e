#include "convert/convert_names.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <system_error>

namespace atex {
namespace convert_detail {

std::string Lower(std::string_view s) {
  std::string out(s);
  std::transform(out.begin(), out.end(), out.begin(), [](unsigned char c) { return std::tolower(c); });
  return out;
}

Status CheckFrameRange(const FrameRange& r) {
  if (!std::isfinite(r.start) || !std::isfinite(r.end) || !std::isfinite(r.step)) {
    return MakeError(StatusCode::kInvalidArgument, "--frames ", r.start, ":", r.end, ":", r.step,
                     " has a part that is not a finite number");
  }
  if (!(r.step > 0)) {
    return MakeError(StatusCode::kInvalidArgument, "--frames STEP ", r.step,
                     " is not positive (times go from START up to END)");
  }
  if (r.end < r.start) {
    return MakeError(StatusCode::kInvalidArgument, "--frames END ", r.end, " is before START ", r.start);
  }
  // In double so that a tiny step cannot overflow the count.
  const double count = std::floor((r.end - r.start) / r.step + kFrameTolerance) + 1;
  if (!(count <= static_cast<double>(kMaxFrames))) {
    const std::string how_many = count < 1e18 ? std::to_string(static_cast<uint64_t>(count)) : StrCat(count);
    return MakeError(StatusCode::kInvalidArgument, "--frames ", r.start, ":", r.end, ":", r.step, " gives ", how_many,
                     " frames, more than the limit of ", kMaxFrames, " (use a larger STEP)");
  }
  return Status::Ok();
}

}  // namespace convert_detail

using convert_detail::CheckFrameRange;
using convert_detail::Lower;

std::string_view FileFormatName(FileFormat format) {
  switch (format) {
    case FileFormat::kPly: return "ply";
    case FileFormat::kSpz: return "spz";
    case FileFormat::kAtex: return "atex";
    case FileFormat::kExrAtlas: return "exr";
    case FileFormat::kDraco: return "drc";
    case FileFormat::kFourDgs: return "4dgs";
    case FileFormat::kSplat: return "splat";
    case FileFormat::kKsplat: return "ksplat";
    case FileFormat::kSog: return "sog";
    case FileFormat::kUnknown: break;
  }
  return "unknown";
}

StatusOr<FileFormat> ParseFileFormat(std::string_view name) {
  const std::string lower = Lower(name);
  for (FileFormat f : {FileFormat::kPly, FileFormat::kSpz, FileFormat::kAtex, FileFormat::kExrAtlas,
                       FileFormat::kDraco, FileFormat::kFourDgs, FileFormat::kSplat, FileFormat::kKsplat,
                       FileFormat::kSog}) {
    if (lower == FileFormatName(f)) return f;
  }
  return MakeError(StatusCode::kInvalidArgument, "unknown format '", name,
                   "' (ply, spz, atex, exr, drc, 4dgs, splat, ksplat, sog)");
}

std::vector<double> FrameRange::Times() const {
  if (!CheckFrameRange(*this).ok()) return {};
  const size_t count = static_cast<size_t>(std::floor((end - start) / step + kFrameTolerance)) + 1;
  std::vector<double> times(count);
  // start + i * step rather than a running sum, so that errors do not accumulate.
  for (size_t i = 0; i < count; ++i) times[i] = start + static_cast<double>(i) * step;
  // When START and STEP are short decimals (0.1, 0.04, 2.5), count in units of
  // their last decimal place so that each time is the double nearest to its
  // decimal value (3 x 0.1 gives 0.3, not 0.30000000000000004): frames.json
  // then shows the times a user typed or a dataset lists.
  for (int digits = 0; digits <= 9; ++digits) {
    const double unit = std::pow(10.0, digits);
    const double a = std::round(start * unit), s = std::round(step * unit);
    // A decimal read into a double misses its scaled integer by a few ulps only.
    auto near = [](double scaled, double rounded) {
      return std::fabs(scaled - rounded) <= std::max(1e-9, 1e-14 * std::fabs(rounded));
    };
    if (!near(start * unit, a) || !near(step * unit, s)) continue;
    if (std::fabs(a) + s * static_cast<double>(count) > 0x1p52) break;  // integers no longer exact
    for (size_t i = 0; i < count; ++i) times[i] = (a + static_cast<double>(i) * s) / unit;
    break;
  }
  if (std::fabs(times.back() - end) <= kFrameTolerance * step) times.back() = end;
  return times;
}

StatusOr<FrameRange> ParseFrameRange(std::string_view text) {
  const char* names[3] = {"START", "END", "STEP"};
  double values[3] = {0, 0, 0};
  std::string_view rest = text;
  for (int k = 0; k < 3; ++k) {
    const size_t colon = rest.find(':');
    if ((k < 2) != (colon != std::string_view::npos)) {
      return MakeError(StatusCode::kInvalidArgument, "--frames '", text,
                       "' is not START:END:STEP (three numbers separated by ':', e.g. 0:1:0.1)");
    }
    const std::string_view part = rest.substr(0, colon);
    if (part.empty()) {
      return MakeError(StatusCode::kInvalidArgument, "--frames '", text, "': ", names[k], " is empty");
    }
    const auto [end, error] = std::from_chars(part.data(), part.data() + part.size(), values[k]);
    if (error != std::errc() || end != part.data() + part.size() || !std::isfinite(values[k])) {
      return MakeError(StatusCode::kInvalidArgument, "--frames '", text, "': ", names[k], " '", part,
                       "' is not a finite number");
    }
    rest = colon == std::string_view::npos ? std::string_view() : rest.substr(colon + 1);
  }
  const FrameRange range{values[0], values[1], values[2]};
  ATEX_RETURN_IF_ERROR(CheckFrameRange(range));
  return range;
}

FileFormat FileFormatFromPath(const std::string& path) {
  if (Lower(std::filesystem::path(path).filename().string()) == "meta.json") return FileFormat::kSog;
  std::string ext = Lower(std::filesystem::path(path).extension().string());
  if (!ext.empty()) ext.erase(0, 1);
  auto format = ParseFileFormat(ext);
  return format.ok() ? *format : FileFormat::kUnknown;
}

}  // namespace atex
