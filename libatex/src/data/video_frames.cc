// Video decoding for datasets (video_frames.h).
#include "data/video_frames.h"

#include <mutex>

#if ATEX_HAVE_FFMPEG
extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/imgutils.h>
#include <libswscale/swscale.h>
}
#endif

namespace atex::data_detail {

#if ATEX_HAVE_FFMPEG

bool VideoDecodingAvailable() { return true; }

namespace {

std::string AvError(int code) {
  char text[AV_ERROR_MAX_STRING_SIZE] = {};
  av_strerror(code, text, sizeof(text));
  return text;
}

// Owns the FFmpeg objects of one decode.
struct Decoder {
  AVFormatContext* format = nullptr;
  AVCodecContext* codec = nullptr;
  AVPacket* packet = nullptr;
  AVFrame* frame = nullptr;
  SwsContext* scale = nullptr;
  ~Decoder() {
    sws_freeContext(scale);
    av_frame_free(&frame);
    av_packet_free(&packet);
    avcodec_free_context(&codec);
    avformat_close_input(&format);
  }
};

}  // namespace

StatusOr<int64_t> DecodeVideoFrames(const std::string& path, int64_t max_frames,
                                    const std::function<Status(int64_t, Image)>& sink) {
  // The library does not print: FFmpeg's own log lines (e.g. "moov atom not found") are
  // silenced; every failure comes back as a Status naming the file.
  static std::once_flag quiet;
  std::call_once(quiet, [] { av_log_set_level(AV_LOG_QUIET); });
  Decoder d;
  if (int rc = avformat_open_input(&d.format, path.c_str(), nullptr, nullptr); rc < 0) {
    return MakeError(rc == AVERROR(ENOENT) ? StatusCode::kNotFound : StatusCode::kCorrupt, path,
                     ": cannot open as a video (", AvError(rc), ")");
  }
  if (int rc = avformat_find_stream_info(d.format, nullptr); rc < 0) {
    return MakeError(StatusCode::kCorrupt, path, ": no stream information (", AvError(rc), ")");
  }
  const AVCodec* decoder = nullptr;
  const int stream = av_find_best_stream(d.format, AVMEDIA_TYPE_VIDEO, -1, -1, &decoder, 0);
  if (stream < 0 || decoder == nullptr) {
    return MakeError(stream == AVERROR_DECODER_NOT_FOUND ? StatusCode::kUnsupportedCodec : StatusCode::kCorrupt, path,
                     ": no decodable video stream (", AvError(stream), ")");
  }
  d.codec = avcodec_alloc_context3(decoder);
  d.packet = av_packet_alloc();
  d.frame = av_frame_alloc();
  if (!d.codec || !d.packet || !d.frame) return MakeError(StatusCode::kInternal, path, ": FFmpeg allocation failed");
  if (int rc = avcodec_parameters_to_context(d.codec, d.format->streams[stream]->codecpar); rc < 0) {
    return MakeError(StatusCode::kCorrupt, path, ": bad codec parameters (", AvError(rc), ")");
  }
  if (int rc = avcodec_open2(d.codec, decoder, nullptr); rc < 0) {
    return MakeError(StatusCode::kUnsupportedCodec, path, ": cannot open the ", decoder->name, " decoder (",
                     AvError(rc), ")");
  }
  int64_t decoded = 0;
  int width = 0, height = 0;
  // Converts and hands over every frame the decoder has ready; false when done.
  auto drain = [&](bool* done) -> Status {
    while (true) {
      const int rc = avcodec_receive_frame(d.codec, d.frame);
      if (rc == AVERROR(EAGAIN) || rc == AVERROR_EOF) return Status::Ok();
      if (rc < 0) return MakeError(StatusCode::kCorrupt, path, ": frame ", decoded, ": ", AvError(rc));
      const AVFrame* f = d.frame;
      if (f->width < 1 || f->height < 1 || f->width > kMaxImageSide || f->height > kMaxImageSide) {
        return MakeError(StatusCode::kCorrupt, path, ": frame ", decoded, " is ", f->width, "x", f->height);
      }
      if (decoded == 0) {
        width = f->width;
        height = f->height;
      } else if (f->width != width || f->height != height) {
        return MakeError(StatusCode::kCorrupt, path, ": frame ", decoded, " is ", f->width, "x", f->height,
                         ", the first was ", width, "x", height);
      }
      d.scale = sws_getCachedContext(d.scale, width, height, static_cast<AVPixelFormat>(f->format), width, height,
                                     AV_PIX_FMT_RGB24, SWS_BICUBIC | SWS_ACCURATE_RND | SWS_FULL_CHR_H_INT, nullptr,
                                     nullptr, nullptr);
      if (d.scale == nullptr) {
        return MakeError(StatusCode::kUnsupportedCodec, path, ": pixel format ",
                         av_get_pix_fmt_name(static_cast<AVPixelFormat>(f->format)), " cannot be converted to RGB");
      }
      std::vector<uint8_t> rgb(size_t(width) * height * 3);
      uint8_t* planes[4] = {rgb.data(), nullptr, nullptr, nullptr};
      int strides[4] = {width * 3, 0, 0, 0};
      sws_scale(d.scale, f->data, f->linesize, 0, height, planes, strides);
      av_frame_unref(d.frame);
      Image image(width, height, 3);
      for (size_t k = 0; k < rgb.size(); ++k) image.pixels[k] = rgb[k] / 255.0f;
      ATEX_RETURN_IF_ERROR(sink(decoded, std::move(image)));
      ++decoded;
      if (max_frames > 0 && decoded >= max_frames) {
        *done = true;
        return Status::Ok();
      }
    }
  };
  bool done = false;
  while (!done) {
    const int rc = av_read_frame(d.format, d.packet);
    if (rc == AVERROR_EOF) break;
    if (rc < 0)
      return MakeError(StatusCode::kCorrupt, path, ": read error after frame ", decoded, " (", AvError(rc), ")");
    if (d.packet->stream_index == stream) {
      const int sent = avcodec_send_packet(d.codec, d.packet);
      av_packet_unref(d.packet);
      if (sent < 0 && sent != AVERROR(EAGAIN)) {
        return MakeError(StatusCode::kCorrupt, path, ": frame ", decoded, ": ", AvError(sent));
      }
      ATEX_RETURN_IF_ERROR(drain(&done));
    } else {
      av_packet_unref(d.packet);
    }
  }
  if (!done) {  // the decoder's delayed frames
    avcodec_send_packet(d.codec, nullptr);
    ATEX_RETURN_IF_ERROR(drain(&done));
  }
  if (decoded == 0) return MakeError(StatusCode::kCorrupt, path, ": the video has no frames");
  return decoded;
}

#else  // !ATEX_HAVE_FFMPEG

bool VideoDecodingAvailable() { return false; }

StatusOr<int64_t> DecodeVideoFrames(const std::string& path, int64_t, const std::function<Status(int64_t, Image)>&) {
  return MakeError(StatusCode::kUnsupported, path,
                   ": this build cannot decode videos (built without FFmpeg: install libavformat-dev libavcodec-dev "
                   "libswscale-dev libavutil-dev and rebuild, or extract the frames first, e.g. ffmpeg -i cam00.mp4 "
                   "cam00/images/%04d.png)");
}

#endif

}  // namespace atex::data_detail
