// Image codecs: PNG colour types written directly with libpng (an encoder path
// independent of ours), JPEG and EXR round trips, the real dataset images,
// downscaling, and hostile inputs.
#include <png.h>

#include <cmath>
#include <cstring>
#include <random>

#include <gtest/gtest.h>
#include <zlib.h>

#include "atex/file_io.h"
#include "atex/image.h"
#include "core/test_support.h"

namespace atex {
namespace {

// Writes a PNG with libpng's simple writer loop: rows of raw samples as given.
std::vector<uint8_t> WritePngWithLibpng(int width, int height, int bit_depth, int color_type,
                                        const std::vector<uint8_t>& raw, bool interlace = false,
                                        const std::vector<png_color>& palette = {},
                                        const std::vector<uint8_t>& trns = {}) {
  std::vector<uint8_t> out;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png_create_info_struct(png);
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    ADD_FAILURE() << "libpng write failed";
    return {};
  }
  png_set_write_fn(
      png, &out,
      [](png_structp p, png_bytep data, size_t n) {
        auto* v = static_cast<std::vector<uint8_t>*>(png_get_io_ptr(p));
        v->insert(v->end(), data, data + n);
      },
      nullptr);
  png_set_IHDR(png, info, width, height, bit_depth, color_type, interlace ? PNG_INTERLACE_ADAM7 : PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  if (!palette.empty()) png_set_PLTE(png, info, palette.data(), static_cast<int>(palette.size()));
  if (!trns.empty()) png_set_tRNS(png, info, trns.data(), static_cast<int>(trns.size()), nullptr);
  png_write_info(png, info);
  const size_t rowbytes = raw.size() / height;
  std::vector<png_bytep> rows(height);
  for (int y = 0; y < height; ++y) rows[y] = const_cast<uint8_t*>(raw.data()) + y * rowbytes;
  png_write_image(png, rows.data());
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return out;
}

Image Decode(const std::vector<uint8_t>& bytes) {
  auto image = DecodeImage(bytes.data(), bytes.size(), "test");
  EXPECT_TRUE(image.ok()) << image.status().ToString();
  return image.ok() ? *image : Image();
}

TEST(Png, GreyRgbRgba8Bit) {
  const std::vector<uint8_t> grey = {0, 51, 255, 102, 204, 153};
  Image g = Decode(WritePngWithLibpng(3, 2, 8, PNG_COLOR_TYPE_GRAY, grey));
  ASSERT_EQ(g.channels, 1);
  EXPECT_FLOAT_EQ(g.at(1, 0, 0), 0.2f);
  EXPECT_FLOAT_EQ(g.at(2, 1, 0), 0.6f);
  const std::vector<uint8_t> rgba = {255, 0, 0, 255, 0, 255, 0, 0};
  Image c = Decode(WritePngWithLibpng(2, 1, 8, PNG_COLOR_TYPE_RGB_ALPHA, rgba));
  ASSERT_EQ(c.channels, 4);
  EXPECT_FLOAT_EQ(c.at(0, 0, 0), 1.0f);
  EXPECT_FLOAT_EQ(c.at(1, 0, 1), 1.0f);
  EXPECT_FLOAT_EQ(c.at(1, 0, 3), 0.0f);
}

TEST(Png, SixteenBitIsPreciseAndBigEndian) {
  // Samples 0x1234 and 0xFFFF, stored big-endian in the file.
  const std::vector<uint8_t> raw = {0x12, 0x34, 0xFF, 0xFF, 0x00, 0x01};
  Image image = Decode(WritePngWithLibpng(1, 1, 16, PNG_COLOR_TYPE_RGB, raw));
  ASSERT_EQ(image.channels, 3);
  EXPECT_FLOAT_EQ(image.at(0, 0, 0), 0x1234 / 65535.0f);
  EXPECT_FLOAT_EQ(image.at(0, 0, 1), 1.0f);
  EXPECT_FLOAT_EQ(image.at(0, 0, 2), 1 / 65535.0f);
}

TEST(Png, PaletteWithTransparencyAndOneBitGrey) {
  const std::vector<png_color> palette = {{10, 20, 30}, {200, 100, 50}};
  const std::vector<uint8_t> trns = {255, 0};  // index 1 fully transparent
  const std::vector<uint8_t> indices = {0, 1, 1, 0};
  Image p = Decode(WritePngWithLibpng(2, 2, 8, PNG_COLOR_TYPE_PALETTE, indices, false, palette, trns));
  ASSERT_EQ(p.channels, 4);
  EXPECT_FLOAT_EQ(p.at(0, 0, 0), 10 / 255.0f);
  EXPECT_FLOAT_EQ(p.at(1, 0, 0), 200 / 255.0f);
  EXPECT_FLOAT_EQ(p.at(1, 0, 3), 0.0f);
  EXPECT_FLOAT_EQ(p.at(0, 0, 3), 1.0f);
  // 1-bit grey, 9 pixels wide (a partial last byte): 1 0 1 0 1 0 1 0 | 1
  const std::vector<uint8_t> bits = {0xAA, 0x80};
  Image m = Decode(WritePngWithLibpng(9, 1, 1, PNG_COLOR_TYPE_GRAY, bits));
  ASSERT_EQ(m.channels, 1);
  for (int x = 0; x < 9; ++x) EXPECT_FLOAT_EQ(m.at(x, 0, 0), x % 2 == 0 ? 1.0f : 0.0f) << x;
}

TEST(Png, GreyAlphaBecomesRgbaAndInterlacedReads) {
  const std::vector<uint8_t> ga = {100, 255, 200, 0};
  Image image = Decode(WritePngWithLibpng(2, 1, 8, PNG_COLOR_TYPE_GRAY_ALPHA, ga));
  ASSERT_EQ(image.channels, 4);
  EXPECT_FLOAT_EQ(image.at(0, 0, 1), 100 / 255.0f);
  EXPECT_FLOAT_EQ(image.at(1, 0, 3), 0.0f);
  std::vector<uint8_t> rgb(17 * 11 * 3);
  for (size_t i = 0; i < rgb.size(); ++i) rgb[i] = static_cast<uint8_t>(i * 7);
  Image inter = Decode(WritePngWithLibpng(17, 11, 8, PNG_COLOR_TYPE_RGB, rgb, true));
  ASSERT_EQ(inter.width, 17);
  for (size_t i = 0; i < rgb.size(); ++i) ASSERT_FLOAT_EQ(inter.pixels[i], rgb[i] / 255.0f) << i;
}

TEST(Png, EncodeRoundTripAndAtomicWrite) {
  testing::TempDir dir;
  Image image(5, 4, 3);
  for (size_t i = 0; i < image.pixels.size(); ++i) image.pixels[i] = float(i % 11) / 10.0f;
  image.pixels[3] = 2.0f;                          // clamped to 1
  image.pixels[4] = -1.0f;                         // clamped to 0
  image.pixels[5] = std::nanf("");                 // NaN -> 0
  const std::string path = (dir / "out.png").string();
  ASSERT_TRUE(WriteImage(path, image).ok());
  auto back = ReadImage(path);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->channels, 3);
  EXPECT_FLOAT_EQ(back->pixels[3], 1.0f);
  EXPECT_FLOAT_EQ(back->pixels[4], 0.0f);
  EXPECT_FLOAT_EQ(back->pixels[5], 0.0f);
  for (size_t i = 6; i < image.pixels.size(); ++i)
    EXPECT_NEAR(back->pixels[i], image.pixels[i], 0.5f / 255 + 1e-6f) << i;
  auto info = ReadImageInfo(path);
  ASSERT_TRUE(info.ok());
  EXPECT_EQ(info->width, 5);
  EXPECT_EQ(info->height, 4);
  EXPECT_EQ(info->format, ImageFormat::kPng);
  // 16-bit keeps more precision.
  ImageEncodeOptions options;
  options.png_bit_depth = 16;
  auto bytes16 = EncodeImage(image, ImageFormat::kPng, options);
  ASSERT_TRUE(bytes16.ok());
  Image back16 = Decode(*bytes16);
  for (size_t i = 6; i < image.pixels.size(); ++i)
    EXPECT_NEAR(back16.pixels[i], image.pixels[i], 0.5f / 65535 + 1e-6f) << i;
  // Only the final file exists in the folder (the temporary was renamed).
  int files = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir.path())) files += e.is_regular_file() ? 1 : 0;
  EXPECT_EQ(files, 1);
  EXPECT_EQ(WriteImage((dir / "x.bmp").string(), image).code(), StatusCode::kInvalidArgument);
}

TEST(Jpeg, RoundTripIsClose) {
  Image image(32, 24, 3);
  for (int y = 0; y < 24; ++y) {
    for (int x = 0; x < 32; ++x) {
      image.at(x, y, 0) = x / 31.0f;
      image.at(x, y, 1) = y / 23.0f;
      image.at(x, y, 2) = 0.5f;
    }
  }
  auto bytes = EncodeImage(image, ImageFormat::kJpeg);
  ASSERT_TRUE(bytes.ok());
  Image back = Decode(*bytes);
  ASSERT_EQ(back.channels, 3);
  double err = 0;
  for (size_t i = 0; i < image.pixels.size(); ++i) err += std::abs(back.pixels[i] - image.pixels[i]);
  EXPECT_LT(err / image.pixels.size(), 0.02);
  Image grey(16, 8, 1, 0.25f);
  auto g = EncodeImage(grey, ImageFormat::kJpeg);
  ASSERT_TRUE(g.ok());
  EXPECT_EQ(Decode(*g).channels, 1);
}

TEST(Exr, RoundTripWhenBuiltIn) {
  Image image(6, 5, 4);
  for (size_t i = 0; i < image.pixels.size(); ++i) image.pixels[i] = float(i) * 0.25f - 3.0f;  // any range
  auto bytes = EncodeImage(image, ImageFormat::kExr);
  if (!ImageFormatSupported(ImageFormat::kExr)) {
    EXPECT_EQ(bytes.status().code(), StatusCode::kUnsupportedCodec);
    GTEST_SKIP() << "built without OpenEXR";
  }
  ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
  Image back = Decode(*bytes);
  ASSERT_EQ(back.channels, 4);
  ASSERT_EQ(back.width, 6);
  for (size_t i = 0; i < image.pixels.size(); ++i) EXPECT_EQ(back.pixels[i], image.pixels[i]) << i;  // exact in half
  Image grey(3, 2, 1, 0.5f);
  auto g = EncodeImage(grey, ImageFormat::kExr);
  ASSERT_TRUE(g.ok());
  EXPECT_EQ(Decode(*g).channels, 1);
}

TEST(Image, RealDatasetFiles) {
  ATEX_REQUIRE_DATA_FILE(jpg, "panoptic_basketball/ims/0/000000.jpg");
  auto image = ReadImage(jpg.string());
  ASSERT_TRUE(image.ok()) << image.status().ToString();
  EXPECT_EQ(image->width, 640);
  EXPECT_EQ(image->height, 360);
  EXPECT_EQ(image->channels, 3);
  double mean = 0;
  for (float v : image->pixels) mean += v;
  mean /= image->pixels.size();
  EXPECT_GT(mean, 0.05);
  EXPECT_LT(mean, 0.95);
  ATEX_REQUIRE_DATA_FILE(png, "panoptic_basketball/seg/1/000000.png");
  auto mask = ReadImage(png.string());
  ASSERT_TRUE(mask.ok()) << mask.status().ToString();
  EXPECT_EQ(mask->channels, 1);
  size_t ones = 0, others = 0;
  for (float v : mask->pixels) {
    ones += v == 1.0f;
    others += v != 0.0f && v != 1.0f;
  }
  EXPECT_EQ(others, 0u);  // a 1-bit mask expands to exactly 0 and 1
  EXPECT_GT(ones, 100u);
  EXPECT_LT(ones, mask->pixels.size() / 2);
}

TEST(Image, DownscaleBoxFilterAndCrop) {
  Image image(5, 3, 1);
  for (int y = 0; y < 3; ++y) {
    for (int x = 0; x < 5; ++x) image.at(x, y, 0) = float(10 * y + x);
  }
  auto half = DownscaleImage(image, 2);
  ASSERT_TRUE(half.ok());
  ASSERT_EQ(half->width, 2);  // column 4 and row 2 are cropped
  ASSERT_EQ(half->height, 1);
  EXPECT_FLOAT_EQ(half->at(0, 0, 0), (0 + 1 + 10 + 11) / 4.0f);
  EXPECT_FLOAT_EQ(half->at(1, 0, 0), (2 + 3 + 12 + 13) / 4.0f);
  EXPECT_EQ(DownscaleImage(image, 0).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(DownscaleImage(image, 4).status().code(), StatusCode::kInvalidArgument);  // height 3 / 4 = 0
  auto same = DownscaleImage(image, 1);
  ASSERT_TRUE(same.ok());
  EXPECT_EQ(same->pixels, image.pixels);
}

TEST(Image, ToRgbCompositesAlpha) {
  Image rgba(1, 1, 4);
  rgba.pixels = {1.0f, 0.0f, 0.5f, 0.25f};
  const Image rgb = ToRgb(rgba, {0.0f, 1.0f, 1.0f});
  EXPECT_FLOAT_EQ(rgb.pixels[0], 0.25f);
  EXPECT_FLOAT_EQ(rgb.pixels[1], 0.75f);
  EXPECT_FLOAT_EQ(rgb.pixels[2], 0.125f + 0.75f);
  Image grey(1, 1, 1, 0.3f);
  EXPECT_EQ(ToRgb(grey).pixels, (std::vector<float>{0.3f, 0.3f, 0.3f}));
}

// --- hostile inputs -------------------------------------------------------------
uint32_t BigEndian32(const uint8_t* p) { return uint32_t(p[0]) << 24 | p[1] << 16 | p[2] << 8 | p[3]; }
void PutBigEndian32(uint8_t* p, uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<uint8_t>(v >> (24 - 8 * i));
}

// Rewrites the IHDR width/height of a PNG (fixing its CRC so libpng accepts the chunk).
std::vector<uint8_t> ForgePngSize(std::vector<uint8_t> png, uint32_t width, uint32_t height) {
  PutBigEndian32(&png[16], width);
  PutBigEndian32(&png[20], height);
  PutBigEndian32(&png[29], static_cast<uint32_t>(crc32(0, &png[12], 17)));
  EXPECT_EQ(BigEndian32(&png[8]), 13u);
  return png;
}

TEST(ImageHostile, ForgedDimensionsAreRefusedBeforeAllocating) {
  std::vector<uint8_t> rgb(8 * 8 * 3, 128);
  const std::vector<uint8_t> png = WritePngWithLibpng(8, 8, 8, PNG_COLOR_TYPE_RGB, rgb);
  auto huge = ForgePngSize(png, 30000, 30000);  // 900 M pixels: above kMaxImagePixels
  EXPECT_EQ(DecodeImage(huge.data(), huge.size(), "huge").status().code(), StatusCode::kLimitExceeded);
  auto big = ForgePngSize(png, 8000, 8000);  // allowed size, but impossible for ~100 bytes of data
  EXPECT_EQ(DecodeImage(big.data(), big.size(), "big").status().code(), StatusCode::kCorrupt);
  auto zero = ForgePngSize(png, 0, 8);
  EXPECT_FALSE(DecodeImage(zero.data(), zero.size(), "zero").ok());
  // JPEG: a baseline file whose SOF claims 30000x30000.
  auto jpeg = EncodeImage(Image(16, 16, 3, 0.5f), ImageFormat::kJpeg);
  ASSERT_TRUE(jpeg.ok());
  std::vector<uint8_t> j = *jpeg;
  bool patched = false;
  for (size_t i = 2; i + 9 < j.size(); ++i) {
    if (j[i] == 0xFF && j[i + 1] == 0xC0) {  // SOF0: length(2) precision(1) height(2) width(2)
      j[i + 5] = 30000 >> 8;
      j[i + 6] = 30000 & 0xFF;
      j[i + 7] = 30000 >> 8;
      j[i + 8] = 30000 & 0xFF;
      patched = true;
      break;
    }
  }
  ASSERT_TRUE(patched);
  EXPECT_EQ(DecodeImage(j.data(), j.size(), "jpeg").status().code(), StatusCode::kLimitExceeded);
  // 3000x3000 is within the limits but implausible for a file of a few hundred bytes.
  for (size_t i = 2; i + 9 < j.size(); ++i) {
    if (j[i] == 0xFF && j[i + 1] == 0xC0) {
      j[i + 5] = 3000 >> 8;
      j[i + 6] = 3000 & 0xFF;
      j[i + 7] = 3000 >> 8;
      j[i + 8] = 3000 & 0xFF;
      break;
    }
  }
  EXPECT_FALSE(DecodeImage(j.data(), j.size(), "jpeg").ok());
}

TEST(ImageHostile, TruncationsAndBitFlipsNeverCrash) {
  Image image(24, 16, 3);
  std::mt19937 rng(9);
  for (float& v : image.pixels) v = float(rng() % 256) / 255.0f;
  std::vector<std::vector<uint8_t>> files;
  files.push_back(*EncodeImage(image, ImageFormat::kPng));
  files.push_back(*EncodeImage(image, ImageFormat::kJpeg));
  if (ImageFormatSupported(ImageFormat::kExr)) files.push_back(*EncodeImage(image, ImageFormat::kExr));
  for (const auto& file : files) {
    for (size_t cut = 0; cut < file.size(); cut += 1 + cut / 16) {
      auto result = DecodeImage(file.data(), cut, "cut");
      EXPECT_FALSE(result.ok()) << "a truncation at " << cut << " of " << file.size() << " decoded";
    }
    for (int trial = 0; trial < 300; ++trial) {
      std::vector<uint8_t> b = file;
      for (int f = 0; f < 3; ++f) b[rng() % b.size()] ^= static_cast<uint8_t>(1u << (rng() % 8));
      auto result = DecodeImage(b.data(), b.size(), "flip");
      if (result.ok()) {
        EXPECT_EQ(result->pixels.size(), size_t(result->width) * result->height * result->channels);
      }
    }
  }
  const std::vector<uint8_t> junk = {'G', 'I', 'F', '8', '9', 'a'};
  EXPECT_EQ(DecodeImage(junk.data(), junk.size(), "gif").status().code(), StatusCode::kBadMagic);
  EXPECT_EQ(ReadImage("/nonexistent/image.png").status().code(), StatusCode::kNotFound);
}

}  // namespace
}  // namespace atex
