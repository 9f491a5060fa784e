#include "container/attribute_stream.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <mutex>

#include "container/byte_io.h"
#include "container/format.h"
#include "container/half.h"
#include "container/row_blocks.h"

namespace atex::container {
namespace {

uint32_t QuantMax(ScalarEncoding encoding) { return encoding == ScalarEncoding::kQuant16 ? 65535u : 255u; }

// §6: value = f32(f64(min) + (f64(max) - f64(min)) * (f64(q) / f64(Lmax))), in this order.
inline float Dequantise(uint32_t q, double lo, double range, double lmax) {
  return static_cast<float>(lo + range * (static_cast<double>(q) / lmax));
}

Status NonFinite(const char* what, uint64_t row, uint32_t component, float value) {
  return MakeError(StatusCode::kOutOfRange, what, " row ", row, " component ", component, " is not finite (", value,
                   ")");
}

}  // namespace

size_t EncodingBytes(ScalarEncoding encoding) {
  switch (encoding) {
    case ScalarEncoding::kFloat32: return 4;
    case ScalarEncoding::kFloat16: return 2;
    case ScalarEncoding::kQuant16: return 2;
    case ScalarEncoding::kQuant8: return 1;
  }
  return 0;
}

bool IsQuantised(ScalarEncoding encoding) {
  return encoding == ScalarEncoding::kQuant16 || encoding == ScalarEncoding::kQuant8;
}

uint64_t StreamHeaderBytes(ScalarEncoding encoding, uint32_t components) {
  return kStreamHeaderSize + (IsQuantised(encoding) ? uint64_t{8} * components : 0);
}

namespace {

// q = clamp(floor((v - lo) / (hi - lo) · lmax + 0.5), 0, lmax) in binary64; 0 where hi = lo
// (range = f64(hi) - f64(lo), top = lmax). The one definition of §6's quantisation, shared by
// the encoder and ReadBackStream. For 0 <= t < 4e18 the floor is the truncation (cheaper than
// floor without SSE4.1), which is every value within [lo, hi].
template <typename T>
inline T Quantise(float value, double low, double range, double top) {
  if (!(range > 0)) return 0;
  const double t = (static_cast<double>(value) - low) / range * top + 0.5;
  const double whole = (t >= 0.0 && t < 4.0e18) ? static_cast<double>(static_cast<int64_t>(t)) : std::floor(t);
  return static_cast<T>(std::clamp(whole, 0.0, top));
}

// The quantisation below, for values [rows][C]
// (C = lo.size()), stored little-endian as T at `out`; q = 0 where hi = lo. Row by row with the
// per-component terms computed once: the same operations in the same order as per value, so the
// same bits, without a division of the index by C per value.
template <typename T>
void QuantiseRows(const float* values, uint64_t rows, const std::vector<float>& lo, const std::vector<float>& hi,
                  uint32_t lmax, uint8_t* out) {
  const size_t components = lo.size();
  std::vector<double> low(components), range(components);  // [C]
  for (size_t c = 0; c < components; ++c) {
    low[c] = static_cast<double>(lo[c]);
    range[c] = static_cast<double>(hi[c]) - static_cast<double>(lo[c]);
  }
  const double top = static_cast<double>(lmax);
  ForRowBlocks(rows, RowBlocks(rows, rows * components), [&](int64_t, uint64_t begin, uint64_t end) {
    for (uint64_t r = begin; r < end; ++r) {
      const float* row = values + r * components;
      uint8_t* row_out = out + r * components * sizeof(T);
      for (size_t c = 0; c < components; ++c) {
        const T q = Quantise<T>(row[c], low[c], range[c], top);
        if constexpr (sizeof(T) == 1) {
          row_out[c] = q;
        } else {
          StoreLE<T>(row_out + c * sizeof(T), q);
        }
      }
    }
  });
}

}  // namespace

void StreamRange(const float* values, size_t stride, uint64_t rows, uint32_t components, float* lo, float* hi) {
  std::fill_n(lo, components, 0.0f);
  std::fill_n(hi, components, 0.0f);
  if (rows == 0) return;
  // Each block's range from its first row on, then the blocks' ranges in block order: std::min
  // and std::max keep the earlier of two equal values, so the result is the first minimum (and
  // maximum) in row order, as one pass would find it (-0 and +0 are equal).
  const int64_t blocks = RowBlocks(rows, rows * components);
  std::vector<float> block_lo(static_cast<size_t>(blocks) * components);  // [blocks][C]
  std::vector<float> block_hi(block_lo.size());
  ForRowBlocks(rows, blocks, [&](int64_t b, uint64_t begin, uint64_t end) {
    float* l = block_lo.data() + b * components;
    float* h = block_hi.data() + b * components;
    std::copy_n(values + begin * stride, components, l);
    std::copy_n(values + begin * stride, components, h);
    for (uint64_t r = begin + 1; r < end; ++r) {
      const float* row = values + r * stride;
      for (uint32_t c = 0; c < components; ++c) {
        l[c] = std::min(l[c], row[c]);
        h[c] = std::max(h[c], row[c]);
      }
    }
  });
  std::copy_n(block_lo.begin(), components, lo);
  std::copy_n(block_hi.begin(), components, hi);
  for (int64_t b = 1; b < blocks; ++b) {
    for (uint32_t c = 0; c < components; ++c) {
      lo[c] = std::min(lo[c], block_lo[b * components + c]);
      hi[c] = std::max(hi[c], block_hi[b * components + c]);
    }
  }
}

Status ReadBackStream(const float* in, size_t in_stride, uint64_t rows, uint32_t components, ScalarEncoding encoding,
                      float* out, size_t out_stride, const char* what) {
  if (EncodingBytes(encoding) == 0) {
    return MakeError(StatusCode::kInvalidArgument, what, ": unknown encoding ", int{static_cast<uint8_t>(encoding)});
  }
  std::vector<double> low(components), range(components);  // [C], as the decoder reads them
  if (IsQuantised(encoding)) {
    std::vector<float> lo(components), hi(components);  // [C], as the encoder stores them
    StreamRange(in, in_stride, rows, components, lo.data(), hi.data());
    for (uint32_t c = 0; c < components; ++c) {
      low[c] = lo[c];
      range[c] = static_cast<double>(hi[c]) - static_cast<double>(lo[c]);
    }
  }
  const double top = IsQuantised(encoding) ? QuantMax(encoding) : 0.0;
  // The first value f16 cannot hold, and the value (`out` may be `in`: it is overwritten).
  std::mutex overflow_mutex;
  uint64_t overflow_at = UINT64_MAX;
  float overflow_value = 0;
  // One loop per encoding, so that the encoding's test is not inside it.
  const auto each_value = [&](auto value_of) {
    ForRowBlocks(rows, RowBlocks(rows, rows * components), [&](int64_t, uint64_t begin, uint64_t end) {
      for (uint64_t r = begin; r < end; ++r) {
        const float* row = in + r * in_stride;
        float* row_out = out + r * out_stride;
        for (uint32_t c = 0; c < components; ++c) row_out[c] = value_of(row[c], c, r);
      }
    });
  };
  switch (encoding) {
    case ScalarEncoding::kFloat32: each_value([](float v, uint32_t, uint64_t) { return v; }); break;
    case ScalarEncoding::kFloat16:
      each_value([&](float v, uint32_t c, uint64_t r) {
        bool overflow = false;
        const uint16_t h = FloatToHalf(v, &overflow);
        if (overflow) {
          std::lock_guard<std::mutex> lock(overflow_mutex);
          if (r * components + c < overflow_at) {
            overflow_at = r * components + c;
            overflow_value = v;
          }
        }
        return HalfToFloat(h);
      });
      break;
    case ScalarEncoding::kQuant16:
    case ScalarEncoding::kQuant8: {
      // Each component's dequantised levels once, when the stream is long enough to pay for
      // them (a table an eighth of the values at most): the same Dequantise of the same level,
      // so the same values.
      const size_t levels = static_cast<size_t>(top) + 1;
      if (rows >= 8 * levels) {
        std::vector<float> table(levels * components);  // [C][levels]
        for (uint32_t c = 0; c < components; ++c) {
          for (size_t q = 0; q < levels; ++q) {
            table[c * levels + q] = Dequantise(static_cast<uint32_t>(q), low[c], range[c], top);
          }
        }
        if (encoding == ScalarEncoding::kQuant16) {
          each_value([&](float v, uint32_t c, uint64_t) {
            return table[c * levels + Quantise<uint16_t>(v, low[c], range[c], top)];
          });
        } else {
          each_value([&](float v, uint32_t c, uint64_t) {
            return table[c * levels + Quantise<uint8_t>(v, low[c], range[c], top)];
          });
        }
      } else {
        // Quantise<uint16_t> holds both encodings' levels (clamped to top).
        each_value([&](float v, uint32_t c, uint64_t) {
          return Dequantise(Quantise<uint16_t>(v, low[c], range[c], top), low[c], range[c], top);
        });
      }
      break;
    }
  }
  if (overflow_at != UINT64_MAX) {
    return MakeError(StatusCode::kOutOfRange, what, " row ", overflow_at / components, " component ",
                     overflow_at % components, " = ", overflow_value, " does not fit float16 (|v| < 65520)");
  }
  return Status::Ok();
}

StatusOr<std::vector<uint8_t>> EncodeStream(const float* values, uint64_t rows, uint32_t components,
                                            ScalarEncoding encoding, const char* what) {
  if (components == 0 || components > 0xFFFF) {
    return MakeError(StatusCode::kInternal, what, ": ", components, " components do not fit a stream header");
  }
  if (EncodingBytes(encoding) == 0) {
    return MakeError(StatusCode::kInvalidArgument, what, ": unknown encoding ", int{static_cast<uint8_t>(encoding)});
  }
  const uint64_t count = rows * components;
  // A branch-free pass per block of rows; the position only on failure.
  const int64_t blocks = RowBlocks(rows, count);
  std::vector<uint32_t> block_bad(static_cast<size_t>(blocks), 0);
  ForRowBlocks(rows, blocks, [&](int64_t b, uint64_t begin, uint64_t end) {
    uint32_t bad = 0;
    for (uint64_t i = begin * components; i < end * components; ++i)
      bad |= static_cast<uint32_t>((std::bit_cast<uint32_t>(values[i]) & 0x7F800000u) == 0x7F800000u);
    block_bad[static_cast<size_t>(b)] = bad;
  });
  const bool bad = std::any_of(block_bad.begin(), block_bad.end(), [](uint32_t x) { return x != 0; });
  for (uint64_t i = 0; bad && i < count; ++i) {
    if (!std::isfinite(values[i]))
      return NonFinite(what, i / components, static_cast<uint32_t>(i % components), values[i]);
  }
  const uint64_t header = StreamHeaderBytes(encoding, components);
  std::vector<uint8_t> out;
  out.reserve(static_cast<size_t>(header + count * EncodingBytes(encoding)));
  ByteWriter w(&out);
  w.Put<uint8_t>(static_cast<uint8_t>(encoding));
  w.Put<uint8_t>(0);
  w.Put<uint16_t>(static_cast<uint16_t>(components));
  w.Put<uint32_t>(0);
  w.Put<uint64_t>(rows);
  switch (encoding) {
    case ScalarEncoding::kFloat32: {
      out.resize(static_cast<size_t>(header + count * 4));
      uint8_t* p = out.data() + header;
      if constexpr (std::endian::native == std::endian::little) {
        CopyBytes(p, values, static_cast<size_t>(count) * 4);
      } else {
        for (uint64_t i = 0; i < count; ++i) StoreLE<float>(p + i * 4, values[i]);
      }
      break;
    }
    case ScalarEncoding::kFloat16: {
      out.resize(static_cast<size_t>(header + count * 2));
      uint8_t* p = out.data() + header;
      for (uint64_t i = 0; i < count; ++i) {
        bool overflow = false;
        const uint16_t h = FloatToHalf(values[i], &overflow);
        if (overflow) {
          return MakeError(StatusCode::kOutOfRange, what, " row ", i / components, " component ", i % components, " = ",
                           values[i], " does not fit float16 (|v| < 65520)");
        }
        StoreLE<uint16_t>(p + i * 2, h);
      }
      break;
    }
    case ScalarEncoding::kQuant16:
    case ScalarEncoding::kQuant8: {
      std::vector<float> lo(components), hi(components);  // [C]
      StreamRange(values, components, rows, components, lo.data(), hi.data());
      for (uint32_t c = 0; c < components; ++c) {
        w.Put<float>(lo[c]);
        w.Put<float>(hi[c]);
      }
      const size_t b = EncodingBytes(encoding);
      out.resize(static_cast<size_t>(header + count * b));
      uint8_t* p = out.data() + header;
      if (b == 2) {
        QuantiseRows<uint16_t>(values, rows, lo, hi, QuantMax(encoding), p);
      } else {
        QuantiseRows<uint8_t>(values, rows, lo, hi, QuantMax(encoding), p);
      }
      break;
    }
  }
  return out;
}

StatusOr<StreamInfo> ParseStreamHeader(const uint8_t* raw, size_t size) {
  if (size < kStreamHeaderSize) {
    return MakeError(StatusCode::kCorrupt, "stream of ", size, " bytes is shorter than its 16-byte header");
  }
  StreamInfo info;
  const uint8_t encoding = raw[kStreamEncoding];
  if (encoding > static_cast<uint8_t>(ScalarEncoding::kQuant8)) {
    return MakeError(StatusCode::kCorrupt, "stream encoding ", int{encoding}, " is unknown (byte 0)");
  }
  info.encoding = static_cast<ScalarEncoding>(encoding);
  if (raw[kStreamReserved8] != 0 || LoadLE<uint32_t>(raw + kStreamReserved32) != 0) {
    return MakeError(StatusCode::kCorrupt, "stream header reserved bytes are not zero");
  }
  info.components = LoadLE<uint16_t>(raw + kStreamComponents);
  info.rows = LoadLE<uint64_t>(raw + kStreamRows);
  if (info.components == 0) return MakeError(StatusCode::kCorrupt, "stream has 0 components (byte 2)");
  info.header_bytes = StreamHeaderBytes(info.encoding, info.components);
  uint64_t values = 0, value_bytes = 0, expected = 0;
  if (MulOverflows(info.rows, info.components, &values) ||
      MulOverflows(values, EncodingBytes(info.encoding), &value_bytes) ||
      AddOverflows(value_bytes, info.header_bytes, &expected) || expected != size) {
    return MakeError(StatusCode::kCorrupt, "stream of ", info.rows, " rows x ", info.components,
                     " components (encoding ", int{encoding}, ") does not match its raw size ", size);
  }
  return info;
}

Status DecodeStream(const uint8_t* raw, size_t size, uint32_t expected_components, uint64_t expected_rows,
                    std::vector<float>* values) {
  ATEX_ASSIGN_OR_RETURN(const StreamInfo info, ParseStreamHeader(raw, size));
  if (info.components != expected_components) {
    return MakeError(StatusCode::kCorrupt, "stream has ", info.components, " components, expected ",
                     expected_components);
  }
  if (info.rows != expected_rows) {
    return MakeError(StatusCode::kCorrupt, "stream has ", info.rows, " rows, expected ", expected_rows);
  }
  // rows * components * bytes == size - header: the allocation is backed by data.
  values->resize(static_cast<size_t>(info.rows * info.components));
  return DecodeStreamValues(raw, info, values->data(), info.components);
}

Status CheckFiniteValues(const float* values, uint64_t rows, uint32_t components) {
  const uint64_t count = rows * components;
  // Exponent all ones = Inf or NaN: a branch-free pass first (it vectorises), the
  // position only on failure.
  uint32_t bad = 0;
  for (uint64_t i = 0; i < count; ++i)
    bad |= static_cast<uint32_t>((std::bit_cast<uint32_t>(values[i]) & 0x7F800000u) == 0x7F800000u);
  for (uint64_t i = 0; bad && i < count; ++i) {
    if (!std::isfinite(values[i]))
      return NonFinite("stream", i / components, static_cast<uint32_t>(i % components), values[i]);
  }
  return Status::Ok();
}

Status DecodeStreamValues(const uint8_t* raw, const StreamInfo& info, float* out, size_t out_stride) {
  const size_t rows = static_cast<size_t>(info.rows);
  const size_t c_count = info.components;
  const uint8_t* p = raw + info.header_bytes;
  switch (info.encoding) {
    case ScalarEncoding::kFloat32: {
      if (std::endian::native == std::endian::little && out_stride == c_count) {
        CopyBytes(out, p, rows * c_count * 4);
      } else {
        for (size_t r = 0; r < rows; ++r) {
          for (size_t c = 0; c < c_count; ++c) out[r * out_stride + c] = LoadLE<float>(p + (r * c_count + c) * 4);
        }
      }
      if (out_stride == c_count) return CheckFiniteValues(out, rows, info.components);
      for (size_t r = 0; r < rows; ++r) {
        for (size_t c = 0; c < c_count; ++c) {
          if (!std::isfinite(out[r * out_stride + c])) {
            return NonFinite("stream", r, static_cast<uint32_t>(c), out[r * out_stride + c]);
          }
        }
      }
      break;
    }
    case ScalarEncoding::kFloat16:
      for (size_t r = 0; r < rows; ++r) {
        for (size_t c = 0; c < c_count; ++c) {
          const uint16_t h = LoadLE<uint16_t>(p + (r * c_count + c) * 2);
          out[r * out_stride + c] = HalfToFloat(h);
          if (!IsHalfFinite(h)) return NonFinite("stream", r, static_cast<uint32_t>(c), HalfToFloat(h));
        }
      }
      break;
    case ScalarEncoding::kQuant16:
    case ScalarEncoding::kQuant8: {
      std::vector<double> lo(c_count), range(c_count);  // [C]
      for (size_t c = 0; c < c_count; ++c) {
        const float a = LoadLE<float>(raw + kStreamHeaderSize + c * 8);
        const float b = LoadLE<float>(raw + kStreamHeaderSize + c * 8 + 4);
        if (!std::isfinite(a) || !std::isfinite(b) || !(a <= b)) {
          return MakeError(StatusCode::kCorrupt, "stream range of component ", c, " is [", a, ", ", b,
                           "]; it must be finite with min <= max");
        }
        lo[c] = a;
        range[c] = static_cast<double>(b) - static_cast<double>(a);
      }
      const double lmax = QuantMax(info.encoding);
      if (info.encoding == ScalarEncoding::kQuant16) {
        for (size_t r = 0; r < rows; ++r) {
          for (size_t c = 0; c < c_count; ++c) {
            out[r * out_stride + c] = Dequantise(LoadLE<uint16_t>(p + (r * c_count + c) * 2), lo[c], range[c], lmax);
          }
        }
      } else {
        for (size_t r = 0; r < rows; ++r) {
          for (size_t c = 0; c < c_count; ++c)
            out[r * out_stride + c] = Dequantise(p[r * c_count + c], lo[c], range[c], lmax);
        }
      }
      break;
    }
  }
  return Status::Ok();
}

}  // namespace atex::container
