// `atex fit IN OUT`: trim an asset to a byte budget, a Gaussian count or a quality
// floor. Thin front end over atex/fit.h (the method is described there and in docs/fit.md).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <numeric>

#include "atex/container.h"
#include "atex/dataset.h"
#include "atex/file_io.h"
#include "atex/fit.h"
#include "atex/render.h"
#include "atex/train/trainer.h"
#include "asset_view.h"
#include "backend_select.h"
#include "cli.h"
#include "cli_parse.h"

namespace {

struct FitArgs {
  std::string input, output;
  std::string budget;
  double keep_count = 0;
  std::string order_from;
  double quality = 0;
  std::string data;
  atex::cli::DatasetArgs dataset;
  int probes = 8, probe_size = 256, eval_views = 0;
  int finetune = 0;
  std::string backend = "auto";
  bool keep_stats = false;
  uint64_t seed = 6666;
  std::string levers = "default";
  bool json = false, force = false;
};

using namespace atex;

// Evenly spaced subset of `views` (all when count <= 0 or count >= size).
std::vector<View> Spread(const std::vector<View>& views, int count) {
  if (count <= 0 || static_cast<size_t>(count) >= views.size()) return views;
  std::vector<View> out;
  for (int k = 0; k < count; ++k) out.push_back(views[static_cast<size_t>(k) * views.size() / count]);
  return out;
}

StatusOr<train::EvalResult> EvaluateAsset(const Dataset& dataset, train::Backend& backend, const Asset& asset,
                                          const std::vector<View>& views) {
  ATEX_RETURN_IF_ERROR(backend.Load(train::StateFromAsset(asset)));
  return train::Evaluate(dataset, backend, views, train::RenderRequestFor(asset));
}

nlohmann::json MetricsJson(const train::EvalResult& e) {
  return {{"psnr", e.mean.psnr}, {"ssim", e.mean.ssim}, {"dssim1", e.mean.dssim1}, {"dssim2", e.mean.dssim2},
          {"views", e.views.size()}};
}

// What each lever removed between two assets.
nlohmann::json LeverSummary(const Asset& before, const Asset& after, const WriteOptions& write) {
  nlohmann::json j;
  j["gaussians"] = {{"before", before.gaussians.size()}, {"after", after.gaussians.size()}};
  j["sh_degree"] = {{"before", before.gaussians.sh_degree}, {"after", after.gaussians.sh_degree}};
  if (before.textures) {
    j["texels"] = {{"before", before.textures->texel_count()},
                   {"after", after.textures ? after.textures->texel_count() : 0}};
  }
  if (before.deformation && after.deformation) {
    const auto& b = before.deformation->config.grid.base_resolution;
    const auto& a = after.deformation->config.grid.base_resolution;
    j["grid_resolution"] = {{"before", {b[0], b[1], b[2], b[3]}}, {"after", {a[0], a[1], a[2], a[3]}}};
  }
  nlohmann::json enc = nlohmann::json::object();
  for (int s = 0; s < static_cast<int>(fit::Stream::kCount); ++s) {
    enc[fit::StreamName(static_cast<fit::Stream>(s))] =
        ScalarEncodingName(fit::GetEncoding(write, static_cast<fit::Stream>(s)));
  }
  j["encodings"] = enc;
  return j;
}

int RunFit(const FitArgs& a) {
  const char* cmd = "fit";
  const int modes = (!a.budget.empty()) + (a.quality > 0);
  if (modes > 1) {
    return atex::cli::Usage("fit", "--budget and --quality are alternatives");
  }
  if (modes == 0 && a.keep_count <= 0) {
    return atex::cli::Usage("fit", "give --budget SIZE, --keep-count FRACTION or --quality PSNR (see --help)");
  }
  if ((a.quality > 0 || a.finetune > 0) && a.data.empty()) {
    return atex::cli::Usage("fit", "--quality and --finetune need --data");
  }
  // One budget, or several separated by commas sharing one plan (OUTPUT then names each
  // file with "{}", replaced by the budget as written).
  std::vector<uint64_t> budgets;
  std::vector<std::string> budget_texts;
  if (!a.budget.empty()) {
    auto parsed = cli::ParseByteSizeList(a.budget, "--budget", &budget_texts);
    if (!parsed.ok()) return cli::Usage(cmd, parsed.status().message());
    budgets = std::move(*parsed);
  }
  if (budgets.size() > 1 && a.output.find("{}") == std::string::npos) {
    return atex::cli::Usage("fit", "several budgets need an OUTPUT with {} (e.g. out_{}.atex)");
  }
  if (budgets.size() > 1 && a.finetune > 0) {
    return atex::cli::Usage("fit", "--finetune takes one budget");
  }
  for (size_t k = 0; k < std::max<size_t>(1, budgets.size()); ++k) {
    std::string path = a.output;
    if (const size_t brace = path.find("{}"); brace != std::string::npos) {
      path.replace(brace, 2, budget_texts.empty() ? "fit" : budget_texts[k]);
    }
    if (Status s = cli::CheckOutput(path, a.force, {{a.input, a.order_from}, {".atex"}}); !s.ok()) {
      return cli::Fail(cmd, s, path);
    }
  }
  const uint64_t budget = budgets.empty() ? 0 : *std::min_element(budgets.begin(), budgets.end());
  auto levers = fit::ParseLevers(a.levers);
  if (!levers.ok()) return cli::Fail(cmd, levers.status().WithContext("--levers"));

  // Wall seconds per phase, for the report: where a long fit spends its time.
  nlohmann::json phase_seconds = nlohmann::json::object();
  auto phase_start = std::chrono::steady_clock::now();
  const auto phase_done = [&](const char* name) {
    const auto now = std::chrono::steady_clock::now();
    phase_seconds[name] = phase_seconds.value(name, 0.0) + std::chrono::duration<double>(now - phase_start).count();
    phase_start = now;
  };

  auto input_bytes = ReadFileBytes(a.input);
  if (!input_bytes.ok()) return cli::Fail(cmd, input_bytes.status().WithContext(a.input));
  auto decoded = DecodeAsset(input_bytes->data(), input_bytes->size());
  if (!decoded.ok()) return cli::Fail(cmd, decoded.status().WithContext(a.input));
  Asset input = std::move(*decoded);
  WriteOptions base;
  base.write_stats = a.keep_stats;
  auto write = fit::EncodingsOfFile(input_bytes->data(), input_bytes->size(), base);
  if (!write.ok()) return cli::Fail(cmd, write.status().WithContext(a.input));
  phase_done("read_input");

  auto backend = cli::SelectBackend(a.backend);
  if (!backend.ok()) return cli::Fail(cmd, backend.status());
  if (!backend->note.empty()) std::cerr << "atex fit: " << backend->note << "\n";

  std::unique_ptr<Dataset> dataset;
  if (!a.data.empty()) {
    auto opened = cli::OpenDatasetArgs(a.data, a.dataset, &input.metadata.background);  // probes match renders
    if (!opened.ok()) return cli::Fail(cmd, opened.status());
    dataset = std::move(*opened);
  }

  // Probes: training views (scaled down) with a dataset, orbit views without.
  std::vector<fit::Probe> probes;
  if (dataset) {
    for (const View& v : Spread(dataset->train_views(), a.probes)) probes.push_back({fit::ScaleCamera(v.camera, a.probe_size)});
  } else {
    probes = fit::OrbitProbes(input, a.probes, a.probe_size, std::max(1, a.probe_size * 3 / 4));
  }
  if (Status s = fit::EnsureImportance(&input, probes); !s.ok()) return cli::Fail(cmd, s);
  phase_done("backend_dataset_probes");

  nlohmann::json report;
  report["input"] = {{"path", a.input}, {"bytes", input_bytes->size()}, {"components", fit::ComponentsToJson(*input_bytes)}};
  report["backend"] = backend->description;
  report["distortion"] = dataset ? "mean squared difference to the input's renders of training views"
                                 : "mean squared difference to the input's renders of orbit views (proxy)";

  const std::vector<View> eval_views = dataset ? Spread(dataset->test_views(), a.eval_views) : std::vector<View>{};
  if (dataset && !eval_views.empty()) {
    auto before = EvaluateAsset(*dataset, *backend->backend, input, eval_views);
    if (!before.ok()) return cli::Fail(cmd, before.status());
    report["input"]["test"] = MetricsJson(*before);
    phase_done("evaluate_input");
  }

  // Fixed-count protocol first (it may be combined with a budget).
  Asset working = input;
  std::vector<uint32_t> kept(input.gaussians.size());
  std::iota(kept.begin(), kept.end(), 0u);
  if (a.keep_count > 0) {
    std::vector<uint32_t> order;
    if (!a.order_from.empty()) {
      auto reference = ReadAssetFile(a.order_from);
      if (!reference.ok()) return cli::Fail(cmd, reference.status().WithContext(a.order_from));
      if (Status s = fit::EnsureImportance(&*reference, probes); !s.ok()) return cli::Fail(cmd, s);
      order = fit::ImportanceOrder(*reference, a.seed);
    } else {
      order = fit::ImportanceOrder(input, a.seed);
    }
    auto subset = fit::KeepMostImportant(input, order, a.keep_count, &kept);
    if (!subset.ok()) return cli::Fail(cmd, subset.status());
    working = std::move(*subset);
    report["keep_count"] = {{"fraction", a.keep_count}, {"kept", working.gaussians.size()},
                            {"order_from", a.order_from.empty() ? a.input : a.order_from}};
  }

  fit::ProbeRenderer renderer(backend->backend.get(), probes);
  fit::Plan shared_plan;
  nlohmann::json plan_timings = nlohmann::json::array();  // one per plan built (two with --finetune)
  const auto fit_once = [&](const Asset& start, const WriteOptions& start_write, uint64_t target,
                            bool quality_mode) -> StatusOr<fit::Fitted> {
    fit::PlanOptions o;
    o.write = start_write;
    o.seed = a.seed;
    o.floor_bytes = quality_mode ? 0 : target;
    o.levers = *levers;
    o.progress = [&](const fit::FitProgress& p) {
      if (!a.json) std::cerr << "atex fit: move " << p.move << ": " << p.text << "\n";
    };
    if (quality_mode) {
      o.accept_more = [&](const Asset& candidate, const fit::Move&) -> StatusOr<bool> {
        ATEX_ASSIGN_OR_RETURN(train::EvalResult e, EvaluateAsset(*dataset, *backend->backend, candidate, eval_views));
        return e.mean.psnr >= a.quality;
      };
    } else {
      ATEX_RETURN_IF_ERROR(fit::CheckBudget(start, start_write, target, o.min_grid_resolution, o.levers));
    }
    ATEX_ASSIGN_OR_RETURN(fit::Plan plan, fit::BuildPlan(start, &renderer, o));
    shared_plan = plan;
    const uint64_t goal = quality_mode ? (plan.moves.empty() ? plan.initial_bytes : plan.moves.back().bytes_after) : target;
    auto fitted = fit::ApplyPlan(start, plan, start_write, goal);
    nlohmann::json timing = fit::TimingToJson(plan.timing);
    if (fitted.ok()) {
      timing["apply_plan_seconds"] = fitted->apply_seconds;
      timing["refill_seconds"] = fitted->refill_seconds;
    }
    plan_timings.push_back(std::move(timing));
    return fitted;
  };

  fit::Fitted result;
  if (!a.budget.empty() || a.quality > 0) {
    auto fitted = fit_once(working, *write, budget, a.quality > 0);
    if (!fitted.ok()) return cli::Fail(cmd, fitted.status());
    for (uint32_t& k : fitted->kept) k = kept[k];  // back to input indices
    result = std::move(*fitted);
  } else {
    auto bytes = EncodeAsset(working, *write);
    if (!bytes.ok()) return cli::Fail(cmd, bytes.status());
    result.asset = working;
    result.bytes = std::move(*bytes);
    result.write = *write;
    result.kept = kept;
  }
  phase_done("fit");  // plan and apply, or the encode of a --keep-count subset

  if (a.finetune > 0) {
    // Retrain the trimmed model (topology and texture sizes fixed), then fit again.
    train::TrainerOptions topts;
    topts.config = train::DefaultConfig(dataset->kind() == DatasetKind::kPanoptic ? "panoptic" : "dnerf");
    topts.config.seed = a.seed;
    topts.config.stage1.sh_degree = result.asset.gaussians.sh_degree;
    topts.config.stage2.iterations = a.finetune;
    topts.config.stage2.growth_steps.clear();
    topts.config.background = result.asset.metadata.background;
    auto mode = ParseTextureMode(result.asset.metadata.texture_mode);
    topts.config.stage2.textures = mode.ok() ? *mode : TextureMode::kNone;
    if (!result.asset.textures) topts.config.stage2.textures = TextureMode::kNone;
    topts.config.eval_every = 0;
    topts.config.checkpoint_every = 0;
    topts.stages = train::kStage2;
    cli::Progress bar("finetune", a.finetune);
    topts.progress = [&](const train::TrainProgress& p) {
      if (p.event.empty()) bar.Update(p.step, "PSNR " + std::to_string(p.psnr));
      return true;
    };
    auto tuned = train::Train(*dataset, *backend->backend, topts, &result.asset);
    bar.Finish();
    if (!tuned.ok()) return cli::Fail(cmd, tuned.status());
    Asset retrained = std::move(tuned->asset);
    retrained.metadata = result.asset.metadata;
    const uint64_t target = a.budget.empty() ? ~uint64_t{0} : budget;
    auto refit = fit_once(retrained, result.write, target, false);
    if (!refit.ok()) return cli::Fail(cmd, refit.status().WithContext("re-fit after fine-tuning"));
    for (uint32_t& k : refit->kept) k = result.kept[k];
    report["finetune"] = {{"steps", a.finetune}, {"seconds", tuned->textures_seconds},
                          {"refit_moves", refit->moves.size()}};
    result = std::move(*refit);
    phase_done("finetune_and_refit");
  }

  const auto output_for = [&](size_t k) {
    std::string path = a.output;
    const size_t brace = path.find("{}");
    if (brace != std::string::npos) path.replace(brace, 2, budget_texts.empty() ? "fit" : budget_texts[k]);
    return path;
  };
  // The other budgets of a list reuse the plan built for the smallest one.
  nlohmann::json others = nlohmann::json::array();
  for (size_t k = 0; k < budgets.size(); ++k) {
    if (budgets[k] == budget) continue;
    auto fitted = fit::ApplyPlan(working, shared_plan, *write, budgets[k]);
    if (!fitted.ok()) return cli::Fail(cmd, fitted.status());
    const std::string path = output_for(k);
    if (Status s = WriteFileAtomic(path, fitted->bytes); !s.ok()) return cli::Fail(cmd, s.WithContext(path));
    nlohmann::json o = {{"path", path}, {"budget_bytes", budgets[k]}, {"bytes", fitted->bytes.size()},
                        {"components", fit::ComponentsToJson(fitted->bytes)},
                        {"levers", LeverSummary(input, fitted->asset, fitted->write)}};
    if (dataset && !eval_views.empty()) {
      auto after = EvaluateAsset(*dataset, *backend->backend, fitted->asset, eval_views);
      if (!after.ok()) return cli::Fail(cmd, after.status());
      o["test"] = MetricsJson(*after);
    }
    if (!a.json) std::printf("wrote %s: %zu bytes\n", path.c_str(), fitted->bytes.size());
    others.push_back(o);
  }
  size_t smallest_index = 0;
  for (size_t k = 0; k < budgets.size(); ++k)
    if (budgets[k] == budget) smallest_index = k;
  const std::string output_path = output_for(smallest_index);
  if (Status s = WriteFileAtomic(output_path, result.bytes); !s.ok()) return cli::Fail(cmd, s.WithContext(output_path));
  if (!others.empty()) report["other_budgets"] = others;
  phase_done("other_budgets_and_write");

  report["output"] = {{"path", output_path}, {"bytes", result.bytes.size()}, {"components", fit::ComponentsToJson(result.bytes)}};
  if (!a.budget.empty()) report["budget_bytes"] = budget;
  if (a.quality > 0) report["quality_floor_psnr"] = a.quality;
  report["levers"] = LeverSummary(input, result.asset, result.write);
  if (!a.budget.empty() || a.quality > 0) {  // a plan was built
    report["levers"]["allowed"] = fit::LeverSetNames(*levers);
  }
  nlohmann::json moves = nlohmann::json::array();
  for (const fit::Move& m : result.moves) moves.push_back(fit::MoveToJson(m));
  report["moves"] = moves;
  if (!plan_timings.empty()) report["plan_timing"] = plan_timings;
  if (!result.moves.empty()) {
    const double d = result.moves.back().distortion_after;
    report["estimated_psnr_vs_input"] = d > 0 ? -10.0 * std::log10(d) : 99.0;
  }
  if (dataset && !eval_views.empty()) {
    auto after = EvaluateAsset(*dataset, *backend->backend, result.asset, eval_views);
    if (!after.ok()) return cli::Fail(cmd, after.status());
    report["output"]["test"] = MetricsJson(*after);
    phase_done("evaluate_output");
  }
  report["seconds"] = phase_seconds;
  if (a.json) {
    cli::PrintJson(report);
  } else {
    std::printf("wrote %s: %zu bytes (%.3f MiB) from %zu bytes; %zu of %zu Gaussians kept\n", output_path.c_str(),
                result.bytes.size(), result.bytes.size() / 1048576.0, input_bytes->size(),
                result.asset.gaussians.size(), input.gaussians.size());
    for (const fit::Move& m : result.moves) {
      std::printf("  %-45s -> %10llu bytes, proxy PSNR %.2f dB\n", fit::DescribeMove(m).c_str(),
                  static_cast<unsigned long long>(m.bytes_after),
                  m.distortion_after > 0 ? -10.0 * std::log10(m.distortion_after) : 99.0);
    }
    if (report["input"].contains("test") && report["output"].contains("test")) {
      std::printf("test PSNR %.3f -> %.3f dB over %zu views\n", report["input"]["test"]["psnr"].get<double>(),
                  report["output"]["test"]["psnr"].get<double>(), eval_views.size());
    }
  }
  return cli::kExitOk;
}

atex::cli::Runner SetupFit(CLI::App& app) {
  auto a = std::make_shared<FitArgs>();
  app.add_option("input", a->input, "The .atex to fit")->required();
  app.add_option("output", a->output, "Where to write the fitted .atex (atomically)")->required();
  app.add_option("--budget", a->budget,
                 "Largest output file size: bytes or 80MiB, 80MB, 1.5GiB ...; several, comma-separated, share "
                 "one plan (OUTPUT then contains {}, replaced by each budget)");
  cli::AddReal(app, "--keep-count", &a->keep_count, 1e-9, 1.0,
               "Keep this fraction (0, 1] of the Gaussians, most important first (fixed-count protocol)");
  app.add_option("--order-from", a->order_from,
                 "Take the importance order from this asset (same Gaussians, e.g. the shared stage-1 model)");
  cli::AddReal(app, "--quality", &a->quality, 1e-9, 200,
               "Smallest asset whose test PSNR stays at or above this (needs --data)");
  app.add_option("--data", a->data, "Dataset: distortion from its training views, PSNR on its test views");
  atex::cli::AddDatasetOptions(app, &a->dataset);
  cli::AddInt(app, "--probes", &a->probes, 1, 100000, "Views the distortion is measured from");
  cli::AddInt(app, "--probe-size", &a->probe_size, 8, 16384, "Longer side of the probe renders in pixels");
  cli::AddInt(app, "--eval-views", &a->eval_views, 0, 1 << 24, "Test views for PSNR (evenly spaced; 0 = all)");
  cli::AddInt(app, "--finetune", &a->finetune, 0, 100000000,
              "Retrain the trimmed model this many steps, then fit again (needs --data)");
  app.add_option("--backend", a->backend, "auto, cuda or cpu")->capture_default_str();
  app.add_flag("--keep-stats", a->keep_stats, "Keep the per-Gaussian statistics (GSTA) for later fits");
  cli::AddUint64(app, "--seed", &a->seed, "Breaks importance ties");
  cli::AddForceFlag(app, &a->force);
  app.add_option("--levers", a->levers,
                 "Levers the fit may use, comma-separated: prune, textures, sh, encoding, grid, all-textures; "
                 "default = the first five. 'prune' alone, or 'prune,all-textures', is the paper's fixed-memory "
                 "protocol: the model's own texture allocation and precision kept (docs/fit.md)")
      ->capture_default_str();
  app.add_flag("--json", a->json, "Machine-readable report on stdout");
  return [a]() { return RunFit(*a); };
}

ATEX_REGISTER_COMMAND("fit", "Fit an asset to a byte budget, a Gaussian count or a PSNR floor", SetupFit);

}  // namespace
