// mkkellogg GaussianSplats3D .ksplat reading (see atex/converters/web_splats.h).
#include <algorithm>
#include <cmath>
#include <vector>

#include "atex/converters/web_splats.h"
#include "atex/file_io.h"
#include "convert/bytes.h"

namespace atex {
namespace {

using converters::bytes::HalfToFloat;
using converters::bytes::LoadLE;

constexpr size_t kHeaderBytes = 4096;
constexpr size_t kSectionHeaderBytes = 1024;
constexpr double kShC0 = 0.28209479177387814;
constexpr uint32_t kMaxSections = 1u << 20;

struct Section {
  uint32_t count = 0, max_count = 0, bucket_size = 0, bucket_count = 0;
  float block_size = 0;
  uint32_t bucket_bytes = 0, scale_range = 0, full_buckets = 0, partial_buckets = 0;
  int sh_degree = 0;
  uint64_t row_bytes = 0;
  uint64_t base = 0;  // first byte of the section's bucket lengths
};

int ShComponents(int degree) { return degree == 0 ? 0 : degree == 1 ? 9 : 24; }

uint64_t RowBytes(int level, int degree) {
  const int sh = ShComponents(degree);
  if (level == 0) return 44 + 4 * uint64_t(sh);
  return 24 + uint64_t(level == 1 ? 2 : 1) * uint64_t(sh);
}

// Reads float component `k` of a row field: f32 at level 0, f16 above.
float Component(const uint8_t* p, int k, int level) {
  return level == 0 ? LoadLE<float>(p + 4 * k) : HalfToFloat(LoadLE<uint16_t>(p + 2 * k));
}

}  // namespace

StatusOr<Gaussians> ReadKsplatGaussiansFromMemory(const uint8_t* data, size_t size, const WebSplatLimits& limits) {
  if (data == nullptr && size != 0) return MakeError(StatusCode::kInvalidArgument, ".ksplat: null data");
  if (size < kHeaderBytes) {
    return MakeError(StatusCode::kTruncated, ".ksplat: ", size, " bytes, shorter than the 4096-byte header");
  }
  if (data[0] != 0) {
    return MakeError(StatusCode::kBadMagic, ".ksplat: version ", int(data[0]), ".", int(data[1]),
                     " (only 0.x SplatBuffers are known)");
  }
  const uint32_t max_sections = LoadLE<uint32_t>(data + 4), sections_used = LoadLE<uint32_t>(data + 8);
  const uint32_t total = LoadLE<uint32_t>(data + 16);
  const int level = LoadLE<uint16_t>(data + 20);
  float sh_min = LoadLE<float>(data + 36), sh_max = LoadLE<float>(data + 40);
  if (sh_min == 0) sh_min = -1.5f;  // the writer's defaults when the fields are zero
  if (sh_max == 0) sh_max = 1.5f;
  if (level > 2) return MakeError(StatusCode::kUnsupported, ".ksplat: compression level ", level, " (0, 1 or 2)");
  if (sections_used > max_sections || max_sections > kMaxSections ||
      uint64_t(max_sections) * kSectionHeaderBytes > size - kHeaderBytes) {
    return MakeError(StatusCode::kCorrupt, ".ksplat: header at byte 4 announces ", sections_used, " of ",
                     max_sections, " sections of 1024-byte headers, which a ", size, "-byte file cannot hold");
  }
  if (total > limits.max_gaussians) {
    return MakeError(StatusCode::kLimitExceeded, ".ksplat: ", total, " Gaussians exceed the limit of ",
                     limits.max_gaussians);
  }
  if (level == 2 && !(std::isfinite(sh_min) && std::isfinite(sh_max) && sh_min < sh_max)) {
    return MakeError(StatusCode::kCorrupt, ".ksplat: SH range [", sh_min, ", ", sh_max, "] at byte 36 is empty");
  }

  // Section headers; every section's storage must lie inside the file.
  std::vector<Section> sections(max_sections);
  uint64_t base = kHeaderBytes + uint64_t(max_sections) * kSectionHeaderBytes;
  uint64_t counted = 0;
  int sh_degree = 0;
  for (uint32_t s = 0; s < max_sections; ++s) {
    const uint8_t* h = data + kHeaderBytes + size_t(s) * kSectionHeaderBytes;
    Section& sec = sections[s];
    sec.count = LoadLE<uint32_t>(h), sec.max_count = LoadLE<uint32_t>(h + 4);
    sec.bucket_size = LoadLE<uint32_t>(h + 8), sec.bucket_count = LoadLE<uint32_t>(h + 12);
    sec.block_size = LoadLE<float>(h + 16);
    sec.bucket_bytes = LoadLE<uint16_t>(h + 20);
    sec.scale_range = LoadLE<uint32_t>(h + 24);
    if (sec.scale_range == 0) sec.scale_range = level == 0 ? 1 : 32767;
    sec.full_buckets = LoadLE<uint32_t>(h + 32), sec.partial_buckets = LoadLE<uint32_t>(h + 36);
    sec.sh_degree = LoadLE<uint16_t>(h + 40);
    const uint64_t at = kHeaderBytes + uint64_t(s) * kSectionHeaderBytes;
    if (sec.sh_degree > 2) {
      return MakeError(StatusCode::kUnsupported, ".ksplat: section ", s, " (header at byte ", at, ") has SH degree ",
                       sec.sh_degree, " (0..2)");
    }
    if (sec.count > sec.max_count) {
      return MakeError(StatusCode::kCorrupt, ".ksplat: section ", s, " (header at byte ", at, ") holds ", sec.count,
                       " of at most ", sec.max_count, " Gaussians");
    }
    if (level >= 1 &&
        (sec.bucket_bytes != 12 || sec.partial_buckets > sec.bucket_count || sec.full_buckets > sec.bucket_count ||
         !(sec.block_size > 0) || !std::isfinite(sec.block_size))) {
      return MakeError(StatusCode::kCorrupt, ".ksplat: section ", s, " (header at byte ", at,
                       ") has inconsistent buckets (", sec.bucket_count, " buckets of ", sec.bucket_bytes, " bytes, ",
                       sec.full_buckets, " full, ", sec.partial_buckets, " partial, block size ", sec.block_size, ")");
    }
    sec.row_bytes = RowBytes(level, sec.sh_degree);
    sec.base = base;
    const uint64_t storage = sec.row_bytes * sec.max_count + uint64_t(sec.bucket_bytes) * sec.bucket_count +
                             4 * uint64_t(sec.partial_buckets);
    if (base > size || storage > size - base) {
      return MakeError(StatusCode::kTruncated, ".ksplat: section ", s, " needs ", storage, " bytes at byte ", base,
                       " but the file has ", size, " bytes");
    }
    base += storage;
    if (s < sections_used) {
      counted += sec.count;
      sh_degree = std::max(sh_degree, sec.sh_degree);
    }
  }
  if (counted != total) {
    return MakeError(StatusCode::kCorrupt, ".ksplat: the header (byte 16) announces ", total,
                     " Gaussians, the sections hold ", counted);
  }

  Gaussians g;
  g.sh_degree = sh_degree;
  g.Resize(size_t(total));
  const size_t k_count = size_t(g.sh_coeffs());
  size_t i = 0;
  for (uint32_t s = 0; s < sections_used; ++s) {
    const Section& sec = sections[s];
    const uint8_t* lengths = data + sec.base;
    const uint8_t* centres = lengths + 4 * size_t(sec.partial_buckets);
    const uint8_t* rows = centres + size_t(sec.bucket_bytes) * sec.bucket_count;
    const double factor = 0.5 * double(sec.block_size) / double(sec.scale_range);
    // Bucket of each row: full buckets of bucket_size rows, then the partial ones by their lengths.
    const uint64_t full_rows = uint64_t(sec.full_buckets) * sec.bucket_size;
    uint64_t bucket = 0, left_in_bucket = 0;
    uint32_t partial = 0;
    for (uint32_t j = 0; j < sec.count; ++j, ++i) {
      const uint8_t* row = rows + size_t(j) * sec.row_bytes;
      const uint64_t at = uint64_t(row - data);
      if (level >= 1) {
        if (j < full_rows) {
          bucket = j / sec.bucket_size;
        } else {
          while (left_in_bucket == 0) {
            if (partial >= sec.partial_buckets) {
              return MakeError(StatusCode::kCorrupt, ".ksplat: section ", s, " Gaussian ", j, " (byte ", at,
                               ") lies beyond its full and partially filled buckets");
            }
            bucket = uint64_t(sec.full_buckets) + partial;
            left_in_bucket = LoadLE<uint32_t>(lengths + 4 * size_t(partial++));
          }
          --left_in_bucket;
        }
        if (bucket >= sec.bucket_count) {
          return MakeError(StatusCode::kCorrupt, ".ksplat: section ", s, " Gaussian ", j, " (byte ", at,
                           ") falls in bucket ", bucket, " of ", sec.bucket_count);
        }
      }
      for (int k = 0; k < 3; ++k) {
        double p;
        if (level == 0) {
          p = LoadLE<float>(row + 4 * k);
        } else {
          const double centre = LoadLE<float>(centres + bucket * 12 + 4 * size_t(k));
          p = (double(LoadLE<uint16_t>(row + 2 * k)) - sec.scale_range) * factor + centre;
        }
        const double scale = Component(row + (level == 0 ? 12 : 6), k, level);
        if (!std::isfinite(p) || !(scale >= 0) || !std::isfinite(scale)) {
          return MakeError(StatusCode::kCorrupt, ".ksplat: section ", s, " Gaussian ", j, " (byte ", at,
                           ") has a position or scale that is not finite, or a negative scale");
        }
        g.positions[i * 3 + k] = float(p);
        // A scale that reads as 0 (f16 underflow at levels 1, 2) becomes the smallest half.
        g.log_scales[i * 3 + k] = float(std::log(std::max(scale, 5.960464477539063e-8)));
      }
      double q[4], length = 0;
      for (int k = 0; k < 4; ++k) {
        q[k] = Component(row + (level == 0 ? 24 : 12), k, level);  // (w, x, y, z)
        if (!std::isfinite(q[k])) {
          return MakeError(StatusCode::kCorrupt, ".ksplat: section ", s, " Gaussian ", j, " (byte ", at,
                           ") has a rotation that is not finite");
        }
        length += q[k] * q[k];
      }
      if (length == 0) q[0] = 1, length = 1;
      length = std::sqrt(length);
      for (int k = 0; k < 4; ++k) g.rotations[i * 4 + k] = float(q[k] / length);
      const uint8_t* colour = row + (level == 0 ? 40 : 20);
      for (int c = 0; c < 3; ++c) g.sh[i * k_count * 3 + size_t(c)] = float((colour[c] / 255.0 - 0.5) / kShC0);
      const double alpha = std::clamp(colour[3] / 255.0, 0.5 / 255, 254.5 / 255);
      g.opacity_logits[i] = float(std::log(alpha / (1 - alpha)));
      // SH rest: band 1 as [R c1..3, G c1..3, B c1..3], then band 2 as [R c4..8, G .., B ..].
      const uint8_t* sh = row + (level == 0 ? 44 : 24);
      for (int band = 1; band <= sec.sh_degree; ++band) {
        const int per = band == 1 ? 3 : 5, first = band == 1 ? 0 : 9, coeff0 = band == 1 ? 1 : 4;
        for (int c = 0; c < 3; ++c) {
          for (int m = 0; m < per; ++m) {
            const int component = first + c * per + m;
            double v;
            if (level == 2) {
              v = sh[component] / 255.0 * (double(sh_max) - sh_min) + sh_min;
            } else {
              v = Component(sh, component, level);
            }
            if (!std::isfinite(v)) {
              return MakeError(StatusCode::kCorrupt, ".ksplat: section ", s, " Gaussian ", j, " (byte ", at,
                               ") has an SH coefficient that is not finite");
            }
            g.sh[(i * k_count + size_t(coeff0 + m)) * 3 + size_t(c)] = float(v);
          }
        }
      }
    }
  }
  return g;
}

StatusOr<Gaussians> ReadKsplatGaussians(const std::string& path, const WebSplatLimits& limits) {
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, ReadFileBytes(path));
  auto result = ReadKsplatGaussiansFromMemory(bytes.data(), bytes.size(), limits);
  if (!result.ok()) return result.status().WithContext(path);
  return result;
}

}  // namespace atex
