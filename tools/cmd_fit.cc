// `atex fit IN OUT`: trim an asset to a byte budget, a Gaussian count or a quality
// floor. Thin front end over atex/fit_run.h (the method is in atex/fit.h and docs/fit.md): parses,
// calls fit::RunFit, writes the files and prints the report.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <future>
#include <iostream>
#include <optional>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include "atex/container.h"
#include "atex/dataset.h"
#include "atex/file_io.h"
#include "atex/fit.h"
#include "atex/fit_run.h"
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
  int probes = 8, probe_size = 256, eval_views = 0, parallel_candidates = 0;
  double step_growth = 2.0;
  double min_texture_step = atex::fit::PlanOptions{}.min_texture_step;
  int finetune = 0;
  std::string backend = "auto";
  bool keep_stats = false;
  uint64_t seed = 6666;
  std::string levers = "default";
  bool json = false, force = false;
};

using namespace atex;

// The fitter makes, fills and frees copies of the asset (hundreds of MB for a large model) for
// every candidate it measures. glibc serves blocks above 32 MiB with fresh mappings and unmaps
// them when freed, so every copy paid the kernel's page faults and page zeroing (half of an
// encode's time on the Panoptic-sized benchmark, bench_fit). Serve them from the heap and keep
// freed memory in the process instead: the fit reuses it for the next candidate. That holds
// for the main heap only: a thread's own arena (the candidates are prepared on their own
// threads) is a set of 64 MiB heaps, and a larger block there is mapped and unmapped anyway,
// so every thread allocates from the main heap (one arena; the fit's allocations are few and
// large, so the arena's lock is not contended). On the Panoptic-sized synthetic model this
// halved the measurements' encode, decode and apply seconds (BENCHMARKS.md, issue 23).
void KeepFreedMemoryForReuse() {
#if defined(__GLIBC__)
  mallopt(M_ARENA_MAX, 1);
  mallopt(M_MMAP_MAX, 0);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
#endif
}

// The run's backend (`name`: cli::SelectBackend's) and, when `want_eval` and it is a GPU's, a
// second one for the input's test evaluation beside the plan (FitRunOptions::input_eval_backend).
struct FitBackends {
  StatusOr<cli::SelectedBackend> main = Status(StatusCode::kInternal, "backend not started");
  std::optional<cli::SelectedBackend> eval;
};
FitBackends StartBackends(const std::string& name, bool want_eval) {
  FitBackends b;
  b.main = cli::SelectBackend(name);
  if (b.main.ok() && want_eval && b.main->backend->name() == "cuda") {
    auto second = cli::SelectBackend("cuda");
    if (second.ok()) b.eval = std::move(*second);
  }
  return b;
}

// Writes the fitted files (atomically) and prints the report: JSON with --json, else a summary.
int WriteAndPrint(const FitArgs& a, const std::vector<std::string>& budget_texts, size_t input_size,
                  const std::string& backend_description, fit::FitRunReport* run) {
  const char* cmd = "fit";
  nlohmann::json& report = run->json;

  const auto output_for = [&](size_t k) {
    std::string path = a.output;
    const size_t brace = path.find("{}");
    if (brace != std::string::npos) path.replace(brace, 2, budget_texts.empty() ? "fit" : budget_texts[k]);
    return path;
  };
  // outputs[0] is the smallest budget's; the others follow in the order given.
  std::vector<std::string> paths;
  paths.push_back(output_for(run->main_budget_index));
  for (size_t k = 0; k < budget_texts.size(); ++k)
    if (k != run->main_budget_index) paths.push_back(output_for(k));
  for (size_t j = 1; j <= run->outputs.size(); ++j) {  // the others first, then the main output
    const size_t k = j % run->outputs.size();
    const std::vector<uint8_t>& bytes = run->outputs[k].fitted.bytes;
    const auto write_start = std::chrono::steady_clock::now();
    if (Status s = WriteFileAtomic(paths[k], bytes); !s.ok()) return cli::Fail(cmd, s.WithContext(paths[k]));
    report["seconds"]["command_write_outputs"] =
        report["seconds"].value("command_write_outputs", 0.0) +
        std::chrono::duration<double>(std::chrono::steady_clock::now() - write_start).count();
    if (k > 0) {
      report["other_budgets"][k - 1]["path"] = paths[k];
      if (!a.json) std::printf("wrote %s: %zu bytes\n", paths[k].c_str(), bytes.size());
    }
  }
  report["input"]["path"] = a.input;
  report["output"]["path"] = paths[0];
  report["backend"] = backend_description;
  if (report.contains("keep_count")) report["keep_count"]["order_from"] = a.order_from.empty() ? a.input : a.order_from;

  const fit::Fitted& result = run->outputs[0].fitted;
  if (a.json) {
    cli::PrintJson(report);
  } else {
    std::printf("wrote %s: %zu bytes (%.3f MiB) from %zu bytes; %zu of %s Gaussians kept\n", paths[0].c_str(),
                result.bytes.size(), result.bytes.size() / 1048576.0, input_size,
                result.asset.gaussians.size(), report["levers"]["gaussians"]["before"].dump().c_str());
    if (result.smallest_fallback) {
      std::printf("  the plan's moves ended at %llu bytes, above the budget: the output is the smallest asset of the "
                  "levers, the size the budget check names\n",
                  static_cast<unsigned long long>(result.plan_end_bytes));
    }
    for (const fit::Move& m : result.moves) {
      std::printf("  %-45s -> %10llu bytes, proxy PSNR %.2f dB\n", fit::DescribeMove(m).c_str(),
                  static_cast<unsigned long long>(m.bytes_after),
                  m.distortion_after > 0 ? -10.0 * std::log10(m.distortion_after) : 99.0);
    }
    if (report["input"].contains("test") && report["output"].contains("test")) {
      std::printf("test PSNR %.3f -> %.3f dB over %d views\n", report["input"]["test"]["psnr"].get<double>(),
                  report["output"]["test"]["psnr"].get<double>(), report["output"]["test"]["views"].get<int>());
    }
  }
  return cli::kExitOk;
}

int RunFit(const FitArgs& a) {
  const char* cmd = "fit";
  KeepFreedMemoryForReuse();
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
  auto levers = fit::ParseLevers(a.levers);
  if (!levers.ok()) return cli::Fail(cmd, levers.status().WithContext("--levers"));

  fit::FitRunOptions o;
  o.budgets = budgets;
  o.keep_count = a.keep_count;
  o.quality = a.quality;
  o.probes = a.probes;
  o.probe_size = a.probe_size;
  o.eval_views = a.eval_views;
  o.finetune = a.finetune;
  o.keep_stats = a.keep_stats;
  o.seed = a.seed;
  o.levers = *levers;
  o.step_growth = a.step_growth;
  o.min_texture_step = a.min_texture_step;
  o.parallel_candidates = a.parallel_candidates;
  o.progress = [&](const fit::FitProgress& p) {
    if (!a.json) std::cerr << "atex fit: move " << p.move << ": " << p.text << "\n";
  };
  std::optional<cli::Progress> bar;
  if (a.finetune > 0) bar.emplace("finetune", a.finetune);
  o.finetune_progress = [&](const train::TrainProgress& p) {
    if (p.event.empty() && bar) bar->Update(p.step, "PSNR " + std::to_string(p.psnr));
    return true;
  };
  if (Status s = fit::ValidateFitRunOptions(o, !a.data.empty()); !s.ok()) return cli::Fail(cmd, s);

  // The command's own phases, beside RunFit's in the report's "seconds": where a fit's wall
  // time goes outside the library (reading, the GPU's start, the dataset, writing).
  nlohmann::json command_seconds = nlohmann::json::object();
  auto phase_start = std::chrono::steady_clock::now();
  const auto phase_done = [&](const char* name) {
    const auto now = std::chrono::steady_clock::now();
    command_seconds[name] = std::chrono::duration<double>(now - phase_start).count();
    phase_start = now;
  };
  auto input_bytes = ReadFileBytes(a.input);
  if (!input_bytes.ok()) return cli::Fail(cmd, input_bytes.status().WithContext(a.input));
  std::optional<Asset> order_from;
  if (!a.order_from.empty()) {
    auto reference = ReadAssetFile(a.order_from);
    if (!reference.ok()) return cli::Fail(cmd, reference.status().WithContext(a.order_from));
    order_from = std::move(*reference);
    o.order_from = &*order_from;
  }
  phase_done("command_read_input");
  // The backends start (a GPU's context takes a fraction of a second) while the dataset opens.
  // The input's test evaluation runs beside the plan on a second GPU backend
  // (FitRunOptions::input_eval_backend); on the CPU both would share the same cores. Without
  // one it runs before the plan, with the same result.
  auto starting = std::async(std::launch::async, StartBackends, a.backend, !a.data.empty() && !(o.quality > 0));
  std::unique_ptr<Dataset> dataset;
  Status dataset_status = Status::Ok();
  if (!a.data.empty()) {
    // The ground truth is composited on the asset's background, the one its probe renders have.
    auto metadata = DecodeMetadata(input_bytes->data(), input_bytes->size());
    if (!metadata.ok()) {
      dataset_status = metadata.status().WithContext(a.input);
    } else {
      auto opened = cli::OpenDatasetArgs(a.data, a.dataset, &metadata->background);
      if (opened.ok()) dataset = std::move(*opened);
      dataset_status = opened.status();
    }
  }
  phase_done("command_dataset_open");
  FitBackends backends = starting.get();
  auto& backend = backends.main;
  if (!backend.ok()) return cli::Fail(cmd, backend.status());
  if (!backend->note.empty()) std::cerr << "atex fit: " << backend->note << "\n";
  if (backends.eval) o.input_eval_backend = backends.eval->backend.get();
  // What the backends' start took beyond the dataset's opening.
  phase_done("command_backend_start");
  if (!dataset_status.ok()) return cli::Fail(cmd, dataset_status);

  auto run = fit::RunFit(*input_bytes, dataset.get(), backend->backend.get(), o);
  if (bar) bar->Finish();
  if (!run.ok()) return cli::Fail(cmd, run.status().WithContext(a.input));
  for (const auto& [name, seconds] : command_seconds.items()) run->json["seconds"][name] = seconds;
  return WriteAndPrint(a, budget_texts, input_bytes->size(), backend->description, &*run);
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
  cli::AddReal(app, "--step-growth", &a->step_growth, 1, 16,
               "A prune or texture step that wins again grows by this factor (1: fixed 10 % steps)");
  cli::AddReal(app, "--min-texture-step", &a->min_texture_step, 0, 1,
               "A texture step saves at least an estimated this fraction of the bytes to shed (0: no floor)");
  cli::AddInt(app, "--parallel-candidates", &a->parallel_candidates, 0, 64,
              "Candidate moves prepared at once, each holding copies of the asset (0: up to 4 as cores and RAM allow; "
              "1: serial)");
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
