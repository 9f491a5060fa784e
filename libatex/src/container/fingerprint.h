// Content fingerprints (not part of the public API): what the encode cache (asset_writer.cc)
// keys chunks by, so that an unchanged stream is recognised without quantising and
// comparing its content again.
//
// A fingerprint is 128 bits from four 64-bit lanes of multiply-fold hashing (each step
// multiplies two 64-bit words into 128 bits and folds the halves together), reduced twice
// with different constants. It is no cryptographic hash: two different inputs of the same
// length share a fingerprint with a chance of the order of 2^-64, which is what the encode
// cache relies on (docs/fit.md, "What the fitter caches"). Fast: about as fast as memory reads.
#pragma once

#include <cstddef>
#include <cstdint>
#include <type_traits>
#include <vector>

namespace atex::container {

struct Fingerprint {
  uint64_t a = 0, b = 0;
  friend bool operator==(const Fingerprint&, const Fingerprint&) = default;
};

// Fingerprints a sequence of byte spans: the order of the spans and each span's length count,
// so Add("ab").Add("c") and Add("a").Add("bc") differ.
class FingerprintBuilder {
 public:
  FingerprintBuilder& Add(const void* data, size_t bytes);
  template <typename T>
  FingerprintBuilder& Add(const std::vector<T>& values) {
    static_assert(std::is_trivially_copyable_v<T>);
    return Add(values.data(), values.size() * sizeof(T));
  }
  template <typename T>
  FingerprintBuilder& AddValue(const T& value) {
    static_assert(std::is_trivially_copyable_v<T>);
    return Add(&value, sizeof(T));
  }
  Fingerprint Finish() const;

 private:
  uint64_t a_ = 0x243f6a8885a308d3ull, b_ = 0x13198a2e03707344ull;
  uint64_t spans_ = 0;
};

// A fingerprint of a long span, from blocks hashed on several threads (OpenMP) for spans of
// 4 MiB or more, then the blocks' fingerprints in order. Not FingerprintBuilder().Add(data,
// bytes).Finish(): the two are different functions of the bytes.
Fingerprint BlockFingerprint(const void* data, size_t bytes);

}  // namespace atex::container
