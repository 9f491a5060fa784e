// Assertions shared by the tests of `atex convert` (frames_test.cc, fourdgs_convert_test.cc).
// Header-only, tests only.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "core/test_support.h"

namespace atex::converters::testing {

// gmock's HasSubstr without linking gmock.
inline ::testing::AssertionResult HasText(const std::string& text, const std::string& part) {
  if (text.find(part) != std::string::npos) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "'" << text << "' does not contain '" << part << "'";
}

inline void ExpectBitEqual(const std::vector<float>& a, const std::vector<float>& b, const std::string& what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  for (size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(std::bit_cast<uint32_t>(a[i]), std::bit_cast<uint32_t>(b[i])) << what << "[" << i << "]";
  }
}

inline double MaxAbsDiff(const std::vector<float>& a, const std::vector<float>& b) {
  double worst = 0;
  for (size_t i = 0; i < std::min(a.size(), b.size()); ++i) worst = std::max(worst, std::fabs(double(a[i]) - b[i]));
  return worst;
}

// The committed 4DGaussians output (tests/fixtures/fourdgs, made by its make_fixture.py).
inline std::filesystem::path FourDgsFixtureDir() { return atex::testing::SourceDir() / "tests/fixtures/fourdgs"; }

}  // namespace atex::converters::testing
