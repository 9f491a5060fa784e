// Minimal zip writer: local header + data per member, then the central
// directory and end record; ZIP64 records only where a field overflows.
#include <algorithm>
#include <limits>

#include <zlib.h>

#include "atex/zip.h"
#include "data/byte_reader.h"

namespace atex {
namespace {

constexpr uint32_t kSaturated32 = 0xFFFFFFFFu;
constexpr uint16_t kDosDate1980 = 0x21;  // 1980-01-01: deterministic output, no clock

void Put16(std::vector<uint8_t>& out, uint16_t v) {
  uint8_t b[2];
  StoreLE16(b, v);
  out.insert(out.end(), b, b + 2);
}
void Put32(std::vector<uint8_t>& out, uint32_t v) {
  uint8_t b[4];
  StoreLE32(b, v);
  out.insert(out.end(), b, b + 4);
}
void Put64(std::vector<uint8_t>& out, uint64_t v) {
  uint8_t b[8];
  StoreLE64(b, v);
  out.insert(out.end(), b, b + 8);
}

StatusOr<std::vector<uint8_t>> RawDeflate(const uint8_t* data, size_t size, const std::string& name) {
  z_stream stream{};
  if (deflateInit2(&stream, Z_DEFAULT_COMPRESSION, Z_DEFLATED, -MAX_WBITS, 8, Z_DEFAULT_STRATEGY) != Z_OK) {
    return MakeError(StatusCode::kInternal, "zip member '", name, "': zlib deflateInit2 failed");
  }
  std::vector<uint8_t> out(deflateBound(&stream, static_cast<uLong>(std::min<size_t>(size, 1u << 30))) + 64);
  size_t produced = 0;
  const uint8_t* in = data;
  size_t in_left = size;
  int rc = Z_OK;
  while (rc != Z_STREAM_END) {
    if (stream.avail_in == 0 && in_left > 0) {
      const uInt chunk = static_cast<uInt>(std::min<size_t>(in_left, 1u << 30));
      stream.next_in = const_cast<Bytef*>(in);
      stream.avail_in = chunk;
      in += chunk;
      in_left -= chunk;
    }
    if (produced == out.size()) out.resize(out.size() * 2);
    stream.next_out = out.data() + produced;
    stream.avail_out = static_cast<uInt>(std::min<size_t>(out.size() - produced, 1u << 30));
    const uInt before = stream.avail_out;
    rc = deflate(&stream, in_left == 0 ? Z_FINISH : Z_NO_FLUSH);
    produced += before - stream.avail_out;
    if (rc == Z_STREAM_ERROR) {
      deflateEnd(&stream);
      return MakeError(StatusCode::kInternal, "zip member '", name, "': zlib deflate failed");
    }
  }
  deflateEnd(&stream);
  out.resize(produced);
  return out;
}

}  // namespace

Status ZipWriter::Add(const std::string& name, const uint8_t* data, size_t size, bool deflate) {
  if (name.empty() || name.size() > 0xFFFF) {
    return MakeError(StatusCode::kInvalidArgument, "zip member name of ", name.size(), " bytes (1..65535 allowed)");
  }
  std::vector<uint8_t> compressed;
  const uint8_t* payload = data;
  size_t payload_size = size;
  if (deflate) {
    ATEX_ASSIGN_OR_RETURN(compressed, RawDeflate(data, size, name));
    payload = compressed.data();
    payload_size = compressed.size();
  }
  Record record{name, static_cast<uint16_t>(deflate ? 8 : 0), ZipCrc32(data, size), payload_size, size, out_.size()};
  const bool zip64 = record.compressed_size >= kSaturated32 || record.uncompressed_size >= kSaturated32;
  Put32(out_, 0x04034b50);
  Put16(out_, zip64 ? 45 : 20);  // version needed
  Put16(out_, 0);                // flags
  Put16(out_, record.method);
  Put16(out_, 0);  // time
  Put16(out_, kDosDate1980);
  Put32(out_, record.crc);
  Put32(out_, zip64 ? kSaturated32 : static_cast<uint32_t>(record.compressed_size));
  Put32(out_, zip64 ? kSaturated32 : static_cast<uint32_t>(record.uncompressed_size));
  Put16(out_, static_cast<uint16_t>(name.size()));
  Put16(out_, zip64 ? 20 : 0);
  out_.insert(out_.end(), name.begin(), name.end());
  if (zip64) {
    Put16(out_, 0x0001);
    Put16(out_, 16);
    Put64(out_, record.uncompressed_size);
    Put64(out_, record.compressed_size);
  }
  out_.insert(out_.end(), payload, payload + payload_size);
  records_.push_back(std::move(record));
  return Status::Ok();
}

std::vector<uint8_t> ZipWriter::Finish() {
  const uint64_t cd_offset = out_.size();
  for (const Record& r : records_) {
    const bool big_u = r.uncompressed_size >= kSaturated32;
    const bool big_c = r.compressed_size >= kSaturated32;
    const bool big_o = r.offset >= kSaturated32;
    const uint16_t extra = static_cast<uint16_t>((big_u || big_c || big_o) ? 4 + 8 * (big_u + big_c + big_o) : 0);
    Put32(out_, 0x02014b50);
    Put16(out_, 45);  // made by: MS-DOS host, spec 4.5
    Put16(out_, extra ? 45 : 20);
    Put16(out_, 0);
    Put16(out_, r.method);
    Put16(out_, 0);
    Put16(out_, kDosDate1980);
    Put32(out_, r.crc);
    Put32(out_, big_c ? kSaturated32 : static_cast<uint32_t>(r.compressed_size));
    Put32(out_, big_u ? kSaturated32 : static_cast<uint32_t>(r.uncompressed_size));
    Put16(out_, static_cast<uint16_t>(r.name.size()));
    Put16(out_, extra);
    Put16(out_, 0);  // comment
    Put16(out_, 0);  // disk
    Put16(out_, 0);  // internal attributes
    Put32(out_, 0);  // external attributes
    Put32(out_, big_o ? kSaturated32 : static_cast<uint32_t>(r.offset));
    out_.insert(out_.end(), r.name.begin(), r.name.end());
    if (extra) {
      Put16(out_, 0x0001);
      Put16(out_, static_cast<uint16_t>(extra - 4));
      if (big_u) Put64(out_, r.uncompressed_size);
      if (big_c) Put64(out_, r.compressed_size);
      if (big_o) Put64(out_, r.offset);
    }
  }
  const uint64_t cd_size = out_.size() - cd_offset;
  const uint64_t count = records_.size();
  const bool zip64 = count >= 0xFFFF || cd_offset >= kSaturated32 || cd_size >= kSaturated32;
  if (zip64) {
    const uint64_t z64_pos = out_.size();
    Put32(out_, 0x06064b50);
    Put64(out_, 44);  // size of the rest of this record
    Put16(out_, 45);
    Put16(out_, 45);
    Put32(out_, 0);
    Put32(out_, 0);
    Put64(out_, count);
    Put64(out_, count);
    Put64(out_, cd_size);
    Put64(out_, cd_offset);
    Put32(out_, 0x07064b50);
    Put32(out_, 0);
    Put64(out_, z64_pos);
    Put32(out_, 1);
  }
  Put32(out_, 0x06054b50);
  Put16(out_, 0);
  Put16(out_, 0);
  Put16(out_, zip64 ? 0xFFFF : static_cast<uint16_t>(count));
  Put16(out_, zip64 ? 0xFFFF : static_cast<uint16_t>(count));
  Put32(out_, zip64 ? kSaturated32 : static_cast<uint32_t>(cd_size));
  Put32(out_, zip64 ? kSaturated32 : static_cast<uint32_t>(cd_offset));
  Put16(out_, 0);
  records_.clear();
  return std::move(out_);
}

}  // namespace atex
