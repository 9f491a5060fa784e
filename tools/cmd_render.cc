// `atex render`: one image of an asset from a dataset camera or an explicit camera.
#include <cstdio>
#include <iostream>

#include "asset_view.h"
#include "atex/dataset.h"
#include "atex/image.h"
#include "backend_select.h"
#include "cli.h"

namespace {

struct RenderArgs {
  std::string asset, data, view = "test:0", out, ground_truth, backend = "auto", size;
  atex::cli::DatasetArgs dataset;
  std::vector<double> intrinsics, world_to_camera;
  double time = std::numeric_limits<double>::quiet_NaN();
  bool json = false;
};

int RunRender(const RenderArgs& a) {
  using namespace atex;
  const char* cmd = "render";
  View view;
  std::unique_ptr<Dataset> dataset;
  if (!a.data.empty()) {
    auto opened = cli::OpenDatasetArgs(a.data, a.dataset);
    if (!opened.ok()) return cli::Fail(cmd, opened.status());
    dataset = std::move(*opened);
    auto picked = cli::PickView(*dataset, a.view);
    if (!picked.ok()) return cli::Fail(cmd, picked.status());
    view = *picked;
  } else {
    int w = 0, h = 0;
    if (std::sscanf(a.size.c_str(), "%dx%d", &w, &h) != 2 || a.intrinsics.size() != 4 ||
        a.world_to_camera.size() != 16) {
      std::cerr << "atex render: give --data (and --view), or --size WxH --intrinsics fx cx... --world-to-camera "
                   "(16 values, row-major)\n";
      return cli::kExitUsage;
    }
    view.camera.width = w;
    view.camera.height = h;
    view.camera.fx = a.intrinsics[0];
    view.camera.fy = a.intrinsics[1];
    view.camera.cx = a.intrinsics[2];
    view.camera.cy = a.intrinsics[3];
    std::copy(a.world_to_camera.begin(), a.world_to_camera.end(), view.camera.world_to_camera.begin());
  }
  if (!std::isnan(a.time)) view.camera.time = a.time;
  auto backend = cli::SelectBackend(a.backend);
  if (!backend.ok()) return cli::Fail(cmd, backend.status());
  Asset asset;
  train::RenderRequest request;
  if (Status s = cli::LoadAssetIntoBackend(a.asset, backend->backend.get(), &asset, &request); !s.ok()) {
    return cli::Fail(cmd, s);
  }
  auto image = backend->backend->Render(view.camera, request);
  if (!image.ok()) return cli::Fail(cmd, image.status());
  for (float& v : image->pixels) v = std::clamp(v, 0.0f, 1.0f);
  if (Status s = WriteImage(a.out, *image); !s.ok()) return cli::Fail(cmd, s);
  if (!a.ground_truth.empty()) {
    if (!dataset) {
      std::cerr << "atex render: --ground-truth needs --data\n";
      return cli::kExitUsage;
    }
    auto target = dataset->LoadImage(view);
    if (!target.ok()) return cli::Fail(cmd, target.status());
    if (Status s = WriteImage(a.ground_truth, **target); !s.ok()) return cli::Fail(cmd, s);
  }
  if (a.json) {
    cli::PrintJson({{"output", a.out}, {"width", view.camera.width}, {"height", view.camera.height},
                    {"time", view.camera.time}, {"camera", view.camera_id}, {"backend", backend->description}});
  } else {
    std::printf("wrote %s (%dx%d, time %.4f)\n", a.out.c_str(), view.camera.width, view.camera.height,
                view.camera.time);
  }
  return cli::kExitOk;
}

atex::cli::Runner SetupRender(CLI::App& app) {
  auto a = std::make_shared<RenderArgs>();
  app.add_option("asset", a->asset, "The .atex to render")->required();
  app.add_option("-o,--out", a->out, "Output image (.png, .jpg, .exr)")->required();
  app.add_option("--data", a->data, "Dataset whose camera to use");
  app.add_option("--view", a->view, "test:N or train:N")->capture_default_str();
  app.add_option("--ground-truth", a->ground_truth, "Also write the dataset's image of that view here");
  app.add_option("--time", a->time, "Scene time (default: the view's)");
  app.add_option("--size", a->size, "WxH of an explicit camera");
  app.add_option("--intrinsics", a->intrinsics, "fx fy cx cy of an explicit camera")->expected(4);
  app.add_option("--world-to-camera", a->world_to_camera, "16 values, row-major, OpenCV axes")->expected(16);
  app.add_option("--backend", a->backend, "auto, cuda or cpu")->capture_default_str();
  atex::cli::AddDatasetOptions(app, &a->dataset);
  app.add_flag("--json", a->json, "Machine-readable output");
  return [a]() { return RunRender(*a); };
}

ATEX_REGISTER_COMMAND("render", "Render an asset from a dataset camera or an explicit camera", SetupRender);

}  // namespace
