// `atex view ASSET -o scene.html`: one self-contained HTML page that plays the asset in a
// browser (no server, no network). Thin front end over atex/converters/view.h.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "asset_view.h"
#include "atex/container.h"
#include "atex/converters/view.h"
#include "cli.h"
#include "cli_parse.h"

namespace {

struct ViewArgs {
  std::string input, output, data, view = "test:0", size, up, title;
  atex::cli::DatasetArgs dataset;
  std::vector<double> intrinsics, world_to_camera;
  int frames = 0;
  long long max_splats = 0;
  double max_mib = double(atex::kViewDefaultMaxBytes) / (1 << 20);
  bool json = false, force = false, no_compress = false;
};

// The opening camera: a dataset's (--data, --view), an explicit one (--size ...), or none.
atex::StatusOr<std::optional<atex::Camera>> OpeningCamera(const ViewArgs& a, const atex::Asset& asset) {
  using namespace atex;
  if (!a.data.empty()) {
    ATEX_ASSIGN_OR_RETURN(std::unique_ptr<Dataset> dataset,
                          cli::OpenDatasetArgs(a.data, a.dataset, &asset.metadata.background));
    ATEX_ASSIGN_OR_RETURN(View view, cli::PickView(*dataset, a.view));
    return std::optional<Camera>(view.camera);
  }
  if (a.size.empty()) return std::optional<Camera>();
  ATEX_ASSIGN_OR_RETURN(cli::ImageSize size, cli::ParseImageSize(a.size, "--size"));
  Camera c;
  c.width = size.width, c.height = size.height;
  c.fx = a.intrinsics[0], c.fy = a.intrinsics[1], c.cx = a.intrinsics[2], c.cy = a.intrinsics[3];
  std::copy(a.world_to_camera.begin(), a.world_to_camera.end(), c.world_to_camera.begin());
  return std::optional<Camera>(c);
}

int RunView(const ViewArgs& a) {
  using namespace atex;
  const char* cmd = "view";
  const bool explicit_camera = !a.size.empty() || !a.intrinsics.empty() || !a.world_to_camera.empty();
  if (!a.data.empty() && explicit_camera) {
    return cli::Usage(cmd, "--size, --intrinsics and --world-to-camera describe an explicit camera; with --data the "
                           "camera is the dataset's (--view): give one or the other");
  }
  if (explicit_camera && (a.size.empty() || a.intrinsics.size() != 4 || a.world_to_camera.size() != 16)) {
    return cli::Usage(
        cmd, "an explicit camera needs --size WxH, --intrinsics fx fy cx cy and --world-to-camera (16 values)");
  }
  if (Status s = cli::CheckOutput(a.output, a.force, {{a.input}, {".html", ".htm"}, "-o"}); !s.ok()) {
    return cli::Fail(cmd, s, a.output);
  }
  auto asset = ReadAssetFile(a.input);
  if (!asset.ok()) return cli::Fail(cmd, asset.status(), a.input);

  ViewOptions options;
  options.frames = a.frames;
  options.max_splats = size_t(a.max_splats);
  options.compress = !a.no_compress;
  options.max_bytes = uint64_t(a.max_mib * double(1 << 20));
  options.title = a.title.empty() ? std::filesystem::path(a.input).filename().string() : a.title;
  if (!a.up.empty()) {
    auto up = ParseUpAxis(a.up);
    if (!up.ok()) return cli::Fail(cmd, up.status());
    options.up = *up;
  }
  auto camera = OpeningCamera(a, *asset);
  if (!camera.ok()) return cli::Fail(cmd, camera.status(), a.data);
  options.camera = *camera;
  cli::Progress progress("bake keyframes", 1000);
  options.progress = [&progress](double f) {
    progress.Update(std::min(999LL, static_cast<long long>(f * 1000)));
    return true;
  };
  ViewReport report;
  const auto start = std::chrono::steady_clock::now();
  Status s = WriteViewHtml(a.output, *asset, options, &report);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  progress.Finish();
  if (!s.ok()) return cli::Fail(cmd, s, a.output);

  nlohmann::json summary = report.ToJson();
  summary["input"] = a.input;
  summary["output"] = a.output;
  summary["background"] = asset->metadata.background;
  summary["write_seconds"] = seconds;  // bake, compress, write
  if (a.json) {
    cli::PrintJson(summary);
    return cli::kExitOk;
  }
  std::printf("%s -> %s: %zu of %zu Gaussians, %zu keyframe(s), %.2f MiB, %.1f s\n", a.input.c_str(), a.output.c_str(),
              report.kept, report.gaussians, report.times.size(), double(report.html_bytes) / (1 << 20), seconds);
  for (const auto& n : report.notes) std::printf("  note: %s\n", n.c_str());
  for (const auto& w : report.warnings) std::printf("  approximation: %s\n", w.c_str());
  std::printf("  open it in a browser (file:// works): drag to orbit, right-drag to pan, wheel to zoom\n");
  return cli::kExitOk;
}

atex::cli::Runner SetupView(CLI::App& app) {
  auto a = std::make_shared<ViewArgs>();
  app.add_option("asset", a->input, "The .atex to show")->required();
  app.add_option("-o,--out", a->output, "Output page (.html)")->required();
  app.add_option("--frames", a->frames,
                 "Keyframes baked over the time range (default: 2 x (time nodes of the deformation grid - 1) + 1, "
                 "2..120; at most 256); fewer when the page would exceed --max-mib")
      ->check(CLI::Range(2, atex::kViewMaxFrames));
  app.add_option(
         "--max-splats", a->max_splats,
         "Keep at most this many Gaussians, those with the largest opacity x volume (default: all; the page holds "
         "at most 4,194,304)")
      ->check(CLI::PositiveNumber);
  atex::cli::AddReal(app, "--max-mib", &a->max_mib, 0.01, 1e6,
                     "Cap on the page's size in MiB (keyframes are dropped to fit)");
  app.add_option("--data", a->data, "Dataset whose camera (--view) the page opens with");
  app.add_option("--view", a->view, "test:N or train:N (with --data)")->capture_default_str();
  app.add_option("--size", a->size, "WxH of an explicit opening camera (not with --data)");
  atex::cli::AddReals(app, "--intrinsics", &a->intrinsics, 4, "fx fy cx cy of an explicit opening camera");
  atex::cli::AddReals(app, "--world-to-camera", &a->world_to_camera, 16, "16 values, row-major, OpenCV axes");
  app.add_option("--up", a->up, "World up axis (default: metadata.up; older files: from metadata.axes)")
      ->check(CLI::IsMember({"+x", "-x", "+y", "-y", "+z", "-z"}));
  app.add_flag("--no-compress", a->no_compress,
               "Plain base64 arrays, for browsers without DecompressionStream (before Chrome 80, Firefox 113, "
               "Safari 16.4); up to about 3x larger");
  app.add_option("--title", a->title, "Page title (default: the asset's file name)");
  atex::cli::AddDatasetOptions(app, &a->dataset);
  atex::cli::AddForceFlag(app, &a->force);
  app.add_flag("--json", a->json, "Print a machine-readable summary (keyframe times, opening camera, sizes)");
  app.footer(app.get_footer() +
             "\n\nThe page bakes the deformation at the keyframes with libatex's CPU deformation and interpolates "
             "between them; colour is the DC term plus each texture's average (approximations listed in the "
             "summary). Without --data or --size the page opens upright (the asset's up axis), framing the scene.");
  return [a]() { return RunView(*a); };
}

ATEX_REGISTER_COMMAND("view", "Write one self-contained HTML page that plays the asset in a browser", SetupView);

}  // namespace
