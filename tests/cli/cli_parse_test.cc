// The strict option parser of every `atex` command (tools/cli_parse.h): whole tokens,
// finite numbers, ranges, sizes without wrap-around, byte sizes, view specs.
#include "cli_parse.h"

#include <gtest/gtest.h>

namespace atex::cli {
namespace {

TEST(CliParse, IntegersAreWholeTokensInRange) {
  EXPECT_EQ(*ParseInteger("12", 0, 100, "--n"), 12);
  EXPECT_EQ(*ParseInteger("+3", 0, 100, "--n"), 3);
  EXPECT_EQ(*ParseInteger("-2", -5, 5, "--n"), -2);
  for (const char* bad : {"", "1abc", "1.0", "1e3", "0x10", " 1", "1 ", "+", "++1", "+-1", "nan"}) {
    auto v = ParseInteger(bad, 0, 100000, "--n");
    EXPECT_EQ(v.status().code(), StatusCode::kInvalidArgument) << bad;
    EXPECT_NE(v.status().message().find("--n"), std::string::npos) << bad;
  }
  EXPECT_EQ(ParseInteger("0", 1, 10, "--repeats").status().code(), StatusCode::kOutOfRange);
  EXPECT_EQ(ParseInteger("99999999999999999999999", 0, 10, "--n").status().code(), StatusCode::kOutOfRange);
}

TEST(CliParse, RealsAreFiniteWholeTokensInRange) {
  EXPECT_DOUBLE_EQ(*ParseReal("0.25", 0, 1, "--keep-count"), 0.25);
  EXPECT_DOUBLE_EQ(*ParseReal("1e-3", 0, 1, "--x"), 1e-3);
  EXPECT_DOUBLE_EQ(*ParseReal("+2", 0, 10, "--x"), 2.0);
  for (const char* bad : {"nan", "NaN", "inf", "-inf", "infinity", "1e999"}) {
    EXPECT_FALSE(ParseReal(bad, -1e300, 1e300, "--time").ok()) << bad;
  }
  for (const char* bad : {"", ".", "0.5x", "1,5", "0x1p3", " 1"}) {
    EXPECT_EQ(ParseReal(bad, -10, 10, "--time").status().code(), StatusCode::kInvalidArgument) << bad;
  }
  EXPECT_EQ(ParseReal("1.5", 0, 1, "--keep-count").status().code(), StatusCode::kOutOfRange);
}

TEST(CliParse, ImageSizesNeverWrap) {
  auto size = ParseImageSize("1352x1014", "--size");
  ASSERT_TRUE(size.ok());
  EXPECT_EQ(size->width, 1352);
  EXPECT_EQ(size->height, 1014);
  // 4294967344 = 2^32 + 48: sscanf("%d") made it 48.
  EXPECT_EQ(ParseImageSize("4294967344x48", "--size").status().code(), StatusCode::kOutOfRange);
  for (const char* bad : {"0x10", "10x0", "10", "10x", "x10", "10x10x10", "-5x5", "10X10", "1e3x10"}) {
    EXPECT_FALSE(ParseImageSize(bad, "--size").ok()) << bad;
  }
}

TEST(CliParse, ByteSizesAndLists) {
  EXPECT_EQ(*ParseByteSize("102400", "--budget"), 102400u);
  EXPECT_EQ(*ParseByteSize("80MiB", "--budget"), 80u * 1048576u);
  EXPECT_EQ(*ParseByteSize("80 MB", "--budget"), 80000000u);
  EXPECT_EQ(*ParseByteSize("1.5GiB", "--budget"), 1610612736u);
  for (const char* bad : {".", "", "MiB", "1.2.3MB", "-5MB", "0", "0.2", "12XB", "80  MB", "nan", "1e3"}) {
    EXPECT_FALSE(ParseByteSize(bad, "--budget").ok()) << bad;
  }
  std::vector<std::string> pieces;
  auto list = ParseByteSizeList("1MiB,2MiB", "--budget", &pieces);
  ASSERT_TRUE(list.ok());
  EXPECT_EQ(list->size(), 2u);
  EXPECT_EQ(pieces[1], "2MiB");
  auto duplicate = ParseByteSizeList("100KiB,102400", "--budget");
  EXPECT_EQ(duplicate.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(duplicate.status().message().find("102400"), std::string::npos);
  EXPECT_FALSE(ParseByteSizeList("1MiB,", "--budget").ok());
}

TEST(CliParse, ViewSpecs) {
  auto v = ParseViewSpec("test:3", "--view");
  ASSERT_TRUE(v.ok());
  EXPECT_EQ(v->split, "test");
  EXPECT_EQ(v->index, 3u);
  for (const char* bad : {"test:1abc", "test:", "test", "val:1", "train:-1", "test:1.0", ":1"}) {
    EXPECT_FALSE(ParseViewSpec(bad, "--view").ok()) << bad;
  }
}

TEST(CliParse, OptionsThrowValidationErrorsNamingTheOption) {
  CLI::App app;
  int repeats = 100;
  double time = 0;
  std::vector<int> cameras;
  AddInt(app, "--repeats", &repeats, 1, 1000, "timed renders");
  AddReal(app, "--time", &time, -10, 10, "scene time");
  AddIntList(app, "--test-cameras", &cameras, 0, 100, "ids");
  app.parse(std::vector<std::string>{"1,2", "--test-cameras", "0.5", "--time", "7", "--repeats"});
  EXPECT_EQ(repeats, 7);
  EXPECT_DOUBLE_EQ(time, 0.5);
  EXPECT_EQ(cameras, (std::vector<int>{1, 2}));
  CLI::App strict;
  AddInt(strict, "--repeats", &repeats, 1, 1000, "timed renders");
  try {
    strict.parse(std::vector<std::string>{"0", "--repeats"});
    FAIL() << "--repeats 0 was accepted";
  } catch (const CLI::ValidationError& e) {
    EXPECT_NE(std::string(e.what()).find("--repeats"), std::string::npos) << e.what();
  }
  CLI::App nan_time;
  AddReal(nan_time, "--time", &time, -10, 10, "scene time");
  EXPECT_THROW(nan_time.parse(std::vector<std::string>{"nan", "--time"}), CLI::ValidationError);
}

}  // namespace
}  // namespace atex::cli
