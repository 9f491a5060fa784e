// EXR through OpenEXR (when built in). OpenEXR reports errors by exceptions,
// which are caught here and turned into Status values.
#include "data/image_codecs.h"

#ifdef ATEX_HAVE_OPENEXR
#include <Imath/half.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIO.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>

#include <algorithm>
#include <cstring>
#include <exception>
#include <new>
#include <stdexcept>
#endif

namespace atex::image_detail {

#ifndef ATEX_HAVE_OPENEXR

bool ExrSupported() { return false; }
StatusOr<Image> DecodeExr(const uint8_t*, size_t, const std::string& what) {
  return MakeError(StatusCode::kUnsupportedCodec, what, ": EXR support is not built in (OpenEXR not found)");
}
StatusOr<ImageInfo> ExrInfo(const uint8_t*, size_t, const std::string& what) {
  return MakeError(StatusCode::kUnsupportedCodec, what, ": EXR support is not built in (OpenEXR not found)");
}
StatusOr<std::vector<uint8_t>> EncodeExr(const Image&) {
  return MakeError(StatusCode::kUnsupportedCodec, "EXR support is not built in (OpenEXR not found)");
}

#else

namespace {

constexpr uint64_t kMaxExrRatio = 4096;

class MemoryInput : public Imf::IStream {
 public:
  MemoryInput(const uint8_t* data, size_t size, const std::string& what)
      : Imf::IStream(what.c_str()), data_(data), size_(size) {}
  bool read(char c[], int n) override {
    if (n < 0 || static_cast<uint64_t>(n) > size_ - std::min<uint64_t>(pos_, size_)) {
      throw std::runtime_error("unexpected end of file");
    }
    std::memcpy(c, data_ + pos_, static_cast<size_t>(n));
    pos_ += static_cast<uint64_t>(n);
    return pos_ < size_;
  }
  uint64_t tellg() override { return pos_; }
  void seekg(uint64_t pos) override { pos_ = pos; }  // checked by read()

 private:
  const uint8_t* data_;  // [size_]
  uint64_t size_;
  uint64_t pos_ = 0;
};

class MemoryOutput : public Imf::OStream {
 public:
  explicit MemoryOutput(std::vector<uint8_t>* out) : Imf::OStream("memory"), out_(out) {}
  void write(const char c[], int n) override {
    if (pos_ + n > out_->size()) out_->resize(pos_ + n);
    std::memcpy(out_->data() + pos_, c, static_cast<size_t>(n));
    pos_ += static_cast<uint64_t>(n);
  }
  uint64_t tellp() override { return pos_; }
  void seekp(uint64_t pos) override { pos_ = pos; }

 private:
  std::vector<uint8_t>* out_;
  uint64_t pos_ = 0;
};

// The data window and channel count, read without OpenEXR before it sees the
// bytes: OpenEXR sizes attribute buffers and line buffers from the header, so a
// forged size would allocate before failing. Attributes are "name\0type\0",
// int32 size, value; the header ends at an empty name. Every attribute must lie
// inside the file. Multi-part and deep files are refused.
struct ExrHeaderScan {
  int64_t width = 0, height = 0;
  int channels = 0;
};

StatusOr<ExrHeaderScan> ScanExrHeader(const uint8_t* data, size_t size, const std::string& what) {
  if (size < 8) return MakeError(StatusCode::kTruncated, what, ": EXR header truncated");
  const uint32_t flags = uint32_t{data[5]} << 8 | uint32_t{data[6]} << 16;
  if (flags & (0x800u | 0x1000u)) {
    return MakeError(StatusCode::kUnsupported, what, ": multi-part and deep EXR files are not supported");
  }
  size_t pos = 8;  // magic + version
  ExrHeaderScan scan;
  bool have_window = false;
  auto read_string = [&](std::string* s) {
    const size_t start = pos;
    while (pos < size && pos - start < 256 && data[pos] != 0) ++pos;
    if (pos >= size || data[pos] != 0) return false;
    s->assign(reinterpret_cast<const char*>(data + start), pos - start);
    ++pos;
    return true;
  };
  auto load32 = [&](size_t at) {
    return static_cast<int32_t>(uint32_t{data[at]} | uint32_t{data[at + 1]} << 8 | uint32_t{data[at + 2]} << 16 |
                                uint32_t{data[at + 3]} << 24);
  };
  while (true) {
    const size_t attribute_at = pos;
    std::string name, type;
    if (!read_string(&name)) {
      return MakeError(StatusCode::kCorrupt, what, ": EXR attribute name at byte ", attribute_at, " is unterminated");
    }
    if (name.empty()) break;
    if (!read_string(&type) || size - pos < 4) {
      return MakeError(StatusCode::kTruncated, what, ": EXR attribute '", name, "' at byte ", attribute_at,
                       " truncated");
    }
    const int32_t length = load32(pos);
    pos += 4;
    if (length < 0 || static_cast<size_t>(length) > size - pos) {
      return MakeError(StatusCode::kTruncated, what, ": EXR attribute '", name, "' at byte ", attribute_at, " claims ",
                       length, " bytes, ", size - pos, " remain");
    }
    if (name == "dataWindow" && type == "box2i" && length == 16) {
      scan.width = int64_t{load32(pos + 8)} - load32(pos) + 1;
      scan.height = int64_t{load32(pos + 12)} - load32(pos + 4) + 1;
      have_window = true;
    } else if (name == "channels" && type == "chlist") {
      // Entries: name\0 then 16 bytes (type, pLinear + reserved, xSampling, ySampling); a final \0.
      size_t p = pos;
      const size_t end = pos + length;
      while (p < end && data[p] != 0) {
        while (p < end && data[p] != 0) ++p;
        p += 1 + 16;
        ++scan.channels;
      }
    }
    pos += length;
  }
  if (!have_window) return MakeError(StatusCode::kCorrupt, what, ": EXR header has no box2i dataWindow");
  ATEX_RETURN_IF_ERROR(CheckDimensions(scan.width, scan.height, what));
  // Refuse images far larger than the file can plausibly hold (the lossless
  // codecs are deflate/RLE based; 4096:1 leaves room for flat lossy images).
  const uint64_t raw_bytes = uint64_t(scan.width) * uint64_t(scan.height) * std::max(scan.channels, 1) * 2;
  if (raw_bytes > (uint64_t{1} << 22) && raw_bytes / kMaxExrRatio > size) {
    return MakeError(StatusCode::kCorrupt, what, ": a ", scan.width, "x", scan.height, " EXR cannot be stored in ",
                     size, " bytes (forged dimensions)");
  }
  return scan;
}

bool IsExr(const uint8_t* data, size_t size) {
  return size >= 4 && data[0] == 0x76 && data[1] == 0x2f && data[2] == 0x31 && data[3] == 0x01;
}

// Which file channels fill which output slots.
struct ChannelPlan {
  int out_channels = 0;
  std::vector<std::pair<std::string, int>> reads;  // (file channel, output slot)
  bool replicate_grey = false;                     // Y + A -> copy slot 0 into 1 and 2
};

StatusOr<ChannelPlan> PlanChannels(const Imf::Header& header, const std::string& what) {
  const Imf::ChannelList& channels = header.channels();
  for (auto it = channels.begin(); it != channels.end(); ++it) {
    if (it.channel().xSampling != 1 || it.channel().ySampling != 1) {
      return MakeError(StatusCode::kUnsupported, what, ": EXR channel '", it.name(), "' is subsampled");
    }
  }
  auto has = [&](const char* name) { return channels.findChannel(name) != nullptr; };
  ChannelPlan plan;
  if (has("R") || has("G") || has("B")) {
    plan.out_channels = has("A") ? 4 : 3;
    const char* names[] = {"R", "G", "B", "A"};
    for (int c = 0; c < plan.out_channels; ++c) {
      if (has(names[c])) plan.reads.push_back({names[c], c});
    }
  } else if (has("Y")) {
    plan.out_channels = has("A") ? 4 : 1;
    plan.reads.push_back({"Y", 0});
    if (has("A")) {
      plan.reads.push_back({"A", 3});
      plan.replicate_grey = true;
    }
  } else if (channels.begin() != channels.end() && ++channels.begin() == channels.end()) {
    plan.out_channels = 1;  // a single channel of another name (depth, mask, ...)
    plan.reads.push_back({channels.begin().name(), 0});
  } else {
    return MakeError(StatusCode::kUnsupported, what, ": EXR without R/G/B or Y channels");
  }
  return plan;
}

}  // namespace

bool ExrSupported() { return true; }

StatusOr<ImageInfo> ExrInfo(const uint8_t* data, size_t size, const std::string& what) {
  if (!IsExr(data, size)) return MakeError(StatusCode::kBadMagic, what, ": not an EXR file");
  ATEX_RETURN_IF_ERROR(ScanExrHeader(data, size, what).status());
  try {
    MemoryInput stream(data, size, what);
    Imf::InputFile file(stream);
    const Imath::Box2i window = file.header().dataWindow();
    const int64_t width = int64_t{window.max.x} - window.min.x + 1;
    const int64_t height = int64_t{window.max.y} - window.min.y + 1;
    ATEX_RETURN_IF_ERROR(CheckDimensions(width, height, what));
    ATEX_ASSIGN_OR_RETURN(const ChannelPlan plan, PlanChannels(file.header(), what));
    ImageInfo info;
    info.width = static_cast<int>(width);
    info.height = static_cast<int>(height);
    info.channels = plan.out_channels;
    const Imf::Channel* first = file.header().channels().findChannel(plan.reads[0].first);
    info.bit_depth = first && first->type == Imf::HALF ? 16 : 32;
    info.format = ImageFormat::kExr;
    return info;
  } catch (const std::exception& e) {
    return MakeError(StatusCode::kCorrupt, what, ": EXR header: ", e.what());
  }
}

StatusOr<Image> DecodeExr(const uint8_t* data, size_t size, const std::string& what) {
  if (!IsExr(data, size)) return MakeError(StatusCode::kBadMagic, what, ": not an EXR file");
  ATEX_RETURN_IF_ERROR(ScanExrHeader(data, size, what).status());
  try {
    MemoryInput stream(data, size, what);
    Imf::InputFile file(stream);
    const Imath::Box2i window = file.header().dataWindow();
    const int64_t width = int64_t{window.max.x} - window.min.x + 1;
    const int64_t height = int64_t{window.max.y} - window.min.y + 1;
    ATEX_RETURN_IF_ERROR(CheckDimensions(width, height, what));
    ATEX_ASSIGN_OR_RETURN(const ChannelPlan plan, PlanChannels(file.header(), what));
    const uint64_t raw_bytes = uint64_t(width) * uint64_t(height) * plan.reads.size() * 2;
    if (raw_bytes > (uint64_t{1} << 22) && raw_bytes / kMaxExrRatio > size) {
      return MakeError(StatusCode::kCorrupt, what, ": a ", width, "x", height, " EXR cannot be stored in ", size,
                       " bytes (forged dimensions)");
    }
    Image image(static_cast<int>(width), static_cast<int>(height), plan.out_channels);
    const size_t x_stride = sizeof(float) * plan.out_channels;
    const size_t y_stride = x_stride * static_cast<size_t>(width);
    Imf::FrameBuffer frame;
    for (const auto& [name, slot] : plan.reads) {
      frame.insert(name, Imf::Slice::Make(Imf::FLOAT, image.pixels.data() + slot, window, x_stride, y_stride));
    }
    file.setFrameBuffer(frame);
    file.readPixels(window.min.y, window.max.y);
    if (plan.replicate_grey) {
      for (size_t p = 0; p < size_t(width) * height; ++p) {
        image.pixels[p * 4 + 1] = image.pixels[p * 4 + 2] = image.pixels[p * 4];
      }
    }
    return image;
  } catch (const std::bad_alloc&) {
    return MakeError(StatusCode::kLimitExceeded, what, ": out of memory decoding EXR");
  } catch (const std::exception& e) {
    return MakeError(StatusCode::kCorrupt, what, ": EXR: ", e.what());
  }
}

StatusOr<std::vector<uint8_t>> EncodeExr(const Image& image) {
  if (image.channels != 1 && image.channels != 3 && image.channels != 4) {
    return MakeError(StatusCode::kInvalidArgument, "EXR encoding of a ", image.channels, "-channel image");
  }
  ATEX_RETURN_IF_ERROR(CheckDimensions(image.width, image.height, "EXR encoding"));
  try {
    std::vector<half> halves(image.pixels.size());  // [height][width][channels]
    for (size_t i = 0; i < halves.size(); ++i) halves[i] = half(image.pixels[i]);
    Imf::Header header(image.width, image.height);
    header.compression() = Imf::ZIP_COMPRESSION;
    const char* rgba[] = {"R", "G", "B", "A"};
    const char* grey[] = {"Y"};
    const char** names = image.channels == 1 ? grey : rgba;
    Imf::FrameBuffer frame;
    const size_t x_stride = sizeof(half) * image.channels;
    for (int c = 0; c < image.channels; ++c) {
      header.channels().insert(names[c], Imf::Channel(Imf::HALF));
      frame.insert(names[c], Imf::Slice(Imf::HALF, reinterpret_cast<char*>(halves.data() + c), x_stride,
                                        x_stride * image.width));
    }
    std::vector<uint8_t> out;
    {
      MemoryOutput stream(&out);
      Imf::OutputFile file(stream, header);
      file.setFrameBuffer(frame);
      file.writePixels(image.height);
    }
    return out;
  } catch (const std::exception& e) {
    return MakeError(StatusCode::kInternal, "EXR encoding: ", e.what());
  }
}

#endif  // ATEX_HAVE_OPENEXR

}  // namespace atex::image_detail
