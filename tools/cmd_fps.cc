// `atex fps`: render speed of an asset (deformation included) at a dataset camera,
// optionally re-framed to another resolution with the same pose and field of view
// per pixel (the principal point stays centred on the same ray).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <iostream>

#include "asset_view.h"
#include "atex/dataset.h"
#include "backend_select.h"
#include "cli.h"
#include "cli_parse.h"
#ifdef ATEX_HAVE_CUDA
#include "atex/cuda/cuda_backend.h"
#endif

namespace {

struct FpsArgs {
  std::string asset, data, view = "test:0", size, backend = "auto";
  atex::cli::DatasetArgs dataset;
  int repeats = 100;
  bool json = false;
};

// Same pose, focal lengths scaled by width'/width, the image centre kept on the same ray.
atex::Camera Reframe(const atex::Camera& c, int width, int height) {
  atex::Camera out = c;
  const double s = double(width) / c.width;
  out.fx = c.fx * s;
  out.fy = c.fy * s;
  out.cx = c.cx * s + 0.5 * (width - c.width * s);
  out.cy = c.cy * s + 0.5 * (height - c.height * s);
  out.width = width;
  out.height = height;
  return out;
}

int RunFps(const FpsArgs& a) {
  using namespace atex;
  const char* cmd = "fps";
  auto dataset = cli::OpenDatasetArgs(a.data, a.dataset);
  if (!dataset.ok()) return cli::Fail(cmd, dataset.status(), a.data);
  // A malformed --view is an error with the spec, never an exception.
  auto view = cli::PickView(**dataset, a.view);
  if (!view.ok()) return cli::Fail(cmd, view.status());
  Camera camera = view->camera;
  if (!a.size.empty()) {
    auto size = cli::ParseImageSize(a.size, "--size");
    if (!size.ok()) return cli::Usage(cmd, size.status().message());
    camera = Reframe(camera, size->width, size->height);
  }
  auto backend = cli::SelectBackend(a.backend);
  if (!backend.ok()) return cli::Fail(cmd, backend.status());
  Asset asset;
  train::RenderRequest request;
  if (Status s = cli::LoadAssetIntoBackend(a.asset, backend->backend.get(), &asset, &request); !s.ok()) {
    return cli::Fail(cmd, s);
  }
  double median_ms = 0;
  std::string method;
#ifdef ATEX_HAVE_CUDA
  if (backend->backend->name() == "cuda") {
    auto timing = cuda::TimeRender(*backend->backend, camera, request, a.repeats);
    if (!timing.ok()) return cli::Fail(cmd, timing.status());
    median_ms = timing->median_ms;
    method = "CUDA events, median of " + std::to_string(a.repeats) + " after 10 warm-up renders";
  }
#endif
  if (method.empty()) {  // CPU reference: wall clock around complete renders
    std::vector<double> times;
    const int repeats = std::min(a.repeats, 5);
    for (int i = 0; i < repeats; ++i) {
      const auto start = std::chrono::steady_clock::now();
      auto image = backend->backend->Render(camera, request);
      if (!image.ok()) return cli::Fail(cmd, image.status());
      times.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
    }
    std::sort(times.begin(), times.end());
    median_ms = times[times.size() / 2];
    method = "wall clock, median of " + std::to_string(repeats);
  }
  const double fps = 1000.0 / median_ms;
  if (a.json) {
    cli::PrintJson({{"asset", a.asset},        {"width", camera.width}, {"height", camera.height},
                    {"gaussians", asset.gaussians.size()}, {"median_ms", median_ms}, {"fps", fps},
                    {"method", method},        {"backend", backend->description}});
  } else {
    std::printf("%dx%d, %zu Gaussians: %.3f ms per frame, %.1f FPS (%s; %s)\n", camera.width, camera.height,
                asset.gaussians.size(), median_ms, fps, method.c_str(), backend->description.c_str());
  }
  return cli::kExitOk;
}

atex::cli::Runner SetupFps(CLI::App& app) {
  auto a = std::make_shared<FpsArgs>();
  app.add_option("asset", a->asset, "The .atex to render")->required();
  app.add_option("--data", a->data, "Dataset whose camera to use")->required();
  app.add_option("--view", a->view, "test:N or train:N")->capture_default_str();
  app.add_option("--size", a->size, "Re-frame the camera to WxH (e.g. 1352x1014)");
  atex::cli::AddInt(app, "--repeats", &a->repeats, 1, 1000000, "Timed renders (at least 1)");
  app.add_option("--backend", a->backend, "auto, cuda or cpu")->capture_default_str();
  atex::cli::AddDatasetOptions(app, &a->dataset);
  app.add_flag("--json", a->json, "Machine-readable output");
  return [a]() { return RunFps(*a); };
}

ATEX_REGISTER_COMMAND("fps", "Measure render speed (deformation included) of an asset", SetupFps);

}  // namespace
