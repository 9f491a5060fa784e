// Helpers shared by the conversions of `atex convert` (convert.cc) and its per-frame export
// (convert_frames.cc). Not a public header.
#pragma once

#include <chrono>
#include <string_view>

#include "atex/converters/convert.h"

namespace atex::convert_detail {

using Clock = std::chrono::steady_clock;

inline double SecondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// Reports progress; kCancelled when the callback asks to stop.
inline Status Progress(const ConvertOptions& options, std::string_view stage, double fraction) {
  if (options.progress && !options.progress(stage, fraction)) {
    return MakeError(StatusCode::kCancelled, "conversion cancelled during '", stage, "'");
  }
  return Status::Ok();
}

inline constexpr const char* kTexturesDroppedWarning =
    "textures dropped: .ply/.spz/.drc cannot hold them, so the output renders as plain 4DGS without the "
    "per-Gaussian texture detail";

// `baked`: the deformation went into the output (per-frame export), not dropped;
// `textures_baked`: the textures went into the Gaussians (BakeTextures), not dropped.
inline void NoteDropped(const Asset& asset, ConvertReport* report, bool baked = false, bool textures_baked = false) {
  if (report == nullptr) return;
  if (asset.textures && !textures_baked) {
    report->dropped.push_back("textures");
    report->warnings.push_back(kTexturesDroppedWarning);
  }
  if (asset.deformation && !baked) report->dropped.push_back("deformation");
  if (asset.stats) report->dropped.push_back("stats");
}

}  // namespace atex::convert_detail
