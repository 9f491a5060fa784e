// Writes the files the third-party checks of tests/web read:
//   validator/*.glb|.gltf   exports in every flavour, for the Khronos glTF-Validator
//   letter_f.*              an asymmetric static scene ("F", red/green/blue) with a camera
//                           given in glTF terms and our reference render of it; also as
//                           .ply and .spz written as `atex convert` writes them (PlayCanvas, Spark)
//   garden.*                gsplat's real COLMAP points of Mip-NeRF 360 "garden" as small
//                           Gaussians, a real camera, and our reference render
//   motion.splatv + motion_reference.json   baked motion and the deformation it stands for
//   upright_lego.glb        the bundled lego sample (D-NeRF, Blender Z-up) exported with its
//                           recorded up axis, and the up direction of the dataset's cameras
//                           (from the cameras, not the metadata) that a reader must show as up
//   player_lego.*           the lego sample at a test view's time as .glb, .ply and .spz, the
//                           view's camera and three references (our render, untextured, truth);
//                           player_lego_quantized*.glb: the same .glb with --quantize (and --meshopt)
//                           player_lego_baked.glb the same with --bake-textures
//   player_model_vN.*       optional: an external trained model (ATEX_PLAYER_MODEL, its dataset
//                           ATEX_PLAYER_MODEL_DATA) at test views ATEX_PLAYER_MODEL_VIEWS (default
//                           0), the same files as player_lego's (bench/web_players_model.sh)
//   textured_tiles*         semi-transparent Gaussians with strong 2x2 textures, exported as is
//                           and with --bake-textures, their camera and our textured render
// Usage: atex_web_fixture OUT_DIR   (real data from $ATEX_DATA_DIR or the configured default)
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <string>

#include "atex/container.h"
#include "atex/converters/convert.h"
#include "atex/converters/gltf.h"
#include "atex/converters/splatv.h"
#include "atex/dataset.h"
#include "atex/deform.h"
#include "atex/file_io.h"
#include "atex/image.h"
#include "atex/npy.h"
#include "atex/render.h"
#include "convert/upright_test_util.h"
#include "gltf/gltf_test_scene.h"
#include "web_fixture_player.h"

namespace fs = std::filesystem;
using atex::web_fixture::CameraJson;
using atex::web_fixture::RenderReference;
using atex::web_fixture::SpzV3;
using atex::web_fixture::WritePlayerScene;
using atex::web_fixture::WriteText;
using nlohmann::json;

namespace {

constexpr double kC0 = 0.28209479177387814;

int Fail(const std::string& what, const atex::Status& s) {
  std::fprintf(stderr, "atex_web_fixture: %s: %s\n", what.c_str(), s.ToString().c_str());
  return 1;
}

void SetColor(atex::Gaussians& g, size_t i, double r, double gr, double b) {
  const size_t k = size_t(g.sh_coeffs());
  g.sh[i * k * 3 + 0] = float((r - 0.5) / kC0);
  g.sh[i * k * 3 + 1] = float((gr - 0.5) / kC0);
  g.sh[i * k * 3 + 2] = float((b - 0.5) / kC0);
}

// The letter F in the z = 0 plane of an OpenCV world (y down: the top bar has y < 0).
atex::Asset LetterF() {
  struct Stroke {
    double x0, y0, x1, y1, r, g, b;
  };
  const Stroke strokes[] = {{-0.4, -0.8, -0.4, 0.8, 0.1, 0.2, 0.95},   // stem, blue
                            {-0.36, -0.8, 0.5, -0.8, 0.95, 0.1, 0.1},  // top bar, red
                            {-0.36, 0.0, 0.25, 0.0, 0.1, 0.9, 0.15}};  // middle bar, green
  atex::Asset asset;
  atex::Gaussians& g = asset.gaussians;
  g.sh_degree = 0;
  std::vector<std::array<double, 6>> points;
  for (const auto& s : strokes) {
    const double length = std::hypot(s.x1 - s.x0, s.y1 - s.y0);
    const int steps = int(length / 0.035) + 1;
    for (int i = 0; i <= steps; ++i) {
      const double t = double(i) / steps;
      points.push_back({s.x0 + t * (s.x1 - s.x0), s.y0 + t * (s.y1 - s.y0), s.r, s.g, s.b, 0});
    }
  }
  g.Resize(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    g.positions[i * 3 + 0] = float(points[i][0]);
    g.positions[i * 3 + 1] = float(points[i][1]);
    g.positions[i * 3 + 2] = 0.0f;
    g.rotations[i * 4 + 0] = 1.0f;
    for (int k = 0; k < 3; ++k) g.log_scales[i * 3 + k] = float(std::log(k == 2 ? 0.01 : 0.03));
    g.opacity_logits[i] = 3.0f;
    SetColor(g, i, points[i][2], points[i][3], points[i][4]);
  }
  asset.metadata.axes = "opencv";
  asset.metadata.bounds_min = {-0.5f, -0.9f, -0.1f};
  asset.metadata.bounds_max = {0.6f, 0.9f, 0.1f};
  return asset;
}

// Issue 21 item 5: a 5x4 grid of semi-transparent Gaussians (opacity 0.45) in the z = 0 plane of
// an OpenCV world, each with a 2x2 texture of strong colour ramps (texels ±3: the full ±0.1 of
// conventions §5) that a KHR_gaussian_splatting player drops unless they are baked.
atex::Asset TexturedTiles() {
  atex::Asset asset;
  atex::Gaussians& g = asset.gaussians;
  g.sh_degree = 0;
  constexpr int kCols = 5, kRows = 4;
  g.Resize(kCols * kRows);
  atex::TexturePool t;
  for (int r = 0; r < kRows; ++r) {
    for (int c = 0; c < kCols; ++c) {
      const size_t i = size_t(r * kCols + c);
      g.positions[i * 3 + 0] = float(-0.9 + 0.45 * c);
      g.positions[i * 3 + 1] = float(-0.675 + 0.45 * r);
      g.positions[i * 3 + 2] = 0.0f;
      g.rotations[i * 4 + 0] = 1.0f;
      g.log_scales[i * 3 + 0] = float(std::log(0.15));
      g.log_scales[i * 3 + 1] = float(std::log(0.12));
      g.log_scales[i * 3 + 2] = float(std::log(0.01));
      g.opacity_logits[i] = float(std::log(0.45 / 0.55));
      SetColor(g, i, 0.35 + 0.1 * c, 0.6 - 0.1 * r, 0.45);
      t.heights.push_back(2), t.widths.push_back(2), t.axis_u.push_back(0), t.axis_v.push_back(1);
    }
  }
  t.RebuildOffsets();
  t.texels.assign(t.texel_count() * 4, 0.0f);
  for (size_t i = 0; i < g.size(); ++i) {
    for (int y = 0; y < 2; ++y) {
      for (int x = 0; x < 2; ++x) {
        float* texel = &t.texels[(t.offsets[i] + size_t(y * 2 + x)) * 4];
        const float su = x == 0 ? -3.0f : 3.0f, sv = y == 0 ? -3.0f : 3.0f;
        // Red ramps along u, green along v, blue along the diagonal (varies with i), opacity along u.
        texel[0] = su, texel[1] = sv, texel[2] = (i % 2 == 0) ? su * sv / 3 : -su, texel[3] = su;
      }
    }
  }
  asset.textures = t;
  asset.metadata.axes = "opencv";
  asset.metadata.texture_mode = "adaptive";
  asset.metadata.bounds_min = {-1.2f, -1.0f, -0.1f};
  asset.metadata.bounds_max = {1.2f, 1.0f, 0.1f};
  return asset;
}

// gsplat's garden points (real COLMAP SfM output) as isotropic Gaussians, and its first camera.
atex::StatusOr<std::pair<atex::Asset, atex::Camera>> Garden(const fs::path& npz) {
  ATEX_ASSIGN_OR_RETURN(auto arrays, atex::ReadNpzFile(npz.string()));
  for (const char* key : {"means3d", "colors", "viewmats", "Ks", "width", "height"}) {
    if (!arrays.count(key)) return atex::MakeError(atex::StatusCode::kNotFound, npz.string(), " lacks ", key);
  }
  const std::vector<double> means = arrays["means3d"].ToDouble();
  const std::vector<double> colors = arrays["colors"].ToDouble();
  const std::vector<double> view = arrays["viewmats"].ToDouble();
  const std::vector<double> ks = arrays["Ks"].ToDouble();
  ATEX_ASSIGN_OR_RETURN(double width, arrays["width"].Scalar("width"));
  ATEX_ASSIGN_OR_RETURN(double height, arrays["height"].Scalar("height"));
  const size_t total = means.size() / 3;
  atex::Camera camera;
  camera.width = int(width) / 2;  // half resolution keeps the software-GL browser run short
  camera.height = int(height) / 2;
  camera.fx = ks[0] / 2, camera.fy = ks[4] / 2, camera.cx = ks[2] / 2, camera.cy = ks[5] / 2;
  for (int i = 0; i < 16; ++i) camera.world_to_camera[size_t(i)] = view[size_t(i)];
  // Every third point: 46k Gaussians; scale from the mean spacing inside the central volume.
  atex::Asset asset;
  atex::Gaussians& g = asset.gaussians;
  g.sh_degree = 0;
  std::vector<size_t> keep;
  for (size_t i = 0; i < total; i += 3) keep.push_back(i);
  g.Resize(keep.size());
  std::vector<double> sorted[3];
  for (size_t i : keep) {
    for (int k = 0; k < 3; ++k) sorted[k].push_back(means[i * 3 + k]);
  }
  double volume = 1;
  for (auto& s : sorted) {
    std::sort(s.begin(), s.end());
    volume *= s[s.size() * 95 / 100] - s[s.size() * 5 / 100];
  }
  const double spacing = std::cbrt(volume / (0.9 * double(keep.size())));
  for (size_t j = 0; j < keep.size(); ++j) {
    const size_t i = keep[j];
    for (int k = 0; k < 3; ++k) {
      g.positions[j * 3 + size_t(k)] = float(means[i * 3 + size_t(k)]);
      g.log_scales[j * 3 + size_t(k)] = float(std::log(0.35 * spacing));
    }
    g.rotations[j * 4] = 1.0f;
    g.opacity_logits[j] = 2.0f;
    SetColor(g, j, colors[i * 3] / 255.0, colors[i * 3 + 1] / 255.0, colors[i * 3 + 2] / 255.0);
  }
  asset.metadata.axes = "opencv";  // COLMAP's world: y points down in these captures
  return std::make_pair(std::move(asset), camera);
}

// Section 7 of main: the scenes of ATEX_PLAYER_MODEL at ATEX_PLAYER_MODEL_VIEWS of
// ATEX_PLAYER_MODEL_DATA's test views. Returns main's exit code.
int WriteModelScenes(const fs::path& out, const std::string& model, json* manifest) {
  const char* data = std::getenv("ATEX_PLAYER_MODEL_DATA");
  if (!data || !*data) {
    return Fail("ATEX_PLAYER_MODEL", atex::MakeError(atex::StatusCode::kInvalidArgument,
                                                     "ATEX_PLAYER_MODEL_DATA (the model's dataset) is not set"));
  }
  auto asset = atex::ReadAssetFile(model);
  if (!asset.ok()) return Fail(model, asset.status());
  auto dataset = atex::OpenDataset(data);
  if (!dataset.ok()) return Fail(data, dataset.status());
  const auto& views = (*dataset)->test_views();
  const char* list = std::getenv("ATEX_PLAYER_MODEL_VIEWS");
  std::string indices = list && *list ? list : "0";
  (*manifest)["player_model"] = json::array();
  for (size_t start = 0; start <= indices.size();) {
    const size_t end = std::min(indices.find(',', start), indices.size());
    const std::string item = indices.substr(start, end - start);
    start = end + 1;
    char* rest = nullptr;
    const long index = std::strtol(item.c_str(), &rest, 10);
    if (item.empty() || *rest != '\0' || index < 0 || size_t(index) >= views.size()) {
      return Fail("ATEX_PLAYER_MODEL_VIEWS", atex::MakeError(atex::StatusCode::kInvalidArgument, "\"", item,
                                                             "\" is not a test view index (0..", views.size() - 1, ")"));
    }
    const std::string stem = "player_model_v" + item;
    std::fprintf(stderr, "atex_web_fixture: %s: %s at t = %g\n", stem.c_str(), views[size_t(index)].camera.name.c_str(),
                 views[size_t(index)].camera.time);
    auto scene = WritePlayerScene(out, stem, *asset, **dataset, views[size_t(index)], false);
    if (!scene.ok()) return Fail(stem, scene.status());
    (*scene)["name"] = stem;
    (*scene)["test_view"] = index;
    (*scene)["model"] = model;
    (*manifest)["player_model"].push_back(*scene);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: atex_web_fixture OUT_DIR\n");
    return 2;
  }
  const fs::path out(argv[1]);
  fs::create_directories(out / "validator");
  json manifest = {{"validator", json::array()}};

  // 1. Every export flavour of a scene with textures and motion (and one of the real PLY).
  const atex::Asset moving = atex::testing::MakeTestAsset({.count = 2000, .sh_degree = 2, .seed = 5});
  struct Flavour {
    const char* name;
    atex::GltfExportOptions options;
  };
  std::vector<Flavour> flavours;
  flavours.push_back({"plain_extensions.glb", {}});
  {
    atex::GltfExportOptions o;
    o.textures = false, o.deformation = false, o.raw_parameters = false;
    flavours.push_back({"base_only.glb", o});
  }
  {
    atex::GltfExportOptions o;
    o.time = 0.5;
    flavours.push_back({"baked_t0.5.glb", o});
  }
  {
    atex::GltfExportOptions o;
    o.meshopt = true;
    flavours.push_back({"meshopt_exact.glb", o});
  }
  {
    atex::GltfExportOptions o;
    o.meshopt = true, o.meshopt_float_bits = 14, o.raw_parameters = false;
    flavours.push_back({"meshopt_lossy.glb", o});
  }
  {
    atex::GltfExportOptions o;
    o.spz = true;
    flavours.push_back({"spz_compressed.glb", o});
  }
  {
    atex::GltfExportOptions o;
    o.quantize = true;
    flavours.push_back({"quantized.glb", o});
    o.meshopt = true, o.meshopt_float_bits = 12;
    flavours.push_back({"quantized_meshopt.glb", o});
  }
  flavours.push_back({"text_form.gltf", {}});
  {
    atex::Status s = atex::WriteAssetFile((out / "moving.atex").string(), moving);
    if (!s.ok()) return Fail("moving.atex", s);
    manifest["atex"] = "moving.atex";
  }
  for (const auto& f : flavours) {
    atex::Status s = atex::WriteGltfFile((out / "validator" / f.name).string(), moving, f.options);
    if (!s.ok()) return Fail(f.name, s);
    manifest["validator"].push_back(std::string("validator/") + f.name);
  }

  // 2. The letter F, seen from +z of the glTF world with +y up (a camera stated in glTF
  //    terms, independent of the exporter's axis handling) = the OpenCV camera at z = -3.
  {
    const atex::Asset f = LetterF();
    atex::Camera camera;
    camera.width = 320, camera.height = 240;
    camera.fx = camera.fy = 260, camera.cx = 160, camera.cy = 120;
    camera.world_to_camera = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 3, 0, 0, 0, 1};
    atex::Status s = atex::WriteGltfFile((out / "letter_f.glb").string(), f);
    atex::GltfExportOptions meshopt;
    meshopt.meshopt = true, meshopt.meshopt_float_bits = 12, meshopt.raw_parameters = false;
    if (s.ok()) s = atex::WriteGltfFile((out / "letter_f_meshopt.glb").string(), f, meshopt);
    // The same scene as `atex convert letter_f.atex letter_f.ply` (and `.spz --spz-version 3`:
    // Spark 2.2 reads the gzip-framed SPZ v2/v3, not v4) writes it.
    for (const char* name : {"letter_f.ply", "letter_f.spz"}) {
      if (s.ok()) s = atex::WriteAssetAs((out / name).string(), f, atex::FileFormat::kUnknown, SpzV3());
    }
    if (s.ok()) s = RenderReference(f, camera, out / "letter_f_reference.png");
    if (!s.ok()) return Fail("letter F", s);
    json cam = CameraJson(camera);
    cam["background"] = {0, 0, 0};
    cam["pose"] = {{"gltf", {{"position", {0, 0, 3}}, {"target", {0, 0, 0}}, {"up", {0, 1, 0}}}}};
    s = WriteText(out / "letter_f_camera.json", cam.dump(2));
    if (!s.ok()) return Fail("letter F camera", s);
    manifest["letter_f"] = {{"glb", "letter_f.glb"}, {"ply", "letter_f.ply"}, {"spz", "letter_f.spz"},
                            {"camera", "letter_f_camera.json"}, {"reference", "letter_f_reference.png"},
                            {"gaussians", f.gaussians.size()}};
    manifest["letter_f_meshopt"] = {{"glb", "letter_f_meshopt.glb"}, {"camera", "letter_f_camera.json"},
                                    {"reference", "letter_f_reference.png"}};
    manifest["validator"].push_back("letter_f_meshopt.glb");
  }

  // 2b. Textures baked for KHR-only players (issue 21 item 5): the textured tiles exported as is
  //     (Babylon.js drops ATEX_gaussian_textures) and with --bake-textures, the F's camera, and our
  //     textured render as the reference.
  {
    const atex::Asset tiles = TexturedTiles();
    atex::Camera camera;
    camera.width = 320, camera.height = 240;
    camera.fx = camera.fy = 260, camera.cx = 160, camera.cy = 120;
    camera.world_to_camera = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 3, 0, 0, 0, 1};
    atex::GltfExportOptions baked;
    baked.bake_textures = true;
    atex::Status s = atex::WriteGltfFile((out / "textured_tiles.glb").string(), tiles);
    if (s.ok()) s = atex::WriteGltfFile((out / "textured_tiles_baked.glb").string(), tiles, baked);
    if (s.ok()) s = RenderReference(tiles, camera, out / "textured_tiles_atex.png");
    atex::Asset untextured = tiles;
    untextured.textures.reset();
    untextured.metadata.texture_mode = "none";
    if (s.ok()) s = RenderReference(untextured, camera, out / "textured_tiles_untextured.png");
    if (!s.ok()) return Fail("textured tiles", s);
    json cam = CameraJson(camera);
    cam["background"] = {0, 0, 0};
    cam["pose"] = {{"gltf", {{"position", {0, 0, 3}}, {"target", {0, 0, 0}}, {"up", {0, 1, 0}}}}};
    s = WriteText(out / "textured_tiles_camera.json", cam.dump(2));
    if (!s.ok()) return Fail("textured tiles camera", s);
    manifest["textured_tiles"] = {{"glb", "textured_tiles.glb"}, {"baked_glb", "textured_tiles_baked.glb"},
                                  {"camera", "textured_tiles_camera.json"}, {"reference", "textured_tiles_atex.png"},
                                  {"untextured", "textured_tiles_untextured.png"}, {"gaussians", tiles.gaussians.size()}};
  }

  // 3. Real data: garden points and camera.
  const char* data_env = std::getenv("ATEX_DATA_DIR");
  const char* data_default = std::getenv("ATEX_DATA_DIR_DEFAULT");
  fs::path data = data_env && *data_env ? fs::path(data_env) : data_default ? fs::path(data_default) : fs::path();
  const fs::path npz = data / "gsplat_test_garden" / "test_garden.npz";
  if (fs::exists(npz)) {
    auto garden = Garden(npz);
    if (!garden.ok()) return Fail("garden", garden.status());
    const auto& [asset, camera] = *garden;
    atex::Status s = atex::WriteGltfFile((out / "garden.glb").string(), asset);
    if (s.ok()) s = RenderReference(asset, camera, out / "garden_reference.png");
    if (!s.ok()) return Fail("garden", s);
    json cam = CameraJson(camera);
    cam["background"] = {0, 0, 0};
    cam["pose"] = {{"opencv_world_to_camera", camera.world_to_camera}, {"apply_node_rotation", true}};
    s = WriteText(out / "garden_camera.json", cam.dump(2));
    if (!s.ok()) return Fail("garden camera", s);
    manifest["garden"] = {{"glb", "garden.glb"}, {"camera", "garden_camera.json"}, {"reference", "garden_reference.png"},
                          {"gaussians", asset.gaussians.size()}};
  } else {
    manifest["garden_missing"] = npz.string();
  }

  // 4. splaTV: the moving scene baked, plus the deformation it approximates at chosen times.
  {
    atex::SplatvFitReport report;
    atex::SplatvOptions options;
    atex::SplatvCamera view;  // OpenCV camera at z = -6 looking at the scene (+z), y down
    view.width = 480, view.height = 270, view.fx = view.fy = 220;
    view.position = {0, 0, -6};
    options.cameras = {view};
    options.psnr_times = 3;
    atex::Status s = atex::WriteSplatvFile((out / "motion.splatv").string(), moving, options, &report);
    if (!s.ok()) return Fail("splatv", s);
    json reference = {{"report", report.ToJson()}, {"time_min", moving.metadata.time_min},
                      {"time_max", moving.metadata.time_max}, {"frames", json::array()}};
    for (double u : {0.0, 0.25, 0.5, 0.8, 1.0}) {
      const double t = moving.metadata.time_min + u * (moving.metadata.time_max - moving.metadata.time_min);
      atex::Gaussians deformed;
      s = atex::DeformForward(*moving.deformation, moving.gaussians, t, &deformed, nullptr);
      if (!s.ok()) return Fail("deform", s);
      reference["frames"].push_back({{"u", u}, {"positions", deformed.positions}});
    }
    s = WriteText(out / "motion_reference.json", reference.dump());
    if (!s.ok()) return Fail("splatv reference", s);
    // Reference picture at u = 0.5 with that camera: the deformed scene, DC colour only.
    {
      atex::Asset at_half;
      at_half.metadata = moving.metadata;
      atex::Gaussians deformed;
      s = atex::DeformForward(*moving.deformation, moving.gaussians, 0.5, &deformed, nullptr);
      atex::Camera camera;
      camera.width = view.width, camera.height = view.height;
      camera.fx = view.fx, camera.fy = view.fy, camera.cx = view.width / 2.0, camera.cy = view.height / 2.0;
      camera.world_to_camera = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 6, 0, 0, 0, 1};
      at_half.gaussians = deformed;  // then keep the DC term only
      at_half.gaussians.sh_degree = 0;
      at_half.gaussians.sh.resize(deformed.size() * 3);
      const size_t k = size_t(deformed.sh_coeffs());
      for (size_t i = 0; i < deformed.size(); ++i) {
        for (int c = 0; c < 3; ++c) at_half.gaussians.sh[i * 3 + size_t(c)] = deformed.sh[i * k * 3 + size_t(c)];
      }
      if (s.ok()) s = RenderReference(at_half, camera, out / "motion_u0.5_reference.png");
      if (!s.ok()) return Fail("splatv reference picture", s);
      manifest["splatv_view"] = {{"splatv", "motion.splatv"}, {"time", 0.5}, {"camera", "motion_camera.json"},
                                 {"reference", "motion_u0.5_reference.png"}};
      json cam = CameraJson(camera);
      s = WriteText(out / "motion_camera.json", cam.dump(2));
      if (!s.ok()) return Fail("splatv camera", s);
    }
    manifest["splatv"] = {{"file", "motion.splatv"}, {"reference", "motion_reference.json"}, {"gaussians", moving.gaussians.size()}};
  }

  // 5. Upright: the shipped lego sample, and the up direction its dataset's cameras agree on.
  const char* source_dir = std::getenv("ATEX_SOURCE_DIR");
  const fs::path lego = data / "dnerf_lego_tiny" / "tiny_dnerf_data.npz";
  if (source_dir && fs::exists(lego)) {
    auto up = atex::converters::testing::CamerasUpVector(lego.string());
    if (!up.ok()) return Fail("lego cameras", up.status());
    auto sample = atex::ReadAssetFile((fs::path(source_dir) / "samples" / "lego_adaptive_2MiB.atex").string());
    if (!sample.ok()) return Fail("lego sample", sample.status());
    atex::Status s = atex::WriteGltfFile((out / "upright_lego.glb").string(), *sample);
    if (!s.ok()) return Fail("upright_lego.glb", s);
    manifest["upright"] = {{"glb", "upright_lego.glb"}, {"cameras_up", *up}};
  } else {
    manifest["upright_missing"] = lego.string();
  }

  // 6. A trained asset in the players (issue 21 item 4): the lego sample baked at the time of the
  //    dataset's first test view, exported to glTF, .ply and .spz, with three references for that
  //    camera: our render (textures included: what `atex render` shows), our render of the same
  //    Gaussians without their textures (what a KHR_gaussian_splatting player can show at best),
  //    and the ground truth; also the quantised and texture-baked exports.
  if (source_dir && fs::exists(lego)) {
    auto sample = atex::ReadAssetFile((fs::path(source_dir) / "samples" / "lego_adaptive_2MiB.atex").string());
    if (!sample.ok()) return Fail("lego sample", sample.status());
    auto dataset = atex::OpenDataset(lego.string());
    if (!dataset.ok()) return Fail("lego dataset", dataset.status());
    auto scene = WritePlayerScene(out, "player_lego", *sample, **dataset, (*dataset)->test_views().at(0), true);
    if (!scene.ok()) return Fail("player lego", scene.status());
    manifest["player_lego"] = *scene;
    manifest["player_lego_quantized"] = {{"glb", "player_lego_quantized.glb"},
                                         {"glb_meshopt", "player_lego_quantized_meshopt.glb"}};
    manifest["validator"].push_back("player_lego_quantized.glb");
    manifest["player_lego_baked"] = manifest["player_lego"];
    manifest["player_lego_baked"]["glb"] = "player_lego_baked.glb";
  }

  // 7. Optionally an external trained model in the players (bench/web_players_model.sh):
  //    ATEX_PLAYER_MODEL (an .atex), ATEX_PLAYER_MODEL_DATA (its dataset) and
  //    ATEX_PLAYER_MODEL_VIEWS (comma-separated test-view indices, default 0) give the scenes
  //    player_model_vINDEX, listed in the manifest's "player_model" array.
  if (const char* model = std::getenv("ATEX_PLAYER_MODEL"); model && *model) {
    if (int rc = WriteModelScenes(out, model, &manifest); rc != 0) return rc;
  }

  if (atex::Status s = WriteText(out / "manifest.json", manifest.dump(2)); !s.ok()) return Fail("manifest", s);
  std::printf("%s\n", manifest.dump(2).c_str());
  return 0;
}
