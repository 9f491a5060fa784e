#include <gtest/gtest.h>

#include <limits>

#include "atex/model.h"

namespace atex {
namespace {

Metadata Sample() {
  Metadata m;
  m.bounds_min = {-1.5f, -2.0f, 0.1f};
  m.bounds_max = {3.0f, 4.25f, 7.0f};
  m.time_min = 0.0f;
  m.time_max = 2.5f;
  m.background = {1.0f, 0.5f, 0.0f};
  m.texture_mode = "adaptive";
  m.axes = "opencv";
  m.units = "meters";
  m.extra = {{"trainer", "atex"}, {"steps", 5000}, {"nested", {{"a", {1, 2, 3}}}}};
  return m;
}

TEST(MetadataJson, RoundTrip) {
  const Metadata m = Sample();
  auto back = MetadataFromJson(MetadataToJson(m));
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->bounds_min, m.bounds_min);
  EXPECT_EQ(back->bounds_max, m.bounds_max);
  EXPECT_EQ(back->time_min, m.time_min);
  EXPECT_EQ(back->time_max, m.time_max);
  EXPECT_EQ(back->background, m.background);
  EXPECT_EQ(back->texture_mode, m.texture_mode);
  EXPECT_EQ(back->axes, m.axes);
  EXPECT_EQ(back->units, m.units);
  EXPECT_EQ(back->extra, m.extra);
}

TEST(MetadataJson, RoundTripThroughTextIsExactForAwkwardFloats) {
  Metadata m;
  const float values[] = {0.1f, 1.0f / 3.0f, 16777217.0f, 1e-38f, 3.4028235e38f, -0.0f, 1.17549435e-38f, 7e-45f};
  for (float v : values) {
    m.time_min = v;
    m.time_max = v;
    const std::string text = MetadataToJson(m).dump();
    auto back = MetadataFromJson(nlohmann::json::parse(text));
    ASSERT_TRUE(back.ok()) << text;
    EXPECT_EQ(back->time_min, v) << text;
  }
}

TEST(MetadataJson, FloatsAreWrittenShort) {
  Metadata m;
  m.time_max = 0.1f;
  const std::string text = MetadataToJson(m).dump();
  EXPECT_NE(text.find("\"time_max\":0.1"), std::string::npos) << text;
  EXPECT_EQ(text.find("0.100000001"), std::string::npos) << text;
}

TEST(MetadataJson, MissingKeysTakeDefaults) {
  auto m = MetadataFromJson(nlohmann::json::object());
  ASSERT_TRUE(m.ok());
  EXPECT_EQ(m->texture_mode, "none");
  EXPECT_EQ(m->time_max, 1.0f);
  EXPECT_TRUE(m->extra.is_object());
}

TEST(MetadataJson, UnknownKeysMoveToExtra) {
  nlohmann::json j = MetadataToJson(Sample());
  j["future_key"] = {{"x", 1}};
  j["trainer"] = "would clash";  // extra already has 'trainer': extra wins
  auto m = MetadataFromJson(j);
  ASSERT_TRUE(m.ok());
  EXPECT_EQ(m->extra["future_key"], (nlohmann::json{{"x", 1}}));
  EXPECT_EQ(m->extra["trainer"], "atex");
}

TEST(MetadataJson, WrongTypesAreCorrupt) {
  const std::pair<const char*, nlohmann::json> cases[] = {
      {"bounds_min", "x"},         {"bounds_min", {1, 2}},  {"bounds_max", {1, 2, "3"}}, {"time_min", "0"},
      {"background", nullptr},     {"texture_mode", 3},     {"axes", {1}},              {"units", true},
      {"extra", {1, 2}},
  };
  for (const auto& [key, value] : cases) {
    nlohmann::json j = nlohmann::json::object();
    j[key] = value;
    auto m = MetadataFromJson(j);
    ASSERT_FALSE(m.ok()) << key;
    EXPECT_EQ(m.status().code(), StatusCode::kCorrupt) << key;
    EXPECT_NE(m.status().message().find(key), std::string::npos) << m.status().message();
  }
  EXPECT_EQ(MetadataFromJson(nlohmann::json::array()).status().code(), StatusCode::kCorrupt);
}

TEST(MetadataJson, NumbersBeyondFloatAreOutOfRange) {
  nlohmann::json j = nlohmann::json::object();
  j["time_max"] = 1e39;
  EXPECT_EQ(MetadataFromJson(j).status().code(), StatusCode::kOutOfRange);
  j["time_max"] = std::numeric_limits<double>::infinity();
  EXPECT_EQ(MetadataFromJson(j).status().code(), StatusCode::kOutOfRange);
}

}  // namespace
}  // namespace atex
