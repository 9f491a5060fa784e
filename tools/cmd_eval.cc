// `atex eval`: PSNR / SSIM / DSSIM of an asset on a dataset's test views.
#include <cstdio>
#include <iostream>

#include "asset_view.h"
#include "atex/dataset.h"
#include "atex/train/trainer.h"
#include "backend_select.h"
#include "cli.h"
#include "cli_parse.h"

namespace {

struct EvalArgs {
  std::string asset, data, backend = "auto", split = "test";
  atex::cli::DatasetArgs dataset;
  double near_plane = atex::kDefaultNearPlane;
  double dynamic_threshold = atex::kDefaultDynamicThreshold;
  bool json = false;
};

int RunEval(const EvalArgs& a) {
  using namespace atex;
  const char* cmd = "eval";
  if (a.split != "test" && a.split != "train") return cli::Usage(cmd, "--split must be test or train");
  auto backend = cli::SelectBackend(a.backend);
  if (!backend.ok()) return cli::Fail(cmd, backend.status());
  if (!backend->note.empty()) std::cerr << "atex eval: " << backend->note << "\n";
  Asset asset;
  train::RenderRequest request;
  if (Status s = cli::LoadAssetIntoBackend(a.asset, backend->backend.get(), &asset, &request); !s.ok()) {
    return cli::Fail(cmd, s, a.asset);
  }
  // Ground truth composited on the asset's background, the one its renders have.
  auto dataset = cli::OpenDatasetArgs(a.data, a.dataset, &asset.metadata.background);
  if (!dataset.ok()) return cli::Fail(cmd, dataset.status(), a.data);
  request.near_plane = static_cast<float>(a.near_plane);
  const auto& views = a.split == "test" ? (*dataset)->test_views() : (*dataset)->train_views();
  auto eval = train::Evaluate(**dataset, *backend->backend, views, request,
                              {.dynamic_region = true, .dynamic_threshold = a.dynamic_threshold});
  if (!eval.ok()) return cli::Fail(cmd, eval.status());
  if (a.json) {
    nlohmann::json j = train::EvalToJson(*eval);
    j["asset"] = a.asset;
    j["split"] = a.split;
    j["backend"] = backend->description;
    j["background"] = asset.metadata.background;
    cli::PrintJson(j);
  } else {
    for (const auto& c : train::EvalToJson(*eval)["cameras"]) {
      std::printf("camera %3d (%2d views): PSNR %.3f  SSIM %.4f  DSSIM1 %.4f  DSSIM2 %.4f", c["camera"].get<int>(),
                  c["views"].get<int>(), c["psnr"].get<double>(), c["ssim"].get<double>(), c["dssim1"].get<double>(),
                  c["dssim2"].get<double>());
      if (c["dynamic_psnr"].is_number()) {
        std::printf("  dynamic PSNR %.3f (%.1f %% of pixels)", c["dynamic_psnr"].get<double>(),
                    100.0 * c["dynamic_fraction"].get<double>());
      }
      std::printf("\n");
    }
    const auto& m = eval->mean;
    std::printf("mean over %zu %s views: PSNR %.3f dB  SSIM %.4f  DSSIM1 %.4f  DSSIM2 %.4f", eval->views.size(),
                a.split.c_str(), m.psnr, m.ssim, m.dssim1, m.dssim2);
    if (eval->dynamic_views > 0) std::printf("  dynamic PSNR %.3f dB", eval->dynamic_psnr);
    std::printf("\n");
  }
  return cli::kExitOk;
}

atex::cli::Runner SetupEval(CLI::App& app) {
  auto a = std::make_shared<EvalArgs>();
  app.add_option("asset", a->asset, "The .atex to evaluate")->required();
  app.add_option("--data", a->data, "Dataset folder or .npz")->required();
  app.add_option("--split", a->split, "test or train")->capture_default_str();
  app.add_option("--backend", a->backend, "auto, cuda or cpu")->capture_default_str();
  atex::cli::AddDatasetOptions(app, &a->dataset);
  atex::cli::AddReal(app, "--near-plane", &a->near_plane, 1e-9, 1e9,
                     "Cull Gaussians at camera z <= this (scene units; training's default)");
  atex::cli::AddReal(app, "--dynamic-threshold", &a->dynamic_threshold, 0.0, 1.0,
                     "Dynamic region: pixels whose ground truth's temporal std (RMS over RGB, values in [0, 1]) over "
                     "the camera's frames exceeds this (atex/dynamic_region.h)");
  app.add_flag("--json", a->json, "Machine-readable output");
  return [a]() { return RunEval(*a); };
}

ATEX_REGISTER_COMMAND("eval", "Evaluate an asset on a dataset's test views (PSNR, SSIM, DSSIM, dynamic-region PSNR)",
                      SetupEval);

}  // namespace
