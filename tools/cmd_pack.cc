// `atex pack IN OUT [options]`: re-encode an .atex file with other codecs and
// scalar encodings, and report the sizes before and after. Attributes without an
// option (and those whose option is `keep`, the default) keep the input file's
// encoding, so a pack never loses precision that was not asked for.
#include <cinttypes>
#include <cstdio>
#include <map>

#include "atex/container.h"
#include "atex/file_io.h"
#include "cli.h"

namespace {

struct PackOptions {
  std::string in, out;
  std::string codec = "shuffle-zstd";
  std::string positions = "keep";
  std::string texels = "keep";
  std::string sh = "keep";
  int level = 3;
  bool json = false, force = false;
};

const std::map<std::string, atex::Codec> kCodecs = {{"raw", atex::Codec::kRaw},
                                                    {"zstd", atex::Codec::kZstd},
                                                    {"shuffle-zstd", atex::Codec::kShuffleZstd},
                                                    {"delta-shuffle-zstd", atex::Codec::kDeltaShuffleZstd}};
const std::map<std::string, atex::ScalarEncoding> kEncodings = {{"f32", atex::ScalarEncoding::kFloat32},
                                                                {"f16", atex::ScalarEncoding::kFloat16},
                                                                {"q16", atex::ScalarEncoding::kQuant16},
                                                                {"q8", atex::ScalarEncoding::kQuant8}};

// WriteOptions that reproduce the input's scalar encodings (and Draco positions).
atex::WriteOptions InputEncodings(const std::vector<uint8_t>& bytes) {
  atex::WriteOptions w;
  auto info = atex::InspectContainer(bytes.data(), bytes.size());
  if (!info.ok()) return w;
  const std::map<std::string, atex::ScalarEncoding*> fields = {
      {"GPOS", &w.positions}, {"GROT", &w.rotations}, {"GSCL", &w.log_scales}, {"GOPA", &w.opacities},
      {"GSH0", &w.sh_dc},     {"GSHR", &w.sh_rest},   {"TEXL", &w.texels},     {"DGRD", &w.deformation_grids}};
  for (const atex::ChunkInfo& c : info->chunks) {
    auto field = fields.find(c.type);
    if (field == fields.end()) continue;
    auto encoding = atex::StreamEncodingOf(bytes.data(), bytes.size(), c);
    if (encoding.ok()) *field->second = *encoding;
    if (c.type == "GPOS" && c.codec == atex::Codec::kDraco) w.draco_positions = true;
  }
  return w;
}

nlohmann::json Components(const std::vector<uint8_t>& bytes) {
  nlohmann::json out = nlohmann::json::object();
  auto info = atex::InspectContainer(bytes.data(), bytes.size());
  if (!info.ok()) return out;
  for (const atex::ComponentSize& c : atex::ComponentBytes(*info)) out[c.component] = c.bytes;
  return out;
}

atex::cli::Runner SetupPack(CLI::App& app) {
  auto o = std::make_shared<PackOptions>();
  app.add_option("IN", o->in, "Input .atex file")->required();
  app.add_option("OUT", o->out, "Output .atex file (written atomically)")->required();
  app.add_option("--codec", o->codec, "Chunk codec")
      ->check(CLI::IsMember({"raw", "zstd", "shuffle-zstd", "delta-shuffle-zstd"}))
      ->capture_default_str();
  app.add_option("--positions", o->positions, "Position encoding (draco: Draco point-cloud codec; keep: as in IN)")
      ->check(CLI::IsMember({"keep", "f32", "f16", "q16", "q8", "draco"}))
      ->capture_default_str();
  app.add_option("--texels", o->texels, "Texel encoding (q8: 8 bits with per-channel scale/offset; keep: as in IN)")
      ->check(CLI::IsMember({"keep", "f32", "f16", "q8"}))
      ->capture_default_str();
  app.add_option("--sh", o->sh, "SH coefficient encoding, DC and rest (keep: as in IN)")
      ->check(CLI::IsMember({"keep", "f32", "f16", "q8"}))
      ->capture_default_str();
  app.add_option("--level", o->level, "zstd level")->check(CLI::Range(-7, 22))->capture_default_str();
  app.add_flag("--json", o->json, "Machine-readable output");
  atex::cli::AddForceFlag(app, &o->force);
  return [o]() {
    // The input is read whole before the atomic write: in == out is allowed with --force.
    if (atex::Status s = atex::cli::CheckOutput(o->out, o->force, {{o->in}, {".atex"}, "OUT"}); !s.ok()) {
      return atex::cli::Fail("pack", s, o->out);
    }
    auto in_bytes = atex::ReadFileBytes(o->in);
    if (!in_bytes.ok()) return atex::cli::Fail("pack", in_bytes.status(), o->in);
    auto asset = atex::DecodeAsset(in_bytes->data(), in_bytes->size());
    if (!asset.ok()) return atex::cli::Fail("pack", asset.status().WithContext(o->in), o->in);
    atex::WriteOptions w = InputEncodings(*in_bytes);
    w.codec = kCodecs.at(o->codec);
    w.zstd_level = o->level;
    if (o->positions == "draco") {
      w.draco_positions = true;
    } else if (o->positions != "keep") {
      w.draco_positions = false;
      w.positions = kEncodings.at(o->positions);
    }
    if (o->texels != "keep") w.texels = kEncodings.at(o->texels);
    if (o->sh != "keep") w.sh_dc = w.sh_rest = kEncodings.at(o->sh);
    auto out_bytes = atex::EncodeAsset(*asset, w);
    if (!out_bytes.ok()) return atex::cli::Fail("pack", out_bytes.status());
    const atex::Status written = atex::WriteFileAtomic(o->out, *out_bytes);
    if (!written.ok()) return atex::cli::Fail("pack", written, o->out);
    const double ratio = out_bytes->empty() ? 0.0 : static_cast<double>(in_bytes->size()) / out_bytes->size();
    if (o->json) {
      atex::cli::PrintJson({{"in", o->in},
                            {"out", o->out},
                            {"in_bytes", in_bytes->size()},
                            {"out_bytes", out_bytes->size()},
                            {"ratio", ratio},
                            {"options",
                             {{"codec", o->codec}, {"positions", o->positions}, {"texels", o->texels}, {"sh", o->sh},
                              {"level", o->level}}},
                            {"in_components", Components(*in_bytes)},
                            {"out_components", Components(*out_bytes)}});
    } else {
      std::printf("packed %s (%zu bytes) -> %s (%zu bytes, %.1f%% of the input)\n", o->in.c_str(), in_bytes->size(),
                  o->out.c_str(), out_bytes->size(), 100.0 / ratio);
      std::printf("  codec %s, positions %s, texels %s, SH %s, zstd level %d\n", o->codec.c_str(), o->positions.c_str(),
                  o->texels.c_str(), o->sh.c_str(), o->level);
      const nlohmann::json before = Components(*in_bytes), after = Components(*out_bytes);
      std::printf("  %-12s %12s %12s\n", "component", "before", "after");
      for (auto it = after.begin(); it != after.end(); ++it) {
        const uint64_t b = before.contains(it.key()) ? before[it.key()].get<uint64_t>() : 0;
        std::printf("  %-12s %12" PRIu64 " %12" PRIu64 "\n", it.key().c_str(), b, it.value().get<uint64_t>());
      }
    }
    return atex::cli::kExitOk;
  };
}

ATEX_REGISTER_COMMAND("pack", "Re-encode an .atex file with other codecs/encodings and print the sizes", SetupPack);

}  // namespace
