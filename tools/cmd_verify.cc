// `atex verify FILE [--json]`: every structural rule, every checksum and every
// value of format_spec/atex.md, then ValidateAsset. Exit 0 only when valid.
#include <cstdio>

#include "atex/container.h"
#include "atex/file_io.h"
#include "cli.h"

namespace {

atex::cli::Runner SetupVerify(CLI::App& app) {
  auto path = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  app.add_option("FILE", *path, "The .atex file")->required();
  app.add_flag("--json", *json, "Machine-readable output (also on failure)");
  return [path, json]() {
    auto fail = [&](const atex::Status& status) {
      return atex::cli::Fail("verify", status, *path, {{"file", *path}, {"valid", false}});
    };
    auto bytes = atex::ReadFileBytes(*path);
    if (!bytes.ok()) return fail(bytes.status());
    auto info = atex::InspectContainer(bytes->data(), bytes->size());
    if (!info.ok()) return fail(info.status().WithContext(*path));
    auto asset = atex::DecodeAsset(bytes->data(), bytes->size());  // all CRCs, all values, ValidateAsset
    if (!asset.ok()) return fail(asset.status().WithContext(*path));
    std::vector<std::string> skipped;
    for (const atex::ChunkInfo& c : info->chunks) {
      if (!c.known) skipped.push_back(c.type);
    }
    if (*json) {
      atex::cli::PrintJson({{"file", *path},
                            {"valid", true},
                            {"version", atex::StrCat(info->version_major, ".", info->version_minor)},
                            {"file_size", info->file_size},
                            {"chunks", info->chunks.size()},
                            {"gaussians", asset->gaussians.size()},
                            {"skipped_unknown_chunks", skipped}});
    } else {
      std::printf("OK %s: format %u.%u, %zu bytes, %zu chunks (checksums match), %zu Gaussians, valid asset\n",
                  path->c_str(), info->version_major, info->version_minor, static_cast<size_t>(info->file_size),
                  info->chunks.size(), asset->gaussians.size());
      for (const std::string& type : skipped) {
        std::printf("note: unknown non-critical chunk '%s' skipped (written by a newer minor version)\n", type.c_str());
      }
    }
    return atex::cli::kExitOk;
  };
}

ATEX_REGISTER_COMMAND("verify", "Check an .atex file completely (structure, checksums, values); exit 0 only if valid",
                      SetupVerify);

}  // namespace
