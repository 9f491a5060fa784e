// Little-endian loads and a bounds-checked cursor over a byte range, for the
// binary parsers of this module (zip, npy, COLMAP). Not a public header.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>

namespace atex {

inline uint16_t LoadLE16(const uint8_t* p) { return static_cast<uint16_t>(p[0] | (p[1] << 8)); }
inline uint32_t LoadLE32(const uint8_t* p) {
  return uint32_t{p[0]} | (uint32_t{p[1]} << 8) | (uint32_t{p[2]} << 16) | (uint32_t{p[3]} << 24);
}
inline uint64_t LoadLE64(const uint8_t* p) { return uint64_t{LoadLE32(p)} | (uint64_t{LoadLE32(p + 4)} << 32); }
inline double LoadLEDouble(const uint8_t* p) {
  const uint64_t u = LoadLE64(p);
  double d;
  std::memcpy(&d, &u, 8);
  return d;
}

inline void StoreLE16(uint8_t* p, uint16_t v) {
  p[0] = static_cast<uint8_t>(v);
  p[1] = static_cast<uint8_t>(v >> 8);
}
inline void StoreLE32(uint8_t* p, uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<uint8_t>(v >> (8 * i));
}
inline void StoreLE64(uint8_t* p, uint64_t v) {
  for (int i = 0; i < 8; ++i) p[i] = static_cast<uint8_t>(v >> (8 * i));
}

// Reads fixed-size little-endian fields; every read checks the bytes left and
// returns false (consuming nothing) when they are not there.
class ByteReader {
 public:
  ByteReader(const uint8_t* data, size_t size) : data_(data), size_(size) {}
  size_t position() const { return pos_; }
  size_t remaining() const { return size_ - pos_; }
  const uint8_t* current() const { return data_ + pos_; }
  bool Skip(size_t n) {
    if (n > remaining()) return false;
    pos_ += n;
    return true;
  }
  bool U16(uint16_t& v) { return Read(v, 2, LoadLE16); }
  bool U32(uint32_t& v) { return Read(v, 4, LoadLE32); }
  bool U64(uint64_t& v) { return Read(v, 8, LoadLE64); }

 private:
  template <typename T, typename F>
  bool Read(T& v, size_t n, F load) {
    if (n > remaining()) return false;
    v = load(data_ + pos_);
    pos_ += n;
    return true;
  }
  const uint8_t* data_;  // [size_]
  size_t size_;
  size_t pos_ = 0;
};

}  // namespace atex
