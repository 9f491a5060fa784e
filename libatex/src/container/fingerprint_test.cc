// Content fingerprints (fingerprint.h): equal content, equal fingerprint; any change of a
// byte, a length or a span boundary, a different one.
#include "container/fingerprint.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <set>
#include <utility>
#include <vector>

namespace atex::container {
namespace {

std::pair<uint64_t, uint64_t> Key(const Fingerprint& f) { return {f.a, f.b}; }

TEST(Fingerprint, EqualContentGivesEqualFingerprints) {
  std::vector<float> a(1000), b(1000);
  for (size_t i = 0; i < a.size(); ++i) a[i] = b[i] = 0.5f * static_cast<float>(i);
  EXPECT_EQ(FingerprintBuilder().Add(a).Finish(), FingerprintBuilder().Add(b).Finish());
  EXPECT_EQ(FingerprintBuilder().Add(a).AddValue(3).Finish(), FingerprintBuilder().Add(b).AddValue(3).Finish());
}

// Every single-bit change, at every position of a buffer that covers whole 64-byte blocks and a
// partial one, gives a fingerprint of its own (none equal to another or to the original's).
TEST(Fingerprint, EveryBitFlipChangesIt) {
  std::vector<uint8_t> bytes(200);
  for (size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<uint8_t>(i * 37 + 11);
  std::set<std::pair<uint64_t, uint64_t>> seen{Key(FingerprintBuilder().Add(bytes).Finish())};
  for (size_t i = 0; i < bytes.size(); ++i) {
    for (int bit = 0; bit < 8; ++bit) {
      std::vector<uint8_t> changed = bytes;
      changed[i] ^= static_cast<uint8_t>(1u << bit);
      EXPECT_TRUE(seen.insert(Key(FingerprintBuilder().Add(changed).Finish())).second) << i << " " << bit;
    }
  }
}

TEST(Fingerprint, LengthsAndSpanBoundariesCount) {
  const std::vector<uint8_t> zeros(128, 0);
  std::set<std::pair<uint64_t, uint64_t>> seen;
  for (size_t n = 0; n <= zeros.size(); ++n) {  // zero-padded tails must not make lengths equal
    EXPECT_TRUE(seen.insert(Key(FingerprintBuilder().Add(zeros.data(), n).Finish())).second) << n;
  }
  const char text[] = "abc";
  const Fingerprint one = FingerprintBuilder().Add(text, 3).Finish();
  const Fingerprint split = FingerprintBuilder().Add(text, 1).Add(text + 1, 2).Finish();
  const Fingerprint other_split = FingerprintBuilder().Add(text, 2).Add(text + 2, 1).Finish();
  EXPECT_FALSE(one == split);
  EXPECT_FALSE(split == other_split);
  EXPECT_FALSE(FingerprintBuilder().Finish() == FingerprintBuilder().Add(text, 0).Finish());
}

// Float streams that differ in one value (as a fit's candidate streams do) never collide here.
TEST(Fingerprint, StreamsDifferingInOneValueDiffer) {
  std::vector<float> values(4096);
  for (size_t i = 0; i < values.size(); ++i) values[i] = static_cast<float>(i % 17) * 0.25f - 1.0f;
  std::set<std::pair<uint64_t, uint64_t>> seen{Key(FingerprintBuilder().Add(values).Finish())};
  for (size_t i = 0; i < values.size(); i += 7) {
    std::vector<float> changed = values;
    changed[i] = std::nextafter(changed[i], 10.0f);
    EXPECT_TRUE(seen.insert(Key(FingerprintBuilder().Add(changed).Finish())).second) << i;
  }
}

}  // namespace
}  // namespace atex::container
