// Small JSON helpers shared by the glTF exporter and importer. Internal header.
#pragma once

#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string>

#include <nlohmann/json.hpp>

#include "atex/status.h"

namespace atex::gltf {

// A float as the shortest decimal that converts back to the same float, so the
// JSON stays readable ("0.1") and the round trip stays exact.
inline nlohmann::json FloatJson(float value) {
  char text[64];
  const auto result = std::to_chars(text, text + sizeof text - 1, value);
  *result.ptr = '\0';
  const double shortest = std::strtod(text, nullptr);
  if (static_cast<float>(shortest) == value) return shortest;
  return static_cast<double>(value);
}

// Reads `object[key]` as a non-negative integer index below `limit`; `where` names the
// JSON path for the message (e.g. "ATEX_gaussian_textures.texels").
inline Status ReadIndex(const nlohmann::json& object, const char* key, uint64_t limit, const std::string& where,
                        uint64_t* out) {
  auto it = object.find(key);
  if (it == object.end()) return MakeError(StatusCode::kCorrupt, where, ": missing '", key, "'");
  if (!it->is_number_unsigned() && !(it->is_number_integer() && it->get<int64_t>() >= 0)) {
    return MakeError(StatusCode::kCorrupt, where, ".", key, " is not a non-negative integer");
  }
  const uint64_t value = it->get<uint64_t>();
  if (value >= limit)
    return MakeError(StatusCode::kCorrupt, where, ".", key, " = ", value, " is out of range (", limit, ")");
  *out = value;
  return Status::Ok();
}

// Reads a finite number that fits a float.
inline Status ReadFloatValue(const nlohmann::json& value, const std::string& where, float* out) {
  if (!value.is_number()) return MakeError(StatusCode::kCorrupt, where, " is not a number");
  const double d = value.get<double>();
  const float f = static_cast<float>(d);
  if (!std::isfinite(d) || !std::isfinite(f))
    return MakeError(StatusCode::kOutOfRange, where, " = ", d, " is not a finite float");
  *out = f;
  return Status::Ok();
}

// Reads an integer in [lo, hi].
inline Status ReadIntValue(const nlohmann::json& value, const std::string& where, int64_t lo, int64_t hi,
                           int64_t* out) {
  if (!value.is_number_integer()) return MakeError(StatusCode::kCorrupt, where, " is not an integer");
  const int64_t v =
      value.is_number_unsigned() && value.get<uint64_t>() > uint64_t(INT64_MAX) ? INT64_MAX : value.get<int64_t>();
  if (v < lo || v > hi) return MakeError(StatusCode::kOutOfRange, where, " = ", v, " is outside ", lo, "..", hi);
  *out = v;
  return Status::Ok();
}

}  // namespace atex::gltf
