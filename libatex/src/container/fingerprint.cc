// Content fingerprints (fingerprint.h).
#include "container/fingerprint.h"

#include <cstring>
#ifdef _OPENMP
#include <omp.h>
#endif

namespace atex::container {
namespace {

// Constants with well-spread bits (hexadecimal digits of pi and e).
constexpr uint64_t kLane[4] = {0xa4093822299f31d0ull, 0x082efa98ec4e6c89ull, 0x452821e638d01377ull,
                               0xbe5466cf34e90c6cull};
constexpr uint64_t kFinishA = 0xc0ac29b7c97c50ddull, kFinishB = 0x3f84d5b5b5470917ull;
constexpr uint64_t kMixA = 0x9216d5d98979fb1bull, kMixB = 0xb7e151628aed2a6bull;

// The 128-bit product of x and y with its halves folded together.
inline uint64_t Fold(uint64_t x, uint64_t y) {
  const unsigned __int128 p = static_cast<unsigned __int128>(x) * y;
  return static_cast<uint64_t>(p) ^ static_cast<uint64_t>(p >> 64);
}

inline uint64_t Load(const uint8_t* p) {
  uint64_t v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

// Four independent lanes over 64-byte blocks (the multiplies of a block overlap), the last
// partial block zero-padded; the length goes into the reduction.
void HashSpan(const uint8_t* p, size_t n, uint64_t* out_a, uint64_t* out_b) {
  uint64_t lane[4] = {kLane[0] ^ n, kLane[1], kLane[2], kLane[3]};
  const auto block = [&lane](const uint8_t* q) {
    for (int j = 0; j < 4; ++j) lane[j] = Fold(Load(q + 16 * j) ^ kLane[j], Load(q + 16 * j + 8) ^ lane[j]);
  };
  size_t i = 0;
  for (; i + 64 <= n; i += 64) block(p + i);
  if (i < n) {
    uint8_t tail[64] = {};
    std::memcpy(tail, p + i, n - i);
    block(tail);
  }
  *out_a = Fold(lane[0] ^ lane[2] ^ kFinishA, lane[1] ^ lane[3] ^ n);
  *out_b = Fold(lane[0] ^ lane[1] ^ kFinishB, lane[2] ^ lane[3] ^ (n * kMixA));
}

}  // namespace

FingerprintBuilder& FingerprintBuilder::Add(const void* data, size_t bytes) {
  uint64_t a = 0, b = 0;
  HashSpan(static_cast<const uint8_t*>(data), bytes, &a, &b);
  ++spans_;
  a_ = Fold(a_ ^ a ^ kMixA, spans_ ^ kLane[0]);
  b_ = Fold(b_ ^ b ^ kMixB, spans_ ^ kLane[1]);
  return *this;
}

Fingerprint FingerprintBuilder::Finish() const {
  return Fingerprint{Fold(a_ ^ kFinishA, spans_ ^ kMixB), Fold(b_ ^ kFinishB, spans_ ^ kMixA)};
}

Fingerprint BlockFingerprint(const void* data, size_t bytes) {
  const auto* p = static_cast<const uint8_t*>(data);
  const int64_t blocks = bytes >= (size_t{4} << 20) ? 64 : 1;
  std::vector<Fingerprint> parts(static_cast<size_t>(blocks));
#ifdef _OPENMP
#pragma omp parallel for schedule(static) if (blocks > 1 && !omp_in_parallel())
#endif
  for (int64_t b = 0; b < blocks; ++b) {
    const size_t begin = bytes * static_cast<size_t>(b) / static_cast<size_t>(blocks);
    const size_t end = bytes * static_cast<size_t>(b + 1) / static_cast<size_t>(blocks);
    parts[static_cast<size_t>(b)] = FingerprintBuilder().Add(p + begin, end - begin).Finish();
  }
  FingerprintBuilder whole;
  whole.AddValue(uint64_t{bytes});
  for (const Fingerprint& part : parts) whole.AddValue(part);
  return whole.Finish();
}

}  // namespace atex::container
