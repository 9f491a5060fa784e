// The player scenes of atex_web_fixture (see web_fixture_player.h).
#include "web_fixture_player.h"

#include <algorithm>

#include "atex/converters/gltf.h"
#include "atex/deform.h"
#include "atex/file_io.h"
#include "atex/image.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace atex::web_fixture {

Status WriteText(const fs::path& path, const std::string& text) {
  return WriteFileAtomic(path.string(), text.data(), text.size());
}

Status RenderReference(const Asset& asset, const Camera& camera, const fs::path& png) {
  RenderSettings settings;
  settings.background = asset.metadata.background;
  auto out = RenderForward(camera, asset.gaussians, asset.textures ? &*asset.textures : nullptr, settings);
  if (!out.ok()) return out.status();
  Image image = RenderedImage(*out);
  for (float& v : image.pixels) v = std::clamp(v, 0.0f, 1.0f);
  return WriteImage(png.string(), image);
}

ConvertOptions SpzV3() {
  ConvertOptions options;
  options.spz_version = 3;
  return options;
}

json CameraJson(const Camera& c) {
  return {{"width", c.width}, {"height", c.height}, {"fx", c.fx}, {"fy", c.fy}, {"cx", c.cx}, {"cy", c.cy}};
}

StatusOr<json> WritePlayerScene(const fs::path& out, const std::string& stem, const Asset& asset,
                                const Dataset& dataset, const View& view, bool variants) {
  const auto file = [&](const std::string& suffix) { return stem + suffix; };
  const auto at = [&](const std::string& suffix) { return (out / file(suffix)).string(); };
  ATEX_ASSIGN_OR_RETURN(auto truth, dataset.LoadImage(view));
  if (!asset.deformation) return MakeError(StatusCode::kInvalidArgument, stem, ": the asset has no deformation");
  Asset baked;
  baked.metadata = asset.metadata;
  baked.textures = asset.textures;
  ATEX_RETURN_IF_ERROR(DeformForward(*asset.deformation, asset.gaussians, view.camera.time, &baked.gaussians, nullptr));
  GltfExportOptions options;
  options.time = view.camera.time;
  ATEX_RETURN_IF_ERROR(WriteGltfFile(at(".glb"), asset, options));
  if (variants) {
    // Issue 21 item 5: the textures baked into plain Gaussians (`--bake-textures`).
    GltfExportOptions baked_options = options;
    baked_options.bake_textures = true;
    ATEX_RETURN_IF_ERROR(WriteGltfFile(at("_baked.glb"), asset, baked_options));
    // The same as `atex export --quantize [--meshopt]` writes it (KHR_mesh_quantization).
    GltfExportOptions quantized = options;
    quantized.quantize = true;
    ATEX_RETURN_IF_ERROR(WriteGltfFile(at("_quantized.glb"), asset, quantized));
    quantized.meshopt = true;
    ATEX_RETURN_IF_ERROR(WriteGltfFile(at("_quantized_meshopt.glb"), asset, quantized));
  }
  // `atex convert --time T` to .ply and .spz v3 (the world turned to each format's up axis).
  ConvertOptions at_time = SpzV3();
  at_time.time = view.camera.time;
  for (const char* ext : {".ply", ".spz"}) {
    ATEX_RETURN_IF_ERROR(WriteAssetAs(at(ext), asset, FileFormat::kUnknown, at_time));
  }
  Asset plain = baked;
  plain.textures.reset();
  ATEX_RETURN_IF_ERROR(RenderReference(plain, view.camera, at("_untextured.png")));
  std::string textured = file("_untextured.png");
  if (baked.textures) {
    textured = file("_atex.png");
    ATEX_RETURN_IF_ERROR(RenderReference(baked, view.camera, at("_atex.png")));
  }
  ATEX_RETURN_IF_ERROR(WriteImage(at("_truth.png"), *truth));
  json entry;
  if (!variants) {
    // Diagnostic reference: each Gaussian's base colour (0.5 + C0 * DC) clamped to [0, 1] before the
    // view-dependent terms are added, as players that keep base colours in 8 bits hold them (our
    // renderer, like 3DGS, only clamps the sum at 0; trained lights reach base colours near 2).
    Asset clamped = plain;
    Gaussians& g = clamped.gaussians;
    const size_t stride = size_t(g.sh_coeffs()) * 3;
    constexpr float kHalfRange = float(0.5 / 0.28209479177387814);
    for (size_t i = 0; i < g.size(); ++i) {
      for (size_t c = 0; c < 3; ++c) g.sh[i * stride + c] = std::clamp(g.sh[i * stride + c], -kHalfRange, kHalfRange);
    }
    ATEX_RETURN_IF_ERROR(RenderReference(clamped, view.camera, at("_clamped.png")));
    entry["clamped"] = file("_clamped.png");
  }
  json cam = CameraJson(view.camera);
  const auto& bg = asset.metadata.background;
  cam["background"] = {bg[0], bg[1], bg[2]};
  cam["pose"] = {{"opencv_world_to_camera", view.camera.world_to_camera}, {"apply_node_rotation", true}};
  // Our renderer culls the Gaussians nearer than its near plane (3DGS's 0.2); the players' pages
  // take it as their camera's near plane. Training never sees what lies in front of it, and a real
  // capture's cameras stand among such untrained splats (issue 21 item 4, Panoptic).
  cam["near"] = RenderSettings{}.near_plane;
  ATEX_RETURN_IF_ERROR(WriteText(at("_camera.json"), cam.dump(2)));
  entry.update(json{{"glb", file(".glb")}, {"ply", file(".ply")}, {"spz", file(".spz")},
                    {"camera", file("_camera.json")}, {"reference", file("_untextured.png")}, {"atex", textured},
                    {"truth", file("_truth.png")}, {"time", view.camera.time}, {"view", view.camera.name},
                    {"gaussians", asset.gaussians.size()}});
  return entry;
}

}  // namespace atex::web_fixture
