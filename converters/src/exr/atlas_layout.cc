#include "exr/atlas_layout.h"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

namespace atex::converters::exr {

namespace {

constexpr const char* kFormat = "atex-texture-atlas";
constexpr int kVersion = 1;

bool ValidSide(uint64_t v) { return v == 1 || v == 2 || v == 4; }

// Reads a required unsigned integer field.
StatusOr<uint64_t> GetUint(const nlohmann::json& json, const char* key) {
  auto it = json.find(key);
  if (it == json.end()) return MakeError(StatusCode::kCorrupt, "atlas sidecar: missing field '", key, "'");
  if (!it->is_number_unsigned()) {
    return MakeError(StatusCode::kCorrupt, "atlas sidecar: field '", key, "' is not a non-negative integer");
  }
  return it->get<uint64_t>();
}

// Reads a required array of n unsigned integers, each <= max_value.
StatusOr<std::vector<uint32_t>> GetArray(const nlohmann::json& json, const char* key, size_t n, uint64_t max_value) {
  auto it = json.find(key);
  if (it == json.end() || !it->is_array()) {
    return MakeError(StatusCode::kCorrupt, "atlas sidecar: missing array '", key, "'");
  }
  if (it->size() != n) {
    return MakeError(StatusCode::kCorrupt, "atlas sidecar: array '", key, "' has ", it->size(), " entries, count is ",
                     n);
  }
  std::vector<uint32_t> values(n);
  for (size_t i = 0; i < n; ++i) {
    const auto& v = (*it)[i];
    if (!v.is_number_unsigned() || v.get<uint64_t>() > max_value) {
      return MakeError(StatusCode::kOutOfRange, "atlas sidecar: ", key, "[", i, "] = ", v.dump(),
                       " is not an integer in 0..", max_value);
    }
    values[i] = static_cast<uint32_t>(v.get<uint64_t>());
  }
  return values;
}

}  // namespace

int AutoAtlasWidth(uint64_t texels) {
  const double side = std::ceil(std::sqrt(static_cast<double>(std::max<uint64_t>(texels, 1))));
  const int width = static_cast<int>(std::ceil(side / 4.0)) * 4;
  return std::clamp(width, 4, 16384);
}

StatusOr<AtlasLayout> PackShelves(const std::vector<uint8_t>& heights, const std::vector<uint8_t>& widths, int width) {
  if (width < kMaxTextureSide || width > kMaxAtlasSide) {
    return MakeError(StatusCode::kInvalidArgument, "atlas width ", width, " outside ", kMaxTextureSide, "..",
                     kMaxAtlasSide);
  }
  AtlasLayout layout;
  layout.width = width;
  const size_t n = heights.size();
  layout.x.resize(n);
  layout.y.resize(n);
  // One open shelf per block height (1, 2, 4): its top row and the next free column.
  struct Shelf {
    uint64_t y = 0;
    uint32_t cursor = 0;
    bool open = false;
  };
  Shelf shelves[kMaxTextureSide + 1];
  uint64_t next_row = 0;
  for (size_t i = 0; i < n; ++i) {
    const uint8_t h = heights[i], w = widths[i];
    if (!ValidSide(h) || !ValidSide(w)) {
      return MakeError(StatusCode::kInvalidArgument, "texture of Gaussian ", i, " is ", int(h), " x ", int(w),
                       " (sides must be 1, 2 or 4)");
    }
    Shelf& shelf = shelves[h];
    if (!shelf.open || shelf.cursor + w > static_cast<uint32_t>(width)) {
      shelf = {next_row, 0, true};
      next_row += h;
      if (next_row > static_cast<uint64_t>(kMaxAtlasSide)) {
        return MakeError(StatusCode::kLimitExceeded, "atlas of width ", width, " would exceed ", kMaxAtlasSide,
                         " rows at Gaussian ", i, "; choose a wider atlas");
      }
    }
    layout.x[i] = shelf.cursor;
    layout.y[i] = static_cast<uint32_t>(shelf.y);
    shelf.cursor += w;
  }
  layout.height = static_cast<int>(std::max<uint64_t>(next_row, 1));
  return layout;
}

std::string SidecarJson(const AtlasLayout& layout, const TexturePool& pool) {
  nlohmann::json json;
  json["format"] = kFormat;
  json["version"] = kVersion;
  json["atlas_width"] = layout.width;
  json["atlas_height"] = layout.height;
  json["pixel_type"] = "half";
  json["channels"] = {"R", "G", "B", "A"};
  json["texels"] = "raw texture parameters before tanh (docs/conventions.md section 5)";
  json["count"] = pool.size();
  json["x"] = layout.x;
  json["y"] = layout.y;
  json["h"] = pool.heights;
  json["w"] = pool.widths;
  json["axis_u"] = pool.axis_u;
  json["axis_v"] = pool.axis_v;
  return json.dump();
}

Status ParseSidecar(std::string_view text, const ExrAtlasReadOptions& options, AtlasLayout* layout,
                    TexturePool* pool) {
  const nlohmann::json json = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (json.is_discarded() || !json.is_object()) {
    return MakeError(StatusCode::kCorrupt, "atlas sidecar is not a JSON object");
  }
  const auto format = json.find("format");
  if (format == json.end() || !format->is_string() || format->get<std::string>() != kFormat) {
    return MakeError(StatusCode::kBadMagic, "atlas sidecar: 'format' is not \"", kFormat, "\"");
  }
  ATEX_ASSIGN_OR_RETURN(uint64_t version, GetUint(json, "version"));
  if (version != kVersion) {
    return MakeError(StatusCode::kUnsupportedVersion, "atlas sidecar version ", version, " (this reader knows ",
                     kVersion, ")");
  }
  ATEX_ASSIGN_OR_RETURN(uint64_t width, GetUint(json, "atlas_width"));
  ATEX_ASSIGN_OR_RETURN(uint64_t height, GetUint(json, "atlas_height"));
  ATEX_ASSIGN_OR_RETURN(uint64_t count, GetUint(json, "count"));
  if (width < 1 || height < 1 || width > kMaxAtlasSide || height > kMaxAtlasSide ||
      width * height > options.max_pixels) {
    return MakeError(StatusCode::kLimitExceeded, "atlas sidecar: atlas ", width, " x ", height,
                     " outside the reader's limits (", options.max_pixels, " pixels)");
  }
  if (count > options.max_gaussians || count > width * height) {
    return MakeError(StatusCode::kLimitExceeded, "atlas sidecar: ", count, " Gaussians cannot fit a ", width, " x ",
                     height, " atlas (or exceed the reader's limit)");
  }
  const size_t n = static_cast<size_t>(count);
  layout->width = static_cast<int>(width);
  layout->height = static_cast<int>(height);
  ATEX_ASSIGN_OR_RETURN(layout->x, GetArray(json, "x", n, width - 1));
  ATEX_ASSIGN_OR_RETURN(layout->y, GetArray(json, "y", n, height - 1));
  ATEX_ASSIGN_OR_RETURN(std::vector<uint32_t> h, GetArray(json, "h", n, kMaxTextureSide));
  ATEX_ASSIGN_OR_RETURN(std::vector<uint32_t> w, GetArray(json, "w", n, kMaxTextureSide));
  ATEX_ASSIGN_OR_RETURN(std::vector<uint32_t> axis_u, GetArray(json, "axis_u", n, 2));
  ATEX_ASSIGN_OR_RETURN(std::vector<uint32_t> axis_v, GetArray(json, "axis_v", n, 2));
  pool->heights.resize(n);
  pool->widths.resize(n);
  pool->axis_u.resize(n);
  pool->axis_v.resize(n);
  for (size_t i = 0; i < n; ++i) {
    if (!ValidSide(h[i]) || !ValidSide(w[i])) {
      return MakeError(StatusCode::kOutOfRange, "atlas sidecar: Gaussian ", i, " has a ", h[i], " x ", w[i],
                       " block (sides must be 1, 2 or 4)");
    }
    if (axis_u[i] == axis_v[i]) {
      return MakeError(StatusCode::kOutOfRange, "atlas sidecar: Gaussian ", i, " has axis_u = axis_v = ", axis_u[i]);
    }
    if (layout->x[i] + w[i] > width || layout->y[i] + h[i] > height) {
      return MakeError(StatusCode::kOutOfRange, "atlas sidecar: block of Gaussian ", i, " at (", layout->x[i], ", ",
                       layout->y[i], ") size ", w[i], " x ", h[i], " leaves the ", width, " x ", height, " atlas");
    }
    pool->heights[i] = static_cast<uint8_t>(h[i]);
    pool->widths[i] = static_cast<uint8_t>(w[i]);
    pool->axis_u[i] = static_cast<uint8_t>(axis_u[i]);
    pool->axis_v[i] = static_cast<uint8_t>(axis_v[i]);
  }
  pool->RebuildOffsets();
  return Status::Ok();
}

}  // namespace atex::converters::exr
