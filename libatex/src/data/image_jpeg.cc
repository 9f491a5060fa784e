// JPEG through libjpeg(-turbo). Errors leave libjpeg by longjmp from our error
// manager; as for PNG, the functions that call setjmp hold no C++ objects with
// destructors. Hostile-input measures: a truncated or corrupt entropy-coded
// segment is an error (libjpeg would pad it with grey), progressive scans are
// capped, libjpeg's own memory is capped, and the decoded size must be
// plausible for the bytes present.
#include <cstdio>
// jpeglib.h needs size_t and FILE declared first.
#include <jerror.h>
#include <jpeglib.h>

#include <csetjmp>
#include <cstdlib>
#include <cstring>
#include <new>

#include "data/image_codecs.h"

namespace atex::image_detail {
namespace {

constexpr int kMaxScans = 1000;                           // progressive scans (libjpeg-turbo suggests ~100s)
constexpr long kMaxLibjpegMemory = 1l << 30;              // libjpeg working memory
constexpr uint64_t kMaxPixelsPerByte = 4096;              // Huffman needs >= ~2 bits per 8x8 block
constexpr uint64_t kAlwaysAllowedPixels = uint64_t{1} << 22;

struct JpegErrorManager {
  jpeg_error_mgr mgr;  // first member: libjpeg passes &mgr, we cast back
  jmp_buf jump;
  char message[JMSG_LENGTH_MAX];
};

[[noreturn]] void OnJpegError(j_common_ptr cinfo) {
  auto* err = reinterpret_cast<JpegErrorManager*>(cinfo->err);
  (*cinfo->err->format_message)(cinfo, err->message);
  std::longjmp(err->jump, 1);
}

// Warnings (msg_level < 0) that mean missing image data are fatal; the rest
// (e.g. extraneous bytes before a marker) are tolerated silently.
void OnJpegMessage(j_common_ptr cinfo, int msg_level) {
  if (msg_level < 0 && (cinfo->err->msg_code == JWRN_JPEG_EOF || cinfo->err->msg_code == JWRN_HIT_MARKER ||
                        cinfo->err->msg_code == JWRN_MUST_RESYNC)) {
    OnJpegError(cinfo);
  }
}
void OnJpegOutput(j_common_ptr) {}

void OnJpegProgress(j_common_ptr cinfo) {
  if (cinfo->is_decompressor) {
    auto* d = reinterpret_cast<j_decompress_ptr>(cinfo);
    if (d->input_scan_number > kMaxScans) {
      auto* err = reinterpret_cast<JpegErrorManager*>(cinfo->err);
      std::snprintf(err->message, sizeof(err->message), "more than %d progressive scans", kMaxScans);
      std::longjmp(err->jump, 1);
    }
  }
}

void InstallErrorManager(JpegErrorManager* err) {
  jpeg_std_error(&err->mgr);
  err->mgr.error_exit = OnJpegError;
  err->mgr.emit_message = OnJpegMessage;
  err->mgr.output_message = OnJpegOutput;
  err->message[0] = '\0';
}

struct JpegHeader {
  int width = 0, height = 0, components = 0;
  J_COLOR_SPACE color_space = JCS_UNKNOWN;
};

// Creates the decompressor and reads the header. Returns false after a libjpeg error.
bool ReadJpegHeader(jpeg_decompress_struct* cinfo, JpegErrorManager* err, jpeg_progress_mgr* progress,
                    const uint8_t* data, size_t size, JpegHeader* header) {
  if (setjmp(err->jump)) return false;
  jpeg_mem_src(cinfo, data, static_cast<unsigned long>(size));
  cinfo->mem->max_memory_to_use = kMaxLibjpegMemory;
  progress->progress_monitor = OnJpegProgress;
  cinfo->progress = progress;
  jpeg_read_header(cinfo, TRUE);
  header->width = static_cast<int>(cinfo->image_width);
  header->height = static_cast<int>(cinfo->image_height);
  header->components = cinfo->num_components;
  header->color_space = cinfo->jpeg_color_space;
  return true;
}

// Decodes every scanline into `out` ([height][width][components], sized by the caller).
bool ReadJpegPixels(jpeg_decompress_struct* cinfo, JpegErrorManager* err, uint8_t* out, size_t row_bytes,
                    int expected_components) {
  if (setjmp(err->jump)) return false;
  cinfo->out_color_space = expected_components == 1 ? JCS_GRAYSCALE : JCS_RGB;
  jpeg_start_decompress(cinfo);
  if (cinfo->output_components != expected_components) {
    std::snprintf(err->message, sizeof(err->message), "unexpected output components %d", cinfo->output_components);
    return false;
  }
  while (cinfo->output_scanline < cinfo->output_height) {
    JSAMPROW row = out + size_t{cinfo->output_scanline} * row_bytes;
    jpeg_read_scanlines(cinfo, &row, 1);
  }
  jpeg_finish_decompress(cinfo);
  return true;
}

struct JpegDecoder {
  jpeg_decompress_struct cinfo;
  JpegErrorManager err;
  jpeg_progress_mgr progress;
  JpegDecoder() {
    std::memset(&cinfo, 0, sizeof(cinfo));
    std::memset(&progress, 0, sizeof(progress));
    InstallErrorManager(&err);
    cinfo.err = &err.mgr;
    jpeg_create_decompress(&cinfo);  // cannot fail except on a library version mismatch
  }
  ~JpegDecoder() { jpeg_destroy_decompress(&cinfo); }
};

StatusOr<JpegHeader> ParseHeader(JpegDecoder& decoder, const uint8_t* data, size_t size, const std::string& what) {
  if (size < 3 || data[0] != 0xFF || data[1] != 0xD8 || data[2] != 0xFF) {
    return MakeError(StatusCode::kBadMagic, what, ": not a JPEG file (no SOI marker)");
  }
  JpegHeader header;
  if (!ReadJpegHeader(&decoder.cinfo, &decoder.err, &decoder.progress, data, size, &header)) {
    return MakeError(StatusCode::kCorrupt, what, ": JPEG header: ", decoder.err.message);
  }
  ATEX_RETURN_IF_ERROR(CheckDimensions(header.width, header.height, what));
  if (header.components != 1 && header.components != 3) {
    return MakeError(StatusCode::kUnsupported, what, ": JPEG with ", header.components,
                     " components (CMYK/YCCK are not supported)");
  }
  return header;
}

}  // namespace

StatusOr<ImageInfo> JpegInfo(const uint8_t* data, size_t size, const std::string& what) {
  JpegDecoder decoder;
  ATEX_ASSIGN_OR_RETURN(const JpegHeader header, ParseHeader(decoder, data, size, what));
  ImageInfo info;
  info.width = header.width;
  info.height = header.height;
  info.channels = header.components;
  info.bit_depth = 8;
  info.format = ImageFormat::kJpeg;
  return info;
}

StatusOr<Image> DecodeJpeg(const uint8_t* data, size_t size, const std::string& what) {
  JpegDecoder decoder;
  ATEX_ASSIGN_OR_RETURN(const JpegHeader header, ParseHeader(decoder, data, size, what));
  const uint64_t pixels = uint64_t(header.width) * uint64_t(header.height);
  if (pixels > kAlwaysAllowedPixels && pixels / kMaxPixelsPerByte > size) {
    return MakeError(StatusCode::kCorrupt, what, ": a ", header.width, "x", header.height,
                     " JPEG cannot be stored in ", size, " bytes (forged dimensions)");
  }
  const int channels = header.components;
  const size_t row_bytes = size_t(header.width) * channels;
  std::vector<uint8_t> samples;  // [height][width][channels]
  try {
    samples.resize(row_bytes * header.height);
  } catch (const std::bad_alloc&) {
    return MakeError(StatusCode::kLimitExceeded, what, ": out of memory for a ", header.width, "x", header.height,
                     " JPEG");
  }
  if (!ReadJpegPixels(&decoder.cinfo, &decoder.err, samples.data(), row_bytes, channels)) {
    return MakeError(StatusCode::kCorrupt, what, ": JPEG data: ", decoder.err.message);
  }
  Image image(header.width, header.height, channels);
  for (size_t i = 0; i < samples.size(); ++i) image.pixels[i] = samples[i] * (1.0f / 255.0f);
  return image;
}

namespace {

bool WriteJpeg(jpeg_compress_struct* cinfo, JpegErrorManager* err, const uint8_t* samples, int width, int height,
               int components, int quality, unsigned char** out, unsigned long* out_size) {
  if (setjmp(err->jump)) return false;
  jpeg_mem_dest(cinfo, out, out_size);
  cinfo->image_width = static_cast<JDIMENSION>(width);
  cinfo->image_height = static_cast<JDIMENSION>(height);
  cinfo->input_components = components;
  cinfo->in_color_space = components == 1 ? JCS_GRAYSCALE : JCS_RGB;
  jpeg_set_defaults(cinfo);
  jpeg_set_quality(cinfo, quality, TRUE);
  jpeg_start_compress(cinfo, TRUE);
  const size_t row_bytes = size_t(width) * components;
  while (cinfo->next_scanline < cinfo->image_height) {
    JSAMPROW row = const_cast<uint8_t*>(samples) + size_t{cinfo->next_scanline} * row_bytes;
    jpeg_write_scanlines(cinfo, &row, 1);
  }
  jpeg_finish_compress(cinfo);
  return true;
}

}  // namespace

StatusOr<std::vector<uint8_t>> EncodeJpeg(const Image& image, int quality) {
  if (image.channels != 1 && image.channels != 3 && image.channels != 4) {
    return MakeError(StatusCode::kInvalidArgument, "JPEG encoding of a ", image.channels, "-channel image");
  }
  if (quality < 1 || quality > 100) {
    return MakeError(StatusCode::kInvalidArgument, "JPEG quality ", quality, " (1..100)");
  }
  ATEX_RETURN_IF_ERROR(CheckDimensions(image.width, image.height, "JPEG encoding"));
  if (image.width > 65500 || image.height > 65500) {
    return MakeError(StatusCode::kInvalidArgument, "JPEG cannot store ", image.width, "x", image.height);
  }
  const int components = image.channels == 1 ? 1 : 3;  // alpha is dropped
  const size_t pixel_count = size_t(image.width) * image.height;
  std::vector<uint8_t> samples(pixel_count * components);  // [height][width][components]
  for (size_t p = 0; p < pixel_count; ++p) {
    for (int c = 0; c < components; ++c) {
      samples[p * components + c] = static_cast<uint8_t>(ToLevel(image.pixels[p * image.channels + c], 255));
    }
  }
  jpeg_compress_struct cinfo;
  JpegErrorManager err;
  std::memset(&cinfo, 0, sizeof(cinfo));
  InstallErrorManager(&err);
  cinfo.err = &err.mgr;
  jpeg_create_compress(&cinfo);
  unsigned char* buffer = nullptr;  // malloc'ed by libjpeg
  unsigned long buffer_size = 0;
  const bool ok = WriteJpeg(&cinfo, &err, samples.data(), image.width, image.height, components, quality, &buffer,
                            &buffer_size);
  jpeg_destroy_compress(&cinfo);
  std::vector<uint8_t> out;
  if (ok && buffer) out.assign(buffer, buffer + buffer_size);
  std::free(buffer);
  if (!ok) return MakeError(StatusCode::kInternal, "JPEG encoding: ", err.message);
  return out;
}

}  // namespace atex::image_detail
