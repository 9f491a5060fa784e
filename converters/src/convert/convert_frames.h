// The per-frame export of `atex convert --frames` (atex/converters/convert.h): one static file
// per time in a folder, then frames.json. Not a public header.
#pragma once

#include <string>

#include "atex/converters/convert.h"

namespace atex::convert_detail {

// The output of a per-frame export must be a folder or not exist yet (kInvalidArgument otherwise,
// and for a name that looks like a file of a known format).
Status CheckFramesFolder(const std::string& folder);

// Writes the frames of options.frames into `folder` (format_in: ply or spz; unknown = ply).
Status WriteFrames(const std::string& folder, const Asset& asset, FileFormat format_in, const ConvertOptions& options,
                   ConvertReport* report);

}  // namespace atex::convert_detail
