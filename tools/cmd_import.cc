// `atex import IN.glb|IN.gltf OUT.atex`: reads our glTF back without loss, or another
// tool's KHR_gaussian_splatting file (base attributes). Front end over
// atex/converters/gltf.h and atex/container.h.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>

#include "atex/container.h"
#include "atex/converters/gltf.h"
#include "cli.h"

namespace {

struct ImportArgs {
  std::string input, output;
  bool json = false, force = false;
};

int RunImport(const ImportArgs& a) {
  const auto start = std::chrono::steady_clock::now();
  // A .gltf reads its buffers from files beside it: no output may be the input or one of them
  // (the .atex extension keeps an output off a .bin buffer).
  if (atex::Status s = atex::cli::CheckOutput(a.output, a.force, {{a.input}, {".atex"}, "output", false}); !s.ok()) {
    return atex::cli::Fail("import", s, a.output);
  }
  auto asset = atex::ReadGltfFile(a.input);
  if (!asset.ok()) return atex::cli::Fail("import", asset.status(), a.input);
  atex::Status s = atex::WriteAssetFile(a.output, *asset);
  if (!s.ok()) return atex::cli::Fail("import", s, a.output);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  nlohmann::json summary = {{"input", a.input},
                            {"output", a.output},
                            {"gaussians", asset->gaussians.size()},
                            {"sh_degree", asset->gaussians.sh_degree},
                            {"textures", asset->textures.has_value()},
                            {"deformation", asset->deformation.has_value()},
                            {"axes", asset->metadata.axes},
                            {"bytes", std::filesystem::file_size(a.output)},
                            {"seconds", seconds}};
  if (a.json) {
    atex::cli::PrintJson(summary);
  } else {
    std::printf("%s -> %s: %llu Gaussians (SH %d)%s%s, %.3f s\n", a.input.c_str(), a.output.c_str(),
                static_cast<unsigned long long>(asset->gaussians.size()), asset->gaussians.sh_degree,
                asset->textures ? ", textures" : "", asset->deformation ? ", deformation" : "", seconds);
  }
  return atex::cli::kExitOk;
}

atex::cli::Runner SetupImport(CLI::App& app) {
  auto a = std::make_shared<ImportArgs>();
  app.add_option("input", a->input, "glTF file (.glb or .gltf) with KHR_gaussian_splatting")->required();
  app.add_option("output", a->output, "Asset to write (.atex)")->required();
  atex::cli::AddForceFlag(app, &a->force);
  app.add_flag("--json", a->json, "Print a machine-readable summary");
  return [a]() { return RunImport(*a); };
}

ATEX_REGISTER_COMMAND("import", "Import a glTF (KHR_gaussian_splatting, with our extensions if present) into .atex",
                      SetupImport);

}  // namespace
