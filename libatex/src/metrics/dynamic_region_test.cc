#include "atex/dynamic_region.h"

#include <cmath>

#include <gtest/gtest.h>

namespace atex {
namespace {

// A grey frame with a red 2×2 square whose top-left corner is (x, y).
Image FrameWithSquare(int w, int h, int x, int y) {
  Image im(w, h, 3, 0.5f);
  for (int yy = y; yy < y + 2; ++yy) {
    for (int xx = x; xx < x + 2; ++xx) {
      im.at(xx, yy, 0) = 0.9f;
      im.at(xx, yy, 1) = 0.1f;
      im.at(xx, yy, 2) = 0.1f;
    }
  }
  return im;
}

TEST(DynamicRegion, IsTheUnionOfWhereTheObjectWent) {
  TemporalVariance tv;
  for (int t = 0; t < 4; ++t) ASSERT_TRUE(tv.Add(FrameWithSquare(10, 6, 2 * t, 1)).ok());
  auto region = tv.Region(kDefaultDynamicThreshold);
  ASSERT_TRUE(region.ok()) << region.status().message();
  EXPECT_EQ(region->count, 16u);  // four disjoint 2×2 positions
  for (int y = 0; y < 6; ++y) {
    for (int x = 0; x < 10; ++x) {
      const bool inside = (y == 1 || y == 2) && x < 8;
      EXPECT_EQ(region->mask[y * 10 + x], inside ? 1 : 0) << x << "," << y;
    }
  }
  EXPECT_NEAR(region->fraction(), 16.0 / 60.0, 1e-12);
}

TEST(DynamicRegion, ThresholdIsTheRmsOverChannelsOfTheTemporalStd) {
  // One pixel changes in the red channel only, by d in one of n frames: σ_R = d·sqrt(p(1−p)),
  // σ = σ_R / sqrt(3). Just above and just below that threshold.
  const int n = 30;
  const double d = 0.4, p = 1.0 / n;
  const double sigma = d * std::sqrt(p * (1 - p)) / std::sqrt(3.0);
  TemporalVariance tv;
  for (int t = 0; t < n; ++t) {
    Image im(1, 1, 3, 0.5f);
    if (t == 7) im.at(0, 0, 0) = 0.5f + float(d);
    ASSERT_TRUE(tv.Add(im).ok());
  }
  EXPECT_EQ(tv.Region(sigma * 0.999)->count, 1u);
  EXPECT_EQ(tv.Region(sigma * 1.001)->count, 0u);
}

TEST(DynamicRegion, PsnrCountsOnlyTheRegion) {
  DynamicRegion region{4, 1, {0, 1, 1, 0}, 2};
  Image target(4, 1, 3, 0.5f), rendered(4, 1, 3, 0.5f);
  rendered.at(0, 0, 0) = 0.0f;  // outside: ignored
  rendered.at(1, 0, 1) = 0.6f;  // inside: one channel off by 0.1 of 2 pixels × 3 channels
  auto psnr = RegionPsnr(rendered, target, region);
  ASSERT_TRUE(psnr.ok());
  EXPECT_NEAR(*psnr, 10 * std::log10(6.0 / 0.01), 1e-4);
  rendered.at(1, 0, 1) = 0.5f;
  EXPECT_TRUE(std::isinf(*RegionPsnr(rendered, target, region)));
  rendered.at(2, 0, 2) = 7.0f;  // clamped to 1 before comparing, as every evaluation
  EXPECT_NEAR(*RegionPsnr(rendered, target, region), 10 * std::log10(6.0 / 0.25), 1e-4);
}

TEST(DynamicRegion, RefusesWhatItCannotMeasure) {
  TemporalVariance tv;
  ASSERT_TRUE(tv.Add(Image(4, 3, 3)).ok());
  EXPECT_EQ(tv.Region(0.05).status().code(), StatusCode::kInvalidArgument);  // one frame
  EXPECT_EQ(tv.Add(Image(3, 4, 3)).code(), StatusCode::kInvalidArgument);     // another shape
  EXPECT_EQ(tv.Add(Image(4, 3, 1)).code(), StatusCode::kInvalidArgument);     // grey
  ASSERT_TRUE(tv.Add(Image(4, 3, 3)).ok());
  EXPECT_EQ(tv.Region(-1).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(tv.Region(NAN).status().code(), StatusCode::kInvalidArgument);
  auto empty = tv.Region(0.05);
  ASSERT_TRUE(empty.ok());
  EXPECT_EQ(empty->count, 0u);
  EXPECT_EQ(RegionPsnr(Image(4, 3, 3), Image(4, 3, 3), *empty).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(RegionPsnr(Image(4, 4, 3), Image(4, 3, 3), *empty).status().code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace atex
