#include "exr/exr_image.h"

#include <algorithm>
#include <cstring>
#include <exception>
#include <limits>
#include <string>

#include <Imath/half.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIO.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStdIO.h>

#include "atex/image.h"  // ImageInfoFromBytes

namespace atex::converters::exr {

namespace {

constexpr const char* kChannels[4] = {"R", "G", "B", "A"};

// A read-only OpenEXR input stream over bytes in memory (no copy).
class MemoryIStream : public Imf::IStream {
 public:
  MemoryIStream(const uint8_t* data, size_t size) : Imf::IStream("<memory>"), data_(data), size_(size) {}

  bool read(char c[], int n) override {
    if (n < 0 || static_cast<uint64_t>(n) > size_ - pos_) {
      throw std::runtime_error("EXR data ends at byte " + std::to_string(size_) + " (read of " + std::to_string(n) +
                               " bytes at " + std::to_string(pos_) + ")");
    }
    std::memcpy(c, data_ + pos_, static_cast<size_t>(n));
    pos_ += static_cast<uint64_t>(n);
    return pos_ < size_;
  }
  uint64_t tellg() override { return pos_; }
  void seekg(uint64_t pos) override { pos_ = std::min<uint64_t>(pos, size_); }
  void clear() override {}

 private:
  const uint8_t* data_;
  uint64_t size_;
  uint64_t pos_ = 0;
};

Imf::FrameBuffer RgbaFrameBuffer(uint16_t* rgba, int x0, int y0, int width) {
  Imf::FrameBuffer frame;
  const size_t x_stride = 4 * sizeof(uint16_t);
  const size_t y_stride = x_stride * static_cast<size_t>(width);
  // OpenEXR addresses pixel (x, y) as base + x * xStride + y * yStride with data-window
  // coordinates; shift the base so that the window's corner lands on rgba[0].
  char* base = reinterpret_cast<char*>(rgba) - static_cast<ptrdiff_t>(x0) * static_cast<ptrdiff_t>(x_stride) -
               static_cast<ptrdiff_t>(y0) * static_cast<ptrdiff_t>(y_stride);
  for (int c = 0; c < 4; ++c) {
    frame.insert(kChannels[c], Imf::Slice(Imf::HALF, base + c * sizeof(uint16_t), x_stride, y_stride));
  }
  return frame;
}

}  // namespace

uint16_t FloatToHalfBits(float value) { return half(value).bits(); }

float HalfBitsToFloat(uint16_t bits) {
  half h;
  h.setBits(bits);
  return static_cast<float>(h);
}

StatusOr<std::vector<uint8_t>> EncodeHalfImage(const HalfImage& image) {
  if (image.width < 1 || image.height < 1 ||
      image.rgba.size() != static_cast<size_t>(image.width) * image.height * 4) {
    return MakeError(StatusCode::kInvalidArgument, "EXR writer: image ", image.width, " x ", image.height, " with ",
                     image.rgba.size(), " values");
  }
  try {
    Imf::Header header(image.width, image.height);
    header.compression() = Imf::ZIP_COMPRESSION;
    for (const char* name : kChannels) header.channels().insert(name, Imf::Channel(Imf::HALF));
    header.insert("atexAtlasVersion", Imf::IntAttribute(image.atlas_version));
    header.insert("atexAtlasCount", Imf::IntAttribute(static_cast<int>(
                                        std::min<int64_t>(image.atlas_count, std::numeric_limits<int>::max()))));
    Imf::StdOSStream stream;
    {
      Imf::OutputFile file(stream, header);
      file.setFrameBuffer(RgbaFrameBuffer(const_cast<uint16_t*>(image.rgba.data()), 0, 0, image.width));
      file.writePixels(image.height);
    }  // the destructor writes the line offset table: the bytes are complete only now
    const std::string bytes = stream.str();
    return std::vector<uint8_t>(bytes.begin(), bytes.end());
  } catch (const std::exception& e) {
    return MakeError(StatusCode::kInternal, "EXR writer: OpenEXR failed: ", e.what());
  }
}

StatusOr<HalfImage> DecodeHalfImage(const uint8_t* data, size_t size, uint64_t max_pixels) {
  // OpenEXR's magic number, checked here for a clear message.
  if (size < 4 || data[0] != 0x76 || data[1] != 0x2f || data[2] != 0x31 || data[3] != 0x01) {
    return MakeError(StatusCode::kBadMagic, "not an OpenEXR file (magic 76 2f 31 01 missing)");
  }
  // libatex's header scan first: OpenEXR's InputFile sizes its line buffers from the
  // header while it is constructed, so a forged data window must be refused before that.
  ATEX_ASSIGN_OR_RETURN(const ImageInfo info, ImageInfoFromBytes(data, size, "EXR atlas"));
  if (static_cast<uint64_t>(info.width) * static_cast<uint64_t>(info.height) > max_pixels) {
    return MakeError(StatusCode::kLimitExceeded, "EXR data window ", info.width, " x ", info.height,
                     " is above the reader's limit of ", max_pixels, " pixels");
  }
  try {
    MemoryIStream stream(data, size);
    Imf::InputFile file(stream);
    const Imf::Header& header = file.header();
    const Imath::Box2i window = header.dataWindow();
    const int64_t width = int64_t{window.max.x} - window.min.x + 1;
    const int64_t height = int64_t{window.max.y} - window.min.y + 1;
    if (width < 1 || height < 1 || static_cast<uint64_t>(width) * static_cast<uint64_t>(height) > max_pixels) {
      return MakeError(StatusCode::kLimitExceeded, "EXR data window ", width, " x ", height,
                       " is empty or above the reader's limit of ", max_pixels, " pixels");
    }
    for (const char* name : kChannels) {
      if (header.channels().findChannel(name) == nullptr) {
        return MakeError(StatusCode::kCorrupt, "EXR image has no '", name, "' channel (an RGBA atlas needs all four)");
      }
    }
    HalfImage image;
    image.width = static_cast<int>(width);
    image.height = static_cast<int>(height);
    if (const auto* v = header.findTypedAttribute<Imf::IntAttribute>("atexAtlasVersion"))
      image.atlas_version = v->value();
    if (const auto* c = header.findTypedAttribute<Imf::IntAttribute>("atexAtlasCount")) image.atlas_count = c->value();
    image.rgba.assign(static_cast<size_t>(width) * static_cast<size_t>(height) * 4, 0);
    file.setFrameBuffer(RgbaFrameBuffer(image.rgba.data(), window.min.x, window.min.y, image.width));
    file.readPixels(window.min.y, window.max.y);
    return image;
  } catch (const std::exception& e) {
    return MakeError(StatusCode::kCorrupt, "EXR data is invalid: ", e.what());
  } catch (...) {
    return MakeError(StatusCode::kCorrupt, "EXR data is invalid (OpenEXR raised an unknown exception)");
  }
}

}  // namespace atex::converters::exr
