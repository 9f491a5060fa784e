// PNG through libpng. libpng reports errors by longjmp; the functions that call
// setjmp hold no C++ objects with destructors, so the jump never skips one
// (C++ [csetjmp.syn]); buffers live in the caller and are sized before libpng
// writes into them.
#include <png.h>

#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <new>

#include "data/image_codecs.h"

namespace atex::image_detail {
namespace {

constexpr uint64_t kMaxDeflateRatio = 1032;  // deflate cannot expand more than ~1032:1

struct PngIo {
  const uint8_t* data = nullptr;  // [size] (reading)
  size_t size = 0;
  size_t pos = 0;
  std::vector<uint8_t>* out = nullptr;  // (writing)
  bool out_of_memory = false;
  char message[200] = {0};
};

void OnPngError(png_structp png, png_const_charp message) {
  auto* io = static_cast<PngIo*>(png_get_error_ptr(png));
  std::snprintf(io->message, sizeof(io->message), "%s", message ? message : "libpng error");
  png_longjmp(png, 1);
}
void OnPngWarning(png_structp, png_const_charp) {}  // never print; ancillary problems are ignored

void OnPngRead(png_structp png, png_bytep out, size_t n) {
  auto* io = static_cast<PngIo*>(png_get_io_ptr(png));
  if (n > io->size - io->pos) png_error(png, "file truncated");
  std::memcpy(out, io->data + io->pos, n);
  io->pos += n;
}

void OnPngWrite(png_structp png, png_bytep data, size_t n) {
  auto* io = static_cast<PngIo*>(png_get_io_ptr(png));
  try {
    io->out->insert(io->out->end(), data, data + n);
  } catch (const std::bad_alloc&) {
    io->out_of_memory = true;
    png_error(png, "out of memory");
  }
}
void OnPngFlush(png_structp) {}

// Header after the expand/gray-alpha transforms we apply.
struct PngLayout {
  uint32_t width = 0, height = 0;
  int bit_depth = 0;         // 8 or 16 after expansion
  int channels = 0;          // 1..4 after expansion (2 = grey + alpha)
  size_t rowbytes = 0;       // bytes per decoded row
  uint64_t raw_bytes = 0;    // filtered, uncompressed size of the stored image data (before expansion)
};

// Reads the chunks up to the image data (no row buffers yet). Returns false after a libpng error.
bool ReadPngHeader(png_structp png, png_infop info, PngIo* io, PngLayout* layout) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_set_read_fn(png, io, OnPngRead);
  png_set_user_limits(png, 0x7fffffff, 0x7fffffff);  // CheckDimensions applies our (smaller) limits
  png_read_info(png, info);
  layout->width = png_get_image_width(png, info);
  layout->height = png_get_image_height(png, info);
  const int stored_depth = png_get_bit_depth(png, info);
  const int stored_channels = png_get_channels(png, info);
  const uint64_t bits_per_row = uint64_t{layout->width} * stored_depth * stored_channels;
  layout->raw_bytes = uint64_t{layout->height} * ((bits_per_row + 7) / 8 + 1);
  return true;
}

// Sets up the transforms (libpng allocates its row buffers here, so the
// dimensions must have been checked). Returns false after a libpng error.
bool SetPngTransforms(png_structp png, png_infop info, PngLayout* layout) {
  if (setjmp(png_jmpbuf(png))) return false;
  const int stored_depth = png_get_bit_depth(png, info);
  png_set_expand(png);  // palette -> RGB(A), grey < 8 bits -> 8 bits, tRNS -> alpha
  if (stored_depth == 16) png_set_swap(png);  // big-endian in the file -> host order (little-endian)
  png_set_interlace_handling(png);
  png_read_update_info(png, info);
  layout->bit_depth = png_get_bit_depth(png, info);
  layout->channels = png_get_channels(png, info);
  layout->rowbytes = png_get_rowbytes(png, info);
  return true;
}

bool ReadPngRows(png_structp png, png_infop info, png_bytep* rows) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_read_image(png, rows);
  png_read_end(png, nullptr);
  return true;
}

struct PngReader {
  PngIo io;
  png_structp png = nullptr;
  png_infop info = nullptr;
  PngReader(const uint8_t* data, size_t size) {
    io.data = data;
    io.size = size;
    png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &io, OnPngError, OnPngWarning);
    if (png) info = png_create_info_struct(png);
  }
  ~PngReader() {
    if (png) png_destroy_read_struct(&png, info ? &info : nullptr, nullptr);
  }
};

Status CheckPngSignature(const uint8_t* data, size_t size, const std::string& what) {
  if (size < 8 || png_sig_cmp(data, 0, 8) != 0) {
    return MakeError(StatusCode::kBadMagic, what, ": not a PNG file (bad signature)");
  }
  return Status::Ok();
}

}  // namespace

StatusOr<ImageInfo> PngInfo(const uint8_t* data, size_t size, const std::string& what) {
  ATEX_RETURN_IF_ERROR(CheckPngSignature(data, size, what));
  PngReader reader(data, size);
  if (!reader.info) return MakeError(StatusCode::kInternal, what, ": libpng initialisation failed");
  PngLayout layout;
  if (!ReadPngHeader(reader.png, reader.info, &reader.io, &layout)) {
    return MakeError(StatusCode::kCorrupt, what, ": PNG header: ", reader.io.message, " (at byte ", reader.io.pos, ")");
  }
  ATEX_RETURN_IF_ERROR(CheckDimensions(layout.width, layout.height, what));
  const int color_type = png_get_color_type(reader.png, reader.info);
  const bool has_alpha = (color_type & PNG_COLOR_MASK_ALPHA) || png_get_valid(reader.png, reader.info, PNG_INFO_tRNS);
  const bool colour = (color_type & PNG_COLOR_MASK_COLOR) || color_type == PNG_COLOR_TYPE_PALETTE;
  ImageInfo result;
  result.width = static_cast<int>(layout.width);
  result.height = static_cast<int>(layout.height);
  result.channels = has_alpha ? 4 : colour ? 3 : 1;
  result.bit_depth = png_get_bit_depth(reader.png, reader.info) == 16 ? 16 : 8;
  result.format = ImageFormat::kPng;
  return result;
}

StatusOr<Image> DecodePng(const uint8_t* data, size_t size, const std::string& what) {
  ATEX_RETURN_IF_ERROR(CheckPngSignature(data, size, what));
  PngReader reader(data, size);
  if (!reader.info) return MakeError(StatusCode::kInternal, what, ": libpng initialisation failed");
  PngLayout layout;
  if (!ReadPngHeader(reader.png, reader.info, &reader.io, &layout)) {
    return MakeError(StatusCode::kCorrupt, what, ": PNG header: ", reader.io.message, " (at byte ", reader.io.pos, ")");
  }
  ATEX_RETURN_IF_ERROR(CheckDimensions(layout.width, layout.height, what));
  if (layout.raw_bytes / kMaxDeflateRatio > size) {
    return MakeError(StatusCode::kCorrupt, what, ": a ", layout.width, "x", layout.height,
                     " PNG cannot be stored in ", size, " bytes (forged dimensions)");
  }
  if (!SetPngTransforms(reader.png, reader.info, &layout)) {
    return MakeError(StatusCode::kCorrupt, what, ": PNG header: ", reader.io.message, " (at byte ", reader.io.pos, ")");
  }
  if (layout.channels < 1 || layout.channels > 4 || (layout.bit_depth != 8 && layout.bit_depth != 16) ||
      layout.rowbytes != size_t{layout.width} * layout.channels * (layout.bit_depth / 8)) {
    return MakeError(StatusCode::kInternal, what, ": unexpected PNG layout after expansion (", layout.channels,
                     " channels, ", layout.bit_depth, " bits)");
  }
  std::vector<uint8_t> raw;       // [height][rowbytes]
  std::vector<png_bytep> rows;    // [height]
  try {
    raw.resize(layout.rowbytes * layout.height);
    rows.resize(layout.height);
  } catch (const std::bad_alloc&) {
    return MakeError(StatusCode::kLimitExceeded, what, ": out of memory for a ", layout.width, "x", layout.height,
                     " PNG");
  }
  for (uint32_t y = 0; y < layout.height; ++y) rows[y] = raw.data() + size_t{y} * layout.rowbytes;
  if (!ReadPngRows(reader.png, reader.info, rows.data())) {
    return MakeError(StatusCode::kCorrupt, what, ": PNG data: ", reader.io.message, " (at byte ", reader.io.pos, ")");
  }

  const int out_channels = layout.channels == 2 ? 4 : layout.channels;
  Image image(static_cast<int>(layout.width), static_cast<int>(layout.height), out_channels);
  const size_t pixel_count = size_t{layout.width} * layout.height;
  const float scale = layout.bit_depth == 16 ? 1.0f / 65535.0f : 1.0f / 255.0f;
  for (size_t p = 0; p < pixel_count; ++p) {
    float sample[4];
    for (int c = 0; c < layout.channels; ++c) {
      const size_t index = p * layout.channels + c;
      uint32_t level;
      if (layout.bit_depth == 16) {
        uint16_t v;
        std::memcpy(&v, raw.data() + 2 * index, 2);
        level = v;
      } else {
        level = raw[index];
      }
      sample[c] = static_cast<float>(level) * scale;
    }
    float* out = image.pixels.data() + p * out_channels;
    if (layout.channels == 2) {  // grey + alpha -> RGBA
      out[0] = out[1] = out[2] = sample[0];
      out[3] = sample[1];
    } else {
      for (int c = 0; c < layout.channels; ++c) out[c] = sample[c];
    }
  }
  return image;
}

namespace {

bool WritePngRows(png_structp png, png_infop info, PngIo* io, const PngLayout* layout, png_bytep* rows) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_set_write_fn(png, io, OnPngWrite, OnPngFlush);
  const int color_type = layout->channels == 1   ? PNG_COLOR_TYPE_GRAY
                         : layout->channels == 3 ? PNG_COLOR_TYPE_RGB
                                                 : PNG_COLOR_TYPE_RGB_ALPHA;
  png_set_IHDR(png, info, layout->width, layout->height, layout->bit_depth, color_type, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  if (layout->bit_depth == 16) png_set_swap(png);  // host (little-endian) -> big-endian file order
  png_write_image(png, rows);
  png_write_end(png, nullptr);
  return true;
}

}  // namespace

StatusOr<std::vector<uint8_t>> EncodePng(const Image& image, int bit_depth) {
  if (bit_depth != 8 && bit_depth != 16) {
    return MakeError(StatusCode::kInvalidArgument, "PNG bit depth ", bit_depth, " (8 or 16)");
  }
  if (image.channels != 1 && image.channels != 3 && image.channels != 4) {
    return MakeError(StatusCode::kInvalidArgument, "PNG encoding of a ", image.channels, "-channel image (1, 3 or 4)");
  }
  ATEX_RETURN_IF_ERROR(CheckDimensions(image.width, image.height, "PNG encoding"));
  PngLayout layout;
  layout.width = static_cast<uint32_t>(image.width);
  layout.height = static_cast<uint32_t>(image.height);
  layout.bit_depth = bit_depth;
  layout.channels = image.channels;
  layout.rowbytes = size_t{layout.width} * layout.channels * (bit_depth / 8);
  std::vector<uint8_t> raw(layout.rowbytes * layout.height);  // [height][rowbytes]
  std::vector<png_bytep> rows(layout.height);                 // [height]
  const uint32_t max_level = bit_depth == 16 ? 65535 : 255;
  for (size_t i = 0; i < image.pixels.size(); ++i) {
    const uint32_t level = ToLevel(image.pixels[i], max_level);
    if (bit_depth == 16) {
      const uint16_t v = static_cast<uint16_t>(level);
      std::memcpy(raw.data() + 2 * i, &v, 2);
    } else {
      raw[i] = static_cast<uint8_t>(level);
    }
  }
  for (uint32_t y = 0; y < layout.height; ++y) rows[y] = raw.data() + size_t{y} * layout.rowbytes;

  std::vector<uint8_t> out;
  PngIo io;
  io.out = &out;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &io, OnPngError, OnPngWarning);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!info) {
    if (png) png_destroy_write_struct(&png, nullptr);
    return MakeError(StatusCode::kInternal, "PNG encoding: libpng initialisation failed");
  }
  const bool ok = WritePngRows(png, info, &io, &layout, rows.data());
  png_destroy_write_struct(&png, &info);
  if (!ok) {
    return MakeError(io.out_of_memory ? StatusCode::kLimitExceeded : StatusCode::kInternal, "PNG encoding: ",
                     io.message);
  }
  return out;
}

}  // namespace atex::image_detail
