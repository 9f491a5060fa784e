// `atex render`: one image of an asset from a dataset camera or an explicit camera.
#include <cmath>
#include <cstdio>
#include <iostream>

#include "asset_view.h"
#include "atex/dataset.h"
#include "atex/image.h"
#include "backend_select.h"
#include "cli.h"
#include "cli_parse.h"

namespace {

struct RenderArgs {
  std::string asset, data, view = "test:0", out, ground_truth, backend = "auto", size;
  atex::cli::DatasetArgs dataset;
  std::vector<double> intrinsics, world_to_camera;
  double time = std::numeric_limits<double>::quiet_NaN();
  bool json = false, force = false;
};

int RunRender(const RenderArgs& a) {
  using namespace atex;
  const char* cmd = "render";
  const bool explicit_camera = !a.size.empty() || !a.intrinsics.empty() || !a.world_to_camera.empty();
  if (!a.data.empty() && explicit_camera) {
    return cli::Usage(cmd, "--size, --intrinsics and --world-to-camera describe an explicit camera; with --data the "
                           "camera is the dataset's (--view): give one or the other");
  }
  if (a.data.empty() && !a.ground_truth.empty()) return cli::Usage(cmd, "--ground-truth needs --data");
  const std::vector<std::string> image_extensions = {".png", ".jpg", ".jpeg", ".exr"};
  if (Status s = cli::CheckOutput(a.out, a.force, {{a.asset}, image_extensions, "-o"}); !s.ok()) {
    return cli::Fail(cmd, s, a.out);
  }
  if (!a.ground_truth.empty()) {
    if (Status s = cli::CheckOutput(a.ground_truth, a.force, {{a.asset, a.out}, image_extensions, "--ground-truth"});
        !s.ok()) {
      return cli::Fail(cmd, s, a.ground_truth);
    }
    if (a.ground_truth == a.out) return cli::Usage(cmd, "--ground-truth and -o name the same file");
  }
  auto backend = cli::SelectBackend(a.backend);
  if (!backend.ok()) return cli::Fail(cmd, backend.status());
  Asset asset;
  train::RenderRequest request;
  if (Status s = cli::LoadAssetIntoBackend(a.asset, backend->backend.get(), &asset, &request); !s.ok()) {
    return cli::Fail(cmd, s, a.asset);
  }
  View view;
  std::unique_ptr<Dataset> dataset;
  if (!a.data.empty()) {
    // The ground truth is composited on the asset's background, as the renderer draws it.
    auto opened = cli::OpenDatasetArgs(a.data, a.dataset, &asset.metadata.background);
    if (!opened.ok()) return cli::Fail(cmd, opened.status(), a.data);
    dataset = std::move(*opened);
    auto picked = cli::PickView(*dataset, a.view);
    if (!picked.ok()) return cli::Fail(cmd, picked.status());
    view = *picked;
  } else {
    if (a.size.empty() || a.intrinsics.size() != 4 || a.world_to_camera.size() != 16) {
      return cli::Usage(cmd, "give --data (and --view), or --size WxH --intrinsics fx fy cx cy --world-to-camera "
                             "(16 values, row-major)");
    }
    auto size = cli::ParseImageSize(a.size, "--size");
    if (!size.ok()) return cli::Usage(cmd, size.status().message());
    view.camera.width = size->width;
    view.camera.height = size->height;
    view.camera.fx = a.intrinsics[0];
    view.camera.fy = a.intrinsics[1];
    view.camera.cx = a.intrinsics[2];
    view.camera.cy = a.intrinsics[3];
    if (!(view.camera.fx > 0 && view.camera.fy > 0)) return cli::Usage(cmd, "--intrinsics: fx and fy must be > 0");
    std::copy(a.world_to_camera.begin(), a.world_to_camera.end(), view.camera.world_to_camera.begin());
  }
  if (!std::isnan(a.time)) view.camera.time = a.time;
  auto image = backend->backend->Render(view.camera, request);
  if (!image.ok()) return cli::Fail(cmd, image.status());
  for (float& v : image->pixels) v = std::clamp(v, 0.0f, 1.0f);
  if (Status s = WriteImage(a.out, *image); !s.ok()) return cli::Fail(cmd, s, a.out);
  if (!a.ground_truth.empty()) {
    auto target = dataset->LoadImage(view);
    if (!target.ok()) return cli::Fail(cmd, target.status());
    if (Status s = WriteImage(a.ground_truth, **target); !s.ok()) return cli::Fail(cmd, s, a.ground_truth);
  }
  if (a.json) {
    cli::PrintJson({{"output", a.out}, {"width", view.camera.width}, {"height", view.camera.height},
                    {"time", view.camera.time}, {"camera", view.camera_id}, {"backend", backend->description},
                    {"background", asset.metadata.background}});
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
  app.add_option("--ground-truth", a->ground_truth,
                 "Also write the dataset's image of that view here (composited on the asset's background)");
  atex::cli::AddReal(app, "--time", &a->time, -1e9, 1e9, "Scene time (default: the view's)");
  app.add_option("--size", a->size, "WxH of an explicit camera (not with --data)");
  atex::cli::AddReals(app, "--intrinsics", &a->intrinsics, 4, "fx fy cx cy of an explicit camera");
  atex::cli::AddReals(app, "--world-to-camera", &a->world_to_camera, 16, "16 values, row-major, OpenCV axes");
  app.add_option("--backend", a->backend, "auto, cuda or cpu")->capture_default_str();
  atex::cli::AddDatasetOptions(app, &a->dataset);
  atex::cli::AddForceFlag(app, &a->force);
  app.add_flag("--json", a->json, "Machine-readable output");
  return [a]() { return RunRender(*a); };
}

ATEX_REGISTER_COMMAND("render", "Render an asset from a dataset camera or an explicit camera", SetupRender);

}  // namespace
