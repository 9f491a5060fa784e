// Video frames decoded with FFmpeg's libavformat/libavcodec/libswscale (Debian's packages;
// optional: ATEX_HAVE_FFMPEG). Not a public header.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "atex/image.h"
#include "atex/status.h"

namespace atex::data_detail {

// Whether this build decodes videos.
bool VideoDecodingAvailable();

// Decodes the first `max_frames` frames (0 = all) of the video stream of `path`, in
// presentation order, each as an 8-bit RGB Image ([H][W][3], values k/255) passed to
// `sink(index, image)`; a sink error stops decoding and is returned. kUnsupported when
// built without FFmpeg (the message says how to get frames another way), kNotFound /
// kCorrupt / kUnsupportedCodec naming the file (and the frame) for unreadable input;
// frame sizes outside 1..kMaxImageSide or changing mid-stream are kCorrupt. Returns the
// number of frames decoded.
StatusOr<int64_t> DecodeVideoFrames(const std::string& path, int64_t max_frames,
                                    const std::function<Status(int64_t, Image)>& sink);

}  // namespace atex::data_detail
