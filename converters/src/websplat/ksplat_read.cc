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

// The 4096-byte file header.
struct FileHeader {
  uint32_t max_sections = 0, sections_used = 0, total = 0;
  int level = 0;                 // compression level 0..2
  float sh_min = 0, sh_max = 0;  // the range of level 2's 8-bit SH
};

StatusOr<FileHeader> ParseFileHeader(const uint8_t* data, size_t size, const WebSplatLimits& limits) {
  if (size < kHeaderBytes) {
    return MakeError(StatusCode::kTruncated, ".ksplat: ", size, " bytes, shorter than the 4096-byte header");
  }
  if (data[0] != 0) {
    return MakeError(StatusCode::kBadMagic, ".ksplat: version ", int(data[0]), ".", int(data[1]),
                     " (only 0.x SplatBuffers are known)");
  }
  FileHeader h;
  h.max_sections = LoadLE<uint32_t>(data + 4), h.sections_used = LoadLE<uint32_t>(data + 8);
  h.total = LoadLE<uint32_t>(data + 16);
  h.level = LoadLE<uint16_t>(data + 20);
  h.sh_min = LoadLE<float>(data + 36), h.sh_max = LoadLE<float>(data + 40);
  if (h.sh_min == 0) h.sh_min = -1.5f;  // the writer's defaults when the fields are zero
  if (h.sh_max == 0) h.sh_max = 1.5f;
  if (h.level > 2) return MakeError(StatusCode::kUnsupported, ".ksplat: compression level ", h.level, " (0, 1 or 2)");
  if (h.sections_used > h.max_sections || h.max_sections > kMaxSections ||
      uint64_t(h.max_sections) * kSectionHeaderBytes > size - kHeaderBytes) {
    return MakeError(StatusCode::kCorrupt, ".ksplat: header at byte 4 announces ", h.sections_used, " of ",
                     h.max_sections, " sections of 1024-byte headers, which a ", size, "-byte file cannot hold");
  }
  if (h.total > limits.max_gaussians) {
    return MakeError(StatusCode::kLimitExceeded, ".ksplat: ", h.total, " Gaussians exceed the limit of ",
                     limits.max_gaussians);
  }
  if (h.level == 2 && !(std::isfinite(h.sh_min) && std::isfinite(h.sh_max) && h.sh_min < h.sh_max)) {
    return MakeError(StatusCode::kCorrupt, ".ksplat: SH range [", h.sh_min, ", ", h.sh_max, "] at byte 36 is empty");
  }
  return h;
}

// The header of section s, checked for itself (its storage is checked by ParseSections).
StatusOr<Section> ParseSectionHeader(const uint8_t* data, uint32_t s, int level) {
  const uint8_t* h = data + kHeaderBytes + size_t(s) * kSectionHeaderBytes;
  Section sec;
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
  if (level >= 1 && (sec.bucket_bytes != 12 || sec.partial_buckets > sec.bucket_count ||
                     sec.full_buckets > sec.bucket_count || !(sec.block_size > 0) || !std::isfinite(sec.block_size))) {
    return MakeError(StatusCode::kCorrupt, ".ksplat: section ", s, " (header at byte ", at,
                     ") has inconsistent buckets (", sec.bucket_count, " buckets of ", sec.bucket_bytes, " bytes, ",
                     sec.full_buckets, " full, ", sec.partial_buckets, " partial, block size ", sec.block_size, ")");
  }
  sec.row_bytes = RowBytes(level, sec.sh_degree);
  return sec;
}

struct SectionTable {
  std::vector<Section> sections;  // all max_sections of them, each placed in the file
  int sh_degree = 0;              // the highest of the used sections
};

// Section headers; every section's storage must lie inside the file, and the used sections must
// hold the header's total.
StatusOr<SectionTable> ParseSections(const uint8_t* data, size_t size, const FileHeader& header) {
  SectionTable table;
  table.sections.resize(header.max_sections);
  uint64_t base = kHeaderBytes + uint64_t(header.max_sections) * kSectionHeaderBytes;
  uint64_t counted = 0;
  for (uint32_t s = 0; s < header.max_sections; ++s) {
    ATEX_ASSIGN_OR_RETURN(Section sec, ParseSectionHeader(data, s, header.level));
    sec.base = base;
    const uint64_t storage = sec.row_bytes * sec.max_count + uint64_t(sec.bucket_bytes) * sec.bucket_count +
                             4 * uint64_t(sec.partial_buckets);
    if (base > size || storage > size - base) {
      return MakeError(StatusCode::kTruncated, ".ksplat: section ", s, " needs ", storage, " bytes at byte ", base,
                       " but the file has ", size, " bytes");
    }
    base += storage;
    if (s < header.sections_used) {
      counted += sec.count;
      table.sh_degree = std::max(table.sh_degree, sec.sh_degree);
    }
    table.sections[s] = sec;
  }
  if (counted != header.total) {
    return MakeError(StatusCode::kCorrupt, ".ksplat: the header (byte 16) announces ", header.total,
                     " Gaussians, the sections hold ", counted);
  }
  return table;
}

// One section's rows in the file: its bucket centres and the quantisation of levels 1 and 2.
struct SectionRows {
  uint32_t index = 0;  // the section's number, for messages
  const Section* sec = nullptr;
  int level = 0;
  float sh_min = 0, sh_max = 0;
  const uint8_t* lengths = nullptr;  // [partial_buckets] u32 row counts of the partial buckets
  const uint8_t* centres = nullptr;  // [bucket_count][3] f32
  const uint8_t* rows = nullptr;     // [count][row_bytes]
  double factor = 0;                 // position units per quantisation step

  SectionRows(const uint8_t* data, uint32_t s, const Section& section, const FileHeader& header)
      : index(s),
        sec(&section),
        level(header.level),
        sh_min(header.sh_min),
        sh_max(header.sh_max) {
    lengths = data + section.base;
    centres = lengths + 4 * size_t(section.partial_buckets);
    rows = centres + size_t(section.bucket_bytes) * section.bucket_count;
    factor = 0.5 * double(section.block_size) / double(section.scale_range);
  }
};

// The bucket of each row at levels 1 and 2, row after row: full buckets of bucket_size rows,
// then the partial ones by their lengths.
class BucketCursor {
 public:
  explicit BucketCursor(const SectionRows& rows)
      : rows_(rows),
        full_rows_(uint64_t(rows.sec->full_buckets) * rows.sec->bucket_size) {}

  // The bucket of row j (at byte `at`); rows must come in order.
  StatusOr<uint64_t> Next(uint32_t j, uint64_t at) {
    const Section& sec = *rows_.sec;
    if (j < full_rows_) {
      bucket_ = j / sec.bucket_size;
    } else {
      while (left_in_bucket_ == 0) {
        if (partial_ >= sec.partial_buckets) {
          return MakeError(StatusCode::kCorrupt, ".ksplat: section ", rows_.index, " Gaussian ", j, " (byte ", at,
                           ") lies beyond its full and partially filled buckets");
        }
        bucket_ = uint64_t(sec.full_buckets) + partial_;
        left_in_bucket_ = LoadLE<uint32_t>(rows_.lengths + 4 * size_t(partial_++));
      }
      --left_in_bucket_;
    }
    if (bucket_ >= sec.bucket_count) {
      return MakeError(StatusCode::kCorrupt, ".ksplat: section ", rows_.index, " Gaussian ", j, " (byte ", at,
                       ") falls in bucket ", bucket_, " of ", sec.bucket_count);
    }
    return bucket_;
  }

 private:
  const SectionRows& rows_;
  const uint64_t full_rows_;
  uint64_t bucket_ = 0, left_in_bucket_ = 0;
  uint32_t partial_ = 0;
};

// Position, scale and rotation of row j (at byte `at`, in `bucket`) into Gaussian i.
Status DecodeGeometry(const SectionRows& r, const uint8_t* row, uint32_t j, uint64_t at, uint64_t bucket, size_t i,
                      Gaussians* g) {
  const int level = r.level;
  for (int k = 0; k < 3; ++k) {
    double p;
    if (level == 0) {
      p = LoadLE<float>(row + 4 * k);
    } else {
      const double centre = LoadLE<float>(r.centres + bucket * 12 + 4 * size_t(k));
      p = (double(LoadLE<uint16_t>(row + 2 * k)) - r.sec->scale_range) * r.factor + centre;
    }
    const double scale = Component(row + (level == 0 ? 12 : 6), k, level);
    if (!std::isfinite(p) || !(scale >= 0) || !std::isfinite(scale)) {
      return MakeError(StatusCode::kCorrupt, ".ksplat: section ", r.index, " Gaussian ", j, " (byte ", at,
                       ") has a position or scale that is not finite, or a negative scale");
    }
    g->positions[i * 3 + k] = float(p);
    // A scale that reads as 0 (f16 underflow at levels 1, 2) becomes the smallest half.
    g->log_scales[i * 3 + k] = float(std::log(std::max(scale, 5.960464477539063e-8)));
  }
  double q[4], length = 0;
  for (int k = 0; k < 4; ++k) {
    q[k] = Component(row + (level == 0 ? 24 : 12), k, level);  // (w, x, y, z)
    if (!std::isfinite(q[k])) {
      return MakeError(StatusCode::kCorrupt, ".ksplat: section ", r.index, " Gaussian ", j, " (byte ", at,
                       ") has a rotation that is not finite");
    }
    length += q[k] * q[k];
  }
  if (length == 0) q[0] = 1, length = 1;
  length = std::sqrt(length);
  for (int k = 0; k < 4; ++k) g->rotations[i * 4 + k] = float(q[k] / length);
  return Status::Ok();
}

// Colour, opacity and the SH rest of row j (at byte `at`) into Gaussian i.
Status DecodeColour(const SectionRows& r, const uint8_t* row, uint32_t j, uint64_t at, size_t i, Gaussians* g) {
  const int level = r.level;
  const size_t k_count = size_t(g->sh_coeffs());
  const uint8_t* colour = row + (level == 0 ? 40 : 20);
  for (int c = 0; c < 3; ++c) g->sh[i * k_count * 3 + size_t(c)] = float((colour[c] / 255.0 - 0.5) / kShC0);
  const double alpha = std::clamp(colour[3] / 255.0, 0.5 / 255, 254.5 / 255);
  g->opacity_logits[i] = float(std::log(alpha / (1 - alpha)));
  // SH rest: band 1 as [R c1..3, G c1..3, B c1..3], then band 2 as [R c4..8, G .., B ..].
  const uint8_t* sh = row + (level == 0 ? 44 : 24);
  for (int band = 1; band <= r.sec->sh_degree; ++band) {
    const int per = band == 1 ? 3 : 5, first = band == 1 ? 0 : 9, coeff0 = band == 1 ? 1 : 4;
    for (int c = 0; c < 3; ++c) {
      for (int m = 0; m < per; ++m) {
        const int component = first + c * per + m;
        double v;
        if (level == 2) {
          v = sh[component] / 255.0 * (double(r.sh_max) - r.sh_min) + r.sh_min;
        } else {
          v = Component(sh, component, level);
        }
        if (!std::isfinite(v)) {
          return MakeError(StatusCode::kCorrupt, ".ksplat: section ", r.index, " Gaussian ", j, " (byte ", at,
                           ") has an SH coefficient that is not finite");
        }
        g->sh[(i * k_count + size_t(coeff0 + m)) * 3 + size_t(c)] = float(v);
      }
    }
  }
  return Status::Ok();
}

}  // namespace

StatusOr<Gaussians> ReadKsplatGaussiansFromMemory(const uint8_t* data, size_t size, const WebSplatLimits& limits) {
  if (data == nullptr && size != 0) return MakeError(StatusCode::kInvalidArgument, ".ksplat: null data");
  ATEX_ASSIGN_OR_RETURN(const FileHeader header, ParseFileHeader(data, size, limits));
  ATEX_ASSIGN_OR_RETURN(const SectionTable table, ParseSections(data, size, header));

  Gaussians g;
  g.sh_degree = table.sh_degree;
  g.Resize(size_t(header.total));
  size_t i = 0;
  for (uint32_t s = 0; s < header.sections_used; ++s) {
    const SectionRows rows(data, s, table.sections[s], header);
    BucketCursor buckets(rows);
    for (uint32_t j = 0; j < rows.sec->count; ++j, ++i) {
      const uint8_t* row = rows.rows + size_t(j) * rows.sec->row_bytes;
      const uint64_t at = uint64_t(row - data);
      uint64_t bucket = 0;
      if (header.level >= 1) {
        ATEX_ASSIGN_OR_RETURN(bucket, buckets.Next(j, at));
      }
      ATEX_RETURN_IF_ERROR(DecodeGeometry(rows, row, j, at, bucket, i, &g));
      ATEX_RETURN_IF_ERROR(DecodeColour(rows, row, j, at, i, &g));
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
