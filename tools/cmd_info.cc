// `atex info FILE [--json]`: what an .atex file holds and where its bytes go.
#include <cinttypes>
#include <cstdio>

#include "atex/container.h"
#include "atex/file_io.h"
#include "cli.h"

namespace {

using atex::ChunkInfo;
using atex::ContainerInfo;

double Percent(uint64_t part, uint64_t whole) { return whole == 0 ? 0.0 : 100.0 * static_cast<double>(part) / whole; }

std::string EncodingOf(const std::vector<uint8_t>& bytes, const ChunkInfo& chunk) {
  auto encoding = atex::StreamEncodingOf(bytes.data(), bytes.size(), chunk);
  return encoding.ok() ? atex::ScalarEncodingName(*encoding) : "-";
}

const char* kHeadNames[atex::kNumDeformHeads] = {"position", "scale", "rotation", "opacity", "sh"};

nlohmann::json DeformationJson(const atex::DeformationField& d) {
  const atex::DeformationConfig& c = d.config;
  nlohmann::json heads = nlohmann::json::array();
  for (int h = 0; h < atex::kNumDeformHeads; ++h) {
    if (c.heads[h]) heads.push_back(kHeadNames[h]);
  }
  uint64_t grid_values = 0, mlp_values = 0;
  for (const auto& scale : d.planes) {
    for (const auto& plane : scale) grid_values += plane.size();
  }
  for (const auto& l : d.trunk) mlp_values += l.weight.size() + l.bias.size();
  for (const auto& head : d.heads) {
    for (const auto& l : head) mlp_values += l.weight.size() + l.bias.size();
  }
  return {{"channels", c.grid.channels},   {"base_resolution", c.grid.base_resolution},
          {"multires", c.grid.multires},   {"mlp_width", c.mlp_width},
          {"trunk_layers", c.trunk_layers}, {"heads", heads},
          {"sh_coeffs", c.sh_coeffs},      {"aabb_lo", c.aabb_lo},
          {"aabb_hi", c.aabb_hi},          {"time_scale", c.time_scale},
          {"time_offset", c.time_offset},  {"grid_values", grid_values},
          {"mlp_values", mlp_values}};
}

nlohmann::json ChunkTableJson(const std::vector<uint8_t>& bytes, const ContainerInfo& info) {
  nlohmann::json chunks = nlohmann::json::array();
  for (const ChunkInfo& c : info.chunks) {
    chunks.push_back({{"type", c.type},
                      {"critical", c.critical()},
                      {"known", c.known},
                      {"codec", atex::CodecName(c.codec)},
                      {"encoding", EncodingOf(bytes, c)},
                      {"offset", c.offset},
                      {"stored_size", c.stored_size},
                      {"raw_size", c.raw_size},
                      {"crc32c", c.checksum}});
  }
  return chunks;
}

// Stored size of the texture chunks and the texel encoding, from the table.
void TextureBytes(const std::vector<uint8_t>& bytes, const ContainerInfo& info, uint64_t* stored, size_t* value_bytes) {
  *stored = 0;
  *value_bytes = 4;
  for (const ChunkInfo& c : info.chunks) {
    if (c.type == "TLAY" || c.type == "TEXL") *stored += c.stored_size;
    if (c.type == "TEXL") {
      auto e = atex::StreamEncodingOf(bytes.data(), bytes.size(), c);
      if (e.ok())
        *value_bytes = (*e == atex::ScalarEncoding::kFloat32) ? 4 : (*e == atex::ScalarEncoding::kQuant8) ? 1 : 2;
    }
  }
}

nlohmann::json TexturesJson(const std::vector<uint8_t>& bytes, const ContainerInfo& info, const atex::Asset& asset) {
  if (!asset.textures) return {{"mode", asset.metadata.texture_mode}, {"present", false}};
  const atex::TextureHistogram h = atex::ComputeTextureHistogram(*asset.textures);
  uint64_t stored = 0;
  size_t value_bytes = 4;
  TextureBytes(bytes, info, &stored, &value_bytes);
  nlohmann::json histogram = nlohmann::json::object();
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) histogram[atex::StrCat(1 << a, "x", 1 << b)] = h.counts[a][b];
  }
  return {{"mode", asset.metadata.texture_mode},
          {"present", true},
          {"histogram_hxw", histogram},
          {"texels", h.texels},
          {"uniform_4x4_texels", h.uniform_texels()},
          {"texel_bytes", h.texel_bytes(value_bytes)},
          {"uniform_4x4_texel_bytes", h.uniform_texel_bytes(value_bytes)},
          {"texel_bytes_f32", h.texel_bytes(4)},
          {"uniform_4x4_texel_bytes_f32", h.uniform_texel_bytes(4)},
          {"stored_bytes", stored}};
}

void PrintText(const std::string& path, const std::vector<uint8_t>& bytes, const ContainerInfo& info,
               const atex::Asset& asset) {
  const atex::Gaussians& g = asset.gaussians;
  std::printf("file         %s (%" PRIu64 " bytes), format %u.%u\n", path.c_str(), info.file_size, info.version_major,
              info.version_minor);
  std::printf("gaussians    %zu, SH degree %d (%d coefficients per channel)\n", g.size(), g.sh_degree, g.sh_coeffs());
  const atex::Metadata& m = asset.metadata;
  std::printf("scene        bounds [%g %g %g] .. [%g %g %g], time %g .. %g, units %s, axes %s\n", m.bounds_min[0],
              m.bounds_min[1], m.bounds_min[2], m.bounds_max[0], m.bounds_max[1], m.bounds_max[2], m.time_min,
              m.time_max, m.units.c_str(), m.axes.c_str());
  if (asset.textures) {
    const atex::TextureHistogram h = atex::ComputeTextureHistogram(*asset.textures);
    uint64_t stored = 0;
    size_t value_bytes = 4;
    TextureBytes(bytes, info, &stored, &value_bytes);
    std::printf("textures     %s: %" PRIu64 " texels = %.1f%% of uniform 4x4 (%" PRIu64 ")\n", m.texture_mode.c_str(),
                h.texels, Percent(h.texels, h.uniform_texels()), h.uniform_texels());
    std::printf("             texel bytes %" PRIu64 " vs uniform 4x4 %" PRIu64 " (%zu byte(s) per channel); "
                "stored TLAY+TEXL %" PRIu64 " bytes\n",
                h.texel_bytes(value_bytes), h.uniform_texel_bytes(value_bytes), value_bytes, stored);
    std::printf("             h\\w %10s %10s %10s\n", "1", "2", "4");
    for (int a = 0; a < 3; ++a) {
      std::printf("             %-3d %10" PRIu64 " %10" PRIu64 " %10" PRIu64 "\n", 1 << a, h.counts[a][0],
                  h.counts[a][1], h.counts[a][2]);
    }
  } else {
    std::printf("textures     none\n");
  }
  if (asset.deformation) {
    const nlohmann::json d = DeformationJson(*asset.deformation);
    const atex::DeformationConfig& c = asset.deformation->config;
    std::string multires, heads;
    for (int s : c.grid.multires) multires += atex::StrCat(multires.empty() ? "" : ",", s);
    for (const auto& h : d["heads"]) heads += atex::StrCat(heads.empty() ? "" : ",", h.get<std::string>());
    std::printf("deformation  HexPlane C=%d, base %dx%dx%d, t %d, multires [%s]: %" PRIu64 " grid values\n",
                c.grid.channels, c.grid.base_resolution[0], c.grid.base_resolution[1], c.grid.base_resolution[2],
                c.grid.base_resolution[3], multires.c_str(), d["grid_values"].get<uint64_t>());
    std::printf("             MLP width %d, %d trunk layer(s), heads %s: %" PRIu64 " weights; t_norm = %g t %+g\n",
                c.mlp_width, c.trunk_layers, heads.empty() ? "none" : heads.c_str(), d["mlp_values"].get<uint64_t>(),
                c.time_scale, c.time_offset);
  } else {
    std::printf("deformation  none (static)\n");
  }
  std::printf("statistics   %s\n", asset.stats ? "present" : "none");
  std::printf("\nchunks\n  %-3s %-5s %-4s %-19s %-4s %12s %12s %7s %10s\n", "#", "type", "crit", "codec", "enc",
              "stored", "raw", "ratio", "offset");
  for (size_t i = 0; i < info.chunks.size(); ++i) {
    const ChunkInfo& c = info.chunks[i];
    const double ratio =
        c.stored_size == 0 ? 0.0 : static_cast<double>(c.raw_size) / static_cast<double>(c.stored_size);
    std::printf("  %-3zu %-5s %-4s %-19s %-4s %12" PRIu64 " %12" PRIu64 " %6.2fx %10" PRIu64 "%s\n", i, c.type.c_str(),
                c.critical() ? "yes" : "no", atex::CodecName(c.codec).c_str(), EncodingOf(bytes, c).c_str(),
                c.stored_size, c.raw_size, ratio, c.offset, c.known ? "" : "  (unknown, skipped)");
  }
  std::printf("\nbytes per component (TOC entry + stored bytes + padding)\n");
  const double per = g.size() > 0 ? 1.0 / static_cast<double>(g.size()) : 0.0;
  for (const atex::ComponentSize& c : atex::ComponentBytes(info)) {
    std::printf("  %-12s %12" PRIu64 "  %5.1f%%  %8.2f bytes/Gaussian\n", c.component.c_str(), c.bytes,
                Percent(c.bytes, info.file_size), static_cast<double>(c.bytes) * per);
  }
}

atex::cli::Runner SetupInfo(CLI::App& app) {
  auto path = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  app.add_option("FILE", *path, "The .atex file")->required();
  app.add_flag("--json", *json, "Machine-readable output");
  return [path, json]() {
    auto bytes = atex::ReadFileBytes(*path);
    if (!bytes.ok()) return atex::cli::Fail("info", bytes.status(), *path);
    auto info = atex::InspectContainer(bytes->data(), bytes->size());
    if (!info.ok()) return atex::cli::Fail("info", info.status().WithContext(*path), *path);
    auto asset = atex::DecodeAsset(bytes->data(), bytes->size());
    if (!asset.ok()) {
      // The table is still useful to see which chunk is damaged.
      if (*json) {
        atex::cli::PrintJson({{"file", *path}, {"chunks", ChunkTableJson(*bytes, *info)},
                              {"error", asset.status().ToString()}});
      }
      return atex::cli::Fail("info", asset.status().WithContext(*path), *path);
    }
    if (!*json) {
      PrintText(*path, *bytes, *info, *asset);
      return atex::cli::kExitOk;
    }
    const atex::Gaussians& g = asset->gaussians;
    nlohmann::json components = nlohmann::json::array();
    for (const atex::ComponentSize& c : atex::ComponentBytes(*info)) {
      components.push_back({{"component", c.component},
                            {"bytes", c.bytes},
                            {"bytes_per_gaussian", g.size() ? static_cast<double>(c.bytes) / g.size() : 0.0}});
    }
    atex::cli::PrintJson({
        {"file", *path},
        {"file_size", info->file_size},
        {"version", atex::StrCat(info->version_major, ".", info->version_minor)},
        {"gaussians", g.size()},
        {"sh_degree", g.sh_degree},
        {"textures", TexturesJson(*bytes, *info, *asset)},
        {"deformation", asset->deformation ? DeformationJson(*asset->deformation) : nlohmann::json(nullptr)},
        {"stats", asset->stats.has_value()},
        {"metadata", atex::MetadataToJson(asset->metadata)},
        {"chunks", ChunkTableJson(*bytes, *info)},
        {"components", components},
    });
    return atex::cli::kExitOk;
  };
}

ATEX_REGISTER_COMMAND("info", "Summarise an .atex file: counts, textures, deformation, chunks, bytes per component",
                      SetupInfo);

}  // namespace
