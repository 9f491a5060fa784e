// Helpers of atex_web_fixture (web_fixture.cc) and its player scenes (issue 21 item 4): a
// trained asset baked at a dataset view's time, exported for the third-party players, with
// our reference renders and the ground truth of that view.
#pragma once

#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "atex/container.h"
#include "atex/converters/convert.h"
#include "atex/dataset.h"
#include "atex/render.h"

namespace atex::web_fixture {

// Writes text to path atomically.
Status WriteText(const std::filesystem::path& path, const std::string& text);

// Renders asset (textures included when it has them) with libatex's reference rasteriser on its
// metadata's background and writes an 8-bit PNG.
Status RenderReference(const Asset& asset, const Camera& camera, const std::filesystem::path& png);

// `atex convert` options for the players' .ply and .spz files: SPZ version 3 (gzip), which
// Spark reads (it refuses version 4's zstd streams).
ConvertOptions SpzV3();

// The intrinsics of a camera as the players' pages read them (width, height, fx, fy, cx, cy).
nlohmann::json CameraJson(const Camera& c);

// One player scene: `asset` (a trained 4D asset) at the time of `view` of its dataset, written
// under out as STEM.glb (`atex export --time`), STEM.ply and STEM.spz (`atex convert --time`,
// SPZ v3), STEM_camera.json (the view's OpenCV camera, applied through the .glb's node
// rotation), STEM_atex.png (our render, textures included), STEM_untextured.png (our render
// of the same Gaussians without textures: what a KHR_gaussian_splatting player can show at
// best; for an untextured asset the same picture, written once) and STEM_truth.png (the view's
// image). With variants, also STEM_baked.glb (--bake-textures), STEM_quantized.glb
// (--quantize) and STEM_quantized_meshopt.glb (--quantize --meshopt); without, the diagnostic
// STEM_clamped.png (our untextured render with each Gaussian's base colour clamped to [0, 1], as
// 8-bit players hold it; manifest key "clamped"). The camera file also states our renderer's
// near plane ("near"), which the players' pages use. Returns the scene's
// manifest entry (files, camera, time, view name, Gaussian count); the variants' entries are
// the caller's to add.
StatusOr<nlohmann::json> WritePlayerScene(const std::filesystem::path& out, const std::string& stem,
                                          const Asset& asset, const Dataset& dataset, const View& view,
                                          bool variants);

}  // namespace atex::web_fixture
