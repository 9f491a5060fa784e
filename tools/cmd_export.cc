// `atex export SCENE.atex OUT`: glTF (.glb / .gltf + .bin), splaTV (.splatv), or a
// folder of per-frame .glb files (--frames a:b:step). Thin front end over
// atex/converters/gltf.h and atex/converters/splatv.h.
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <algorithm>
#include <filesystem>
#include <memory>
#include <optional>

#include "atex/container.h"
#include "atex/converters/convert.h"
#include "atex/converters/gltf.h"
#include "atex/converters/splatv.h"
#include "atex/file_io.h"
#include "atex/version.h"
#include "cli.h"
#include "cli_parse.h"

namespace {

struct ExportArgs {
  std::string input, output;
  double time = 0;
  bool has_time = false;
  std::string frames;
  bool meshopt = false;
  bool spz = false;
  bool quantize = false;
  int meshopt_bits = 0;
  int rotation_bits = 16;
  bool no_textures = false, no_deformation = false, no_raw = false, no_color = false;
  bool bake_textures = false;
  std::string up;
  int samples = 32;
  int psnr_times = 0;
  bool json = false, force = false;
};

std::string Lower(std::string s) {
  for (auto& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

double Seconds(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Every file the export writes: the output, a .gltf's .bin beside it; a --frames folder.
atex::Status CheckExportOutputs(const ExportArgs& a) {
  using atex::cli::CheckOutput;
  if (!a.frames.empty()) return CheckOutput(a.output, a.force, {{a.input}, {}, "output folder", true, true});
  ATEX_RETURN_IF_ERROR(CheckOutput(a.output, a.force, {{a.input}, {".glb", ".gltf", ".splatv"}}));
  const std::filesystem::path out(a.output);
  if (Lower(out.extension().string()) == ".gltf") {
    const std::string bin = (out.parent_path() / (out.stem().string() + ".bin")).string();
    ATEX_RETURN_IF_ERROR(CheckOutput(bin, a.force, {{a.input}, {}, "the .gltf's buffer", false}));
  }
  return atex::Status::Ok();
}

// --frames: one .glb per time of the range in the folder `a.output`, and frames.json listing them.
int ExportFrames(const ExportArgs& a, const atex::Asset& asset, atex::GltfExportOptions gltf, nlohmann::json& summary) {
  const std::filesystem::path out(a.output);
  // The same START:END:STEP grammar as `atex convert --frames`.
  auto range = atex::ParseFrameRange(a.frames);
  if (!range.ok()) return atex::cli::Fail("export", range.status());
  const std::vector<double> times = range->Times();
  if (!asset.deformation) {
    return atex::cli::Fail(
        "export", atex::MakeError(atex::StatusCode::kInvalidArgument, "--frames needs an asset with motion"));
  }
  std::error_code ec;
  std::filesystem::create_directories(out, ec);
  if (ec)
    return atex::cli::Fail(
        "export", atex::MakeError(atex::StatusCode::kIoError, "cannot create folder ", a.output, ": ", ec.message()));
  atex::cli::Progress progress("export frames", static_cast<long long>(times.size()));
  nlohmann::json frames = nlohmann::json::array();
  uint64_t total = 0;
  for (size_t i = 0; i < times.size(); ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "frame_%04zu.glb", i);
    gltf.time = times[i];
    auto bytes = atex::EncodeGlb(asset, gltf);
    if (!bytes.ok()) return atex::cli::Fail("export", bytes.status().WithContext(name));
    atex::Status s = atex::WriteFileAtomic((out / name).string(), *bytes);
    if (!s.ok()) return atex::cli::Fail("export", s);
    total += bytes->size();
    frames.push_back({{"file", name}, {"time", times[i]}});
    if (i + 1 < times.size()) progress.Update(static_cast<long long>(i + 1));
  }
  progress.Finish();
  const nlohmann::json manifest = {
      {"generator", std::string("atex ") + atex::kVersion}, {"format", "glb sequence"}, {"frames", frames}};
  const std::string text = manifest.dump(2);
  atex::Status s = atex::WriteFileAtomic((out / "frames.json").string(), text.data(), text.size());
  if (!s.ok()) return atex::cli::Fail("export", s);
  summary["format"] = "glb sequence";
  summary["frames"] = times.size();
  summary["bytes"] = total;
  return atex::cli::kExitOk;
}

// .splatv: the motion fitted per Gaussian (atex/converters/splatv.h), with a progress bar.
int ExportSplatv(const ExportArgs& a, const atex::Asset& asset, std::optional<atex::UpAxis> up,
                 nlohmann::json& summary) {
  const std::filesystem::path out(a.output);
  atex::SplatvOptions options;
  options.samples = a.samples;
  options.up = up;
  options.psnr_times = a.psnr_times;
  atex::cli::Progress progress("fit motion", 1000);
  options.progress = [&progress](double f) {
    progress.Update(std::min(999LL, static_cast<long long>(f * 1000)));  // Finish() draws the end
    return true;
  };
  atex::SplatvFitReport report;
  atex::Status s = atex::WriteSplatvFile(a.output, asset, options, &report);
  progress.Finish();
  if (!s.ok()) return atex::cli::Fail("export", s);
  summary["format"] = "splatv";
  summary["bytes"] = std::filesystem::file_size(out);
  summary["fit"] = report.ToJson();
  return atex::cli::kExitOk;
}

int RunExport(const ExportArgs& a) {
  const auto start = std::chrono::steady_clock::now();
  if (atex::Status s = CheckExportOutputs(a); !s.ok()) return atex::cli::Fail("export", s, a.output);
  auto asset = atex::ReadAssetFile(a.input);
  if (!asset.ok()) return atex::cli::Fail("export", asset.status(), a.input);
  const double read_seconds = Seconds(start);

  atex::GltfExportOptions gltf;
  gltf.meshopt = a.meshopt;
  gltf.spz = a.spz;
  gltf.quantize = a.quantize;
  gltf.meshopt_float_bits = a.meshopt_bits;
  gltf.meshopt_rotation_bits = a.rotation_bits;
  gltf.textures = !a.no_textures;
  gltf.deformation = !a.no_deformation;
  gltf.raw_parameters = !a.no_raw;
  gltf.color_fallback = !a.no_color;
  atex::TextureBakeReport bake_report;
  gltf.bake_textures = a.bake_textures;
  gltf.bake_report = &bake_report;
  if (!a.up.empty()) {
    auto up = atex::ParseUpAxis(a.up);
    if (!up.ok()) return atex::cli::Fail("export", up.status());
    gltf.up = *up;
  }
  if (a.has_time) gltf.time = a.time;

  nlohmann::json summary = {{"input", a.input},
                            {"output", a.output},
                            {"gaussians", asset->gaussians.size()},
                            {"read_seconds", read_seconds}};
  const std::filesystem::path out(a.output);
  const std::string ext = Lower(out.extension().string());
  const auto write_start = std::chrono::steady_clock::now();

  if (!a.frames.empty()) {
    if (int code = ExportFrames(a, *asset, gltf, summary); code != atex::cli::kExitOk) return code;
  } else if (ext == ".glb" || ext == ".gltf") {
    atex::Status s = atex::WriteGltfFile(a.output, *asset, gltf);
    if (!s.ok()) return atex::cli::Fail("export", s);
    summary["format"] = ext == ".glb" ? "glb" : "gltf";
    uint64_t bytes = std::filesystem::file_size(out);
    if (ext == ".gltf") bytes += std::filesystem::file_size(out.parent_path() / (out.stem().string() + ".bin"));
    summary["bytes"] = bytes;
    summary["meshopt"] = a.meshopt;
    summary["spz"] = a.spz;
    summary["quantize"] = a.quantize;
  } else if (ext == ".splatv") {
    if (int code = ExportSplatv(a, *asset, gltf.up, summary); code != atex::cli::kExitOk) return code;
  } else {
    return atex::cli::Fail("export", atex::MakeError(atex::StatusCode::kInvalidArgument, "output '", a.output,
                                                     "' is not .glb, .gltf or .splatv (or a folder with --frames)"));
  }
  summary["write_seconds"] = Seconds(write_start);
  const bool baked = a.bake_textures && asset->textures && ext != ".splatv";
  if (baked) {
    summary["bake"] = {{"gaussians_in", bake_report.input_gaussians}, {"gaussians_out", bake_report.output_gaussians},
                       {"folded", bake_report.folded}, {"split", bake_report.split},
                       {"fold_better", bake_report.fold_better}, {"fit_rms", bake_report.fit_rms},
                       {"fit_rms_unbaked", bake_report.unbaked_rms}};
  }
  if (a.json) {
    atex::cli::PrintJson(summary);
  } else {
    std::printf("%s -> %s (%s): %llu Gaussians, %llu bytes, %.3f s\n", a.input.c_str(), a.output.c_str(),
                summary["format"].get<std::string>().c_str(), static_cast<unsigned long long>(asset->gaussians.size()),
                static_cast<unsigned long long>(summary["bytes"].get<uint64_t>()),
                summary["write_seconds"].get<double>());
    if (baked) {
      std::printf("  textures baked: %zu Gaussians -> %zu (%zu folded, %zu split); fit RMS over the textured "
                  "ones: %.4f (without baking %.4f)\n",
                  bake_report.input_gaussians, bake_report.output_gaussians, bake_report.folded, bake_report.split,
                  bake_report.fit_rms, bake_report.unbaked_rms);
    }
    if (summary.contains("fit")) {
      const auto& f = summary["fit"];
      std::printf(
          "  motion fit over %d samples: position RMS %.3g (%.3g%% of the scene extent; the motion itself is "
          "%.3g%%), rotation RMS %.3g deg, opacity RMS %.3g\n",
          f["samples"].get<int>(), f["position_rms"].get<double>(), 100 * f["position_rms_relative"].get<double>(),
          100 * f["motion_rms_relative"].get<double>(), f["rotation_rms_deg"].get<double>(),
          f["opacity_rms"].get<double>());
      if (f["psnr_frames"].get<int>() > 0) {
        std::printf("  rendered by libatex over %d times: PSNR %.2f dB against the full asset, %.2f dB against its DC "
                    "colour without textures\n",
                    f["psnr_frames"].get<int>(), f["psnr_full_db"].get<double>(), f["psnr_motion_db"].get<double>());
      }
    }
  }
  return atex::cli::kExitOk;
}

atex::cli::Runner SetupExport(CLI::App& app) {
  auto a = std::make_shared<ExportArgs>();
  app.add_option("input", a->input, "Asset (.atex)")->required();
  app.add_option("output", a->output, "Output: .glb, .gltf (+ .bin), .splatv, or a folder with --frames")->required();
  atex::cli::AddReal(app, "--time", &a->time, -1e9, 1e9, "glTF: bake the deformation at this scene time")
      ->each([a](const std::string&) { a->has_time = true; });
  app.add_option("--frames", a->frames, "Write one baked .glb per time start:end:step into the output folder");
  app.add_flag("--spz", a->spz,
               "glTF: the base attributes as one SPZ stream (KHR_gaussian_splatting_compression_spz_2; lossy, "
               "~20 bytes per Gaussian; no raw parameters)");
  app.add_flag("--quantize", a->quantize,
               "glTF: KHR_mesh_quantization, normalized integer positions, rotations, scales and opacities "
               "(lossy: 16-bit positions and scales in the scene's bounds, 8-bit rotations, 16-bit opacity; SH "
               "stays float; no raw parameters); combines with --meshopt")
      ->excludes("--spz");
  app.add_flag("--meshopt", a->meshopt,
               "glTF: EXT_meshopt_compression (int16 rotations; floats exact unless --meshopt-bits)");
  app.add_option("--meshopt-bits", a->meshopt_bits,
                 "glTF: mantissa bits of the meshopt EXPONENTIAL filter (1-23; 0: exact)")
      ->check(CLI::Range(0, 23));
  app.add_option("--rotation-bits", a->rotation_bits, "glTF: meshopt QUATERNION filter bits")->check(CLI::Range(4, 16));
  app.add_flag("--no-textures", a->no_textures, "glTF: leave out ATEX_gaussian_textures");
  app.add_flag("--bake-textures", a->bake_textures,
               "glTF: bake each textured Gaussian into 1-4 plain Gaussians so that players without "
               "ATEX_gaussian_textures show the texture detail (more Gaussians; no texture extension)");
  app.add_flag("--no-deformation", a->no_deformation, "glTF: leave out the deformation field");
  app.add_flag("--no-raw", a->no_raw, "glTF: leave out the raw parameters (import then inverts the activations)");
  app.add_flag("--no-color", a->no_color, "glTF: leave out the COLOR_0 point-cloud fallback");
  app.add_option(
         "--up", a->up,
         "World up axis of the asset (+x, -x, +y, -y, +z, -z); default: metadata.up (older files: from metadata.axes)")
      ->check(CLI::IsMember({"+y", "-y", "+z", "-z"}));
  app.add_option("--samples", a->samples, "splatv: deformation samples for the motion fit")
      ->check(CLI::Range(4, 100000));
  app.add_option("--psnr", a->psnr_times, "splatv: render this many times with libatex and report the PSNR of the bake")
      ->check(CLI::Range(0, 1000));
  atex::cli::AddForceFlag(app, &a->force);
  app.add_flag("--json", a->json, "Print a machine-readable summary");
  return [a]() { return RunExport(*a); };
}

ATEX_REGISTER_COMMAND("export", "Export an asset to glTF (KHR_gaussian_splatting), a .glb sequence or splaTV",
                      SetupExport);

}  // namespace
