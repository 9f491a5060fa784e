// Pixel operations on decoded images: box downscaling and conversion to RGB.
#include "atex/image.h"

namespace atex {

StatusOr<Image> DownscaleImage(const Image& image, int factor) {
  if (factor < 1) return MakeError(StatusCode::kInvalidArgument, "downscale factor ", factor, " (must be >= 1)");
  if (image.pixels.size() != size_t(image.width) * image.height * image.channels) {
    return MakeError(StatusCode::kInvalidArgument, "image of ", image.width, "x", image.height, "x", image.channels,
                     " has ", image.pixels.size(), " values");
  }
  if (factor == 1) return image;
  const int width = image.width / factor;
  const int height = image.height / factor;
  if (width < 1 || height < 1) {
    return MakeError(StatusCode::kInvalidArgument, "downscaling a ", image.width, "x", image.height,
                     " image by ", factor, " leaves no pixels");
  }
  const int channels = image.channels;
  Image out(width, height, channels);
  const float norm = 1.0f / (float(factor) * float(factor));
  std::vector<float> row_sum(size_t(width) * channels);  // [width][channels] sums of one output row
  for (int y = 0; y < height; ++y) {
    std::fill(row_sum.begin(), row_sum.end(), 0.0f);
    for (int dy = 0; dy < factor; ++dy) {
      const float* in_row = image.pixels.data() + (size_t(y) * factor + dy) * image.width * channels;
      for (int x = 0; x < width; ++x) {
        const float* in = in_row + size_t(x) * factor * channels;
        float* sum = row_sum.data() + size_t(x) * channels;
        for (int dx = 0; dx < factor; ++dx) {
          for (int c = 0; c < channels; ++c) sum[c] += in[dx * channels + c];
        }
      }
    }
    float* out_row = out.pixels.data() + size_t(y) * width * channels;
    for (size_t i = 0; i < row_sum.size(); ++i) out_row[i] = row_sum[i] * norm;
  }
  return out;
}

Image ToRgb(const Image& image, const std::array<float, 3>& background) {
  if (image.channels == 3) return image;
  const size_t pixel_count = size_t(image.width) * image.height;
  Image out(image.width, image.height, 3);
  for (size_t p = 0; p < pixel_count; ++p) {
    float* o = out.pixels.data() + p * 3;
    if (image.channels == 1) {
      o[0] = o[1] = o[2] = image.pixels[p];
    } else if (image.channels == 4) {
      const float* in = image.pixels.data() + p * 4;
      const float a = in[3];
      for (int c = 0; c < 3; ++c) o[c] = in[c] * a + background[c] * (1.0f - a);
    } else {  // 2 channels: grey + alpha
      const float* in = image.pixels.data() + p * image.channels;
      for (int c = 0; c < 3; ++c) o[c] = in[0] * in[1] + background[c] * (1.0f - in[1]);
    }
  }
  return out;
}

}  // namespace atex
