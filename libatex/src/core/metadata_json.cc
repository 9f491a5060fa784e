// Metadata <-> JSON, the content of the META chunk (format_spec/atex.md §7.1).
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <limits>

#include "atex/model.h"
#include "atex/world_up.h"

namespace atex {
namespace {

// The JSON number for a float: the shortest decimal that reads back to the same
// float ("0.1", not "0.10000000149011612"), unless the double nearest to that
// decimal would not convert back exactly, in which case the float's exact value.
nlohmann::json FloatToJson(float value) {
  char text[64];
  const auto result = std::to_chars(text, text + sizeof text - 1, value);
  *result.ptr = '\0';
  const double shortest = std::strtod(text, nullptr);
  if (static_cast<float>(shortest) == value) return shortest;
  return static_cast<double>(value);
}

nlohmann::json Vec3ToJson(const std::array<float, 3>& v) {
  return nlohmann::json::array({FloatToJson(v[0]), FloatToJson(v[1]), FloatToJson(v[2])});
}

Status ReadFloat(const nlohmann::json& value, const char* key, float* out) {
  if (!value.is_number()) return MakeError(StatusCode::kCorrupt, "metadata key '", key, "' is not a number");
  const double d = value.get<double>();
  const float f = static_cast<float>(d);
  if (!std::isfinite(d) || !std::isfinite(f)) {
    return MakeError(StatusCode::kOutOfRange, "metadata key '", key, "' = ", d, " is not a finite float");
  }
  *out = f;
  return Status::Ok();
}

Status ReadVec3(const nlohmann::json& value, const char* key, std::array<float, 3>* out) {
  if (!value.is_array() || value.size() != 3) {
    return MakeError(StatusCode::kCorrupt, "metadata key '", key, "' is not an array of 3 numbers");
  }
  for (size_t i = 0; i < 3; ++i) {
    ATEX_RETURN_IF_ERROR(ReadFloat(value[i], key, &(*out)[i]));
  }
  return Status::Ok();
}

Status ReadString(const nlohmann::json& value, const char* key, std::string* out) {
  if (!value.is_string()) return MakeError(StatusCode::kCorrupt, "metadata key '", key, "' is not a string");
  *out = value.get<std::string>();
  return Status::Ok();
}

}  // namespace

nlohmann::json MetadataToJson(const Metadata& metadata) {
  nlohmann::json json = nlohmann::json::object();
  json["bounds_min"] = Vec3ToJson(metadata.bounds_min);
  json["bounds_max"] = Vec3ToJson(metadata.bounds_max);
  json["time_min"] = FloatToJson(metadata.time_min);
  json["time_max"] = FloatToJson(metadata.time_max);
  json["background"] = Vec3ToJson(metadata.background);
  json["texture_mode"] = metadata.texture_mode;
  json["axes"] = metadata.axes;
  json["units"] = metadata.units;
  if (!metadata.up.empty()) json["up"] = metadata.up;  // absent: older readers and golden files unchanged
  json["extra"] = metadata.extra.is_object() ? metadata.extra : nlohmann::json::object();
  return json;
}

StatusOr<Metadata> MetadataFromJson(const nlohmann::json& json) {
  try {
    if (!json.is_object()) return MakeError(StatusCode::kCorrupt, "metadata is not a JSON object");
    Metadata m;
    nlohmann::json unknown = nlohmann::json::object();
    for (auto it = json.begin(); it != json.end(); ++it) {
      const std::string& key = it.key();
      const nlohmann::json& value = it.value();
      if (key == "bounds_min") {
        ATEX_RETURN_IF_ERROR(ReadVec3(value, "bounds_min", &m.bounds_min));
      } else if (key == "bounds_max") {
        ATEX_RETURN_IF_ERROR(ReadVec3(value, "bounds_max", &m.bounds_max));
      } else if (key == "time_min") {
        ATEX_RETURN_IF_ERROR(ReadFloat(value, "time_min", &m.time_min));
      } else if (key == "time_max") {
        ATEX_RETURN_IF_ERROR(ReadFloat(value, "time_max", &m.time_max));
      } else if (key == "background") {
        ATEX_RETURN_IF_ERROR(ReadVec3(value, "background", &m.background));
      } else if (key == "texture_mode") {
        ATEX_RETURN_IF_ERROR(ReadString(value, "texture_mode", &m.texture_mode));
      } else if (key == "axes") {
        ATEX_RETURN_IF_ERROR(ReadString(value, "axes", &m.axes));
      } else if (key == "up") {
        ATEX_RETURN_IF_ERROR(ReadString(value, "up", &m.up));
        if (!IsUpAxisName(m.up)) {
          return MakeError(StatusCode::kCorrupt, "metadata key 'up' = '", m.up,
                           "' is not one of +x, -x, +y, -y, +z, -z");
        }
      } else if (key == "units") {
        ATEX_RETURN_IF_ERROR(ReadString(value, "units", &m.units));
      } else if (key == "extra") {
        if (!value.is_object()) return MakeError(StatusCode::kCorrupt, "metadata key 'extra' is not an object");
        m.extra = value;
      } else {
        unknown[key] = value;  // a newer writer's key: keep it
      }
    }
    for (auto it = unknown.begin(); it != unknown.end(); ++it) {
      if (!m.extra.contains(it.key())) m.extra[it.key()] = it.value();
    }
    return m;
  } catch (const std::exception& e) {
    return MakeError(StatusCode::kCorrupt, "metadata JSON: ", e.what());
  }
}

}  // namespace atex
