// `atex train`: stage 1 (4DGS) and/or stage 2 (AdaTex4D textures) on a dataset.
#include <cstdio>
#include <fstream>
#include <iostream>

#include "asset_view.h"
#include "atex/container.h"
#include "atex/dataset.h"
#include "atex/file_io.h"
#include "atex/train/checkpoint.h"
#include "atex/train/config_check.h"
#include "atex/train/trainer.h"
#include "backend_select.h"
#include "cli.h"
#include "cli_parse.h"
#include "train_ranks.h"

namespace {

struct TrainArgs {
  std::string data, out, config_file, stage = "all", textures, backend = "auto", init, checkpoint_dir, resume,
      metrics, gpus;
  atex::cli::DatasetArgs dataset;
  int ranks = 1;  // --ranks: CPU ranks as threads
  std::vector<std::string> overrides;
  int checkpoint_every = -1;
  long long seed = -1;
  bool json = false, print_config = false, fp32 = false, profile = false, force = false;
  double time_limit = 0;
};

// The config of this run: the dataset kind's defaults with the dataset's background (or the
// --init asset's, whose model was trained on it), or a resumed checkpoint's config; then
// --config, --set and the flags on top. Not yet validated (CrossCheckConfig does that).
atex::StatusOr<atex::train::TrainConfig> BuildConfig(const TrainArgs& a, const atex::Dataset* data,
                                                     const atex::Asset* initial) {
  using namespace atex;
  // --print-config without a dataset: the kind named by --dataset-kind.
  DatasetKind dataset_kind =
      ParseDatasetKind(a.dataset.kind).ok() ? *ParseDatasetKind(a.dataset.kind) : DatasetKind::kAuto;
  if (data) dataset_kind = data->kind();
  const std::string kind = train::DefaultConfigKind(dataset_kind);
  train::TrainConfig config = train::DefaultConfig(kind);
  config.background = data ? data->background() : DefaultBackground(dataset_kind);
  if (initial) config.background = initial->metadata.background;
  if (!a.resume.empty()) {
    ATEX_ASSIGN_OR_RETURN(train::Checkpoint cp, train::ReadCheckpoint(a.resume));
    if (cp.trainer.contains("config")) {
      ATEX_ASSIGN_OR_RETURN(config, train::ConfigFromJson(cp.trainer.at("config"), config));
    }
  }
  if (!a.config_file.empty()) {
    ATEX_ASSIGN_OR_RETURN(auto bytes, ReadFileBytes(a.config_file, 16 << 20));
    const auto json = nlohmann::json::parse(bytes.begin(), bytes.end(), nullptr, false);
    if (json.is_discarded()) return MakeError(StatusCode::kInvalidArgument, a.config_file, ": not valid JSON");
    ATEX_ASSIGN_OR_RETURN(config, train::ConfigFromJson(json, config));
  }
  for (const auto& o : a.overrides) {
    ATEX_ASSIGN_OR_RETURN(config, train::ApplyOverride(config, o));
  }
  if (!a.textures.empty()) {
    ATEX_ASSIGN_OR_RETURN(config.stage2.textures, ParseTextureMode(a.textures));
  }
  if (a.seed >= 0) config.seed = static_cast<uint64_t>(a.seed);
  if (a.checkpoint_every >= 0) config.checkpoint_every = a.checkpoint_every;
  return config;
}

// Training progress on stderr: one bar per phase, events as lines between them.
class PhaseProgress {
 public:
  bool Show(const atex::train::TrainProgress& p) {
    if (!p.event.empty()) {
      std::cerr << (bar_ && bar_->tty() ? "\n" : "") << "atex train: " << p.event << "\n";
      return true;
    }
    if (p.phase != phase_) {
      if (bar_) bar_->Finish();  // the previous phase's last update already drew its final state
      bar_ = std::make_unique<atex::cli::Progress>(p.phase, p.total);
      phase_ = p.phase;
    }
    char detail[160];
    std::snprintf(detail, sizeof detail, "loss %.4f PSNR %.2f  %zu Gaussians", p.loss, p.psnr, p.gaussians);
    bar_->Update(p.step, detail);
    return true;
  }
  void Finish() {
    if (bar_) bar_->Finish();
  }

 private:
  std::unique_ptr<atex::cli::Progress> bar_;
  std::string phase_;
};

// --print-config: the config a run would start from; with --data, the defaults of that
// dataset's kind.
int PrintConfig(const TrainArgs& a) {
  using namespace atex;
  const char* cmd = "train";
  std::unique_ptr<Dataset> data;
  if (!a.data.empty()) {
    auto opened = cli::OpenDatasetArgs(a.data, a.dataset);
    if (!opened.ok()) return cli::Fail(cmd, opened.status(), a.data);
    data = std::move(*opened);
  }
  auto config = BuildConfig(a, data.get(), nullptr);
  if (!config.ok()) return cli::Fail(cmd, config.status());
  cli::PrintJson(train::ConfigToJson(*config));
  return cli::kExitOk;
}

// The --stage value as train::kStage* flags; 0 when it is not 1, 2 or all.
int ParseStages(const std::string& stage) {
  if (stage == "1") return atex::train::kStage1;
  if (stage == "2") return atex::train::kStage2;
  if (stage == "all") return atex::train::kBothStages;
  return 0;
}

// Writes the trained asset to --out, then the report: JSON with --json, else three lines.
int WriteTrainOutputs(const TrainArgs& a, const atex::train::TrainSummary& summary, const nlohmann::json& background,
                      const atex::cli::SelectedBackend& backend) {
  using namespace atex;
  const char* cmd = "train";
  WriteOptions write;
  const Status written = WriteAssetFile(a.out, summary.asset, write);
  if (!written.ok()) return cli::Fail(cmd, written.WithContext(a.out), a.out);
  nlohmann::json report = train::SummaryToJson(summary);
  report["background"] = background;
  report["output"] = a.out;
  report["backend"] = backend.description;
  if (a.profile) report["profile"] = backend.backend->Profile();
  if (auto bytes = ReadFileBytes(a.out); bytes.ok()) report["model_bytes"] = bytes->size();
  if (a.json) {
    cli::PrintJson(report);
    return cli::kExitOk;
  }
  std::printf("wrote %s: %zu Gaussians, %.2f MiB\n", a.out.c_str(), summary.asset.gaussians.size(),
              report.value("model_bytes", 0.0) / (1024.0 * 1024.0));
  std::printf("time: coarse %.1f s, fine %.1f s, textures %.1f s; peak device memory %.2f GiB\n",
              summary.coarse_seconds, summary.fine_seconds, summary.textures_seconds,
              summary.peak_memory_bytes / double(1ull << 30));
  if (!summary.test.views.empty()) {
    const auto& m = summary.test.mean;
    std::printf("test views: PSNR %.3f dB  SSIM %.4f  DSSIM1 %.4f  DSSIM2 %.4f\n", m.psnr, m.ssim, m.dssim1, m.dssim2);
  }
  return cli::kExitOk;
}

int RunTrain(const TrainArgs& a) {
  using namespace atex;
  const char* cmd = "train";
  if (a.print_config) return PrintConfig(a);
  if (a.data.empty() || a.out.empty()) return cli::Usage(cmd, "--data and --out are required (see --help)");
  const int stages = ParseStages(a.stage);
  if (stages == 0) return cli::Usage(cmd, "--stage must be 1, 2 or all");
  // Data parallelism (docs/multi_gpu.md): several GPUs make this process a launcher of one child
  // per GPU; a launcher's environment (RANK, WORLD_SIZE, ...) makes it one rank of the group.
  bool launched = false;
  auto launch = train::ReadLaunchEnvironment(&launched);
  if (!launch.ok()) return cli::Fail(cmd, launch.status());
  launched = launched && launch->world_size > 1;
  cli::BackendChoice choice;
  if (!a.gpus.empty() && !launched) {
    auto gpus = cli::ParseGpuList(a.gpus);
    if (!gpus.ok()) return cli::Usage(cmd, gpus.status().message());
    if (gpus->size() > 1) {
      if (a.ranks > 1) return cli::Usage(cmd, "--gpus with several GPUs and --ranks exclude each other");
      if (!cli::MultiGpuAvailable()) {
        return cli::Fail(cmd, MakeError(StatusCode::kUnsupported, "--gpus ", a.gpus, ": this build has no NCCL ",
                                        "(or no CUDA backend), so it trains on one GPU; rebuild with the CUDA "
                                        "toolkit's NCCL (ATEX_NCCL=ON) or pass one GPU"));
      }
      auto code = cli::LaunchGpuRanks(*gpus);
      if (!code.ok()) return cli::Fail(cmd, code.status());
      return *code;
    }
    choice.device = gpus->front();
  }
  if (a.ranks > 1 && (a.backend != "cpu" || launched)) {
    return cli::Usage(cmd, "--ranks runs ranks as threads of the CPU backend: it needs --backend cpu");
  }
  std::unique_ptr<train::Communicator> group_comm;
  if (launched) {
    if (a.backend == "cpu") return cli::Usage(cmd, "ranks of separate processes train on GPUs: not --backend cpu");
    auto joined = cli::JoinLaunchedGroup(*launch, &choice.device);
    if (!joined.ok()) return cli::Fail(cmd, joined.status());
    group_comm = std::move(*joined);
  }
  const bool root = group_comm == nullptr || group_comm->rank() == 0;
  // The output is checked before hours of training, not after.
  if (Status s = cli::CheckOutput(a.out, a.force, {{a.init, a.data, a.config_file}, {".atex"}, "--out"}); !s.ok()) {
    return cli::Fail(cmd, s, a.out);
  }
  auto dataset = cli::OpenDatasetArgs(a.data, a.dataset);
  if (!dataset.ok()) return cli::Fail(cmd, dataset.status(), a.data);
  for (const auto& w : (*dataset)->warnings()) std::cerr << "atex train: note: " << w << "\n";
  Asset initial;
  if (!a.init.empty()) {
    auto asset = ReadAssetFile(a.init);
    if (!asset.ok()) return cli::Fail(cmd, asset.status().WithContext(a.init), a.init);
    initial = std::move(*asset);
  }
  auto config = BuildConfig(a, dataset->get(), a.init.empty() ? nullptr : &initial);
  if (!config.ok()) return cli::Fail(cmd, config.status());
  // One background: the frames are composited on the training background (a setting
  // different from the dataset's default reopens it with that background).
  std::string background_reason = DefaultBackgroundReason((*dataset)->kind());
  if (config->background != (*dataset)->background()) {
    auto reopened = cli::OpenDatasetArgs(a.data, a.dataset, &config->background);
    if (!reopened.ok()) return cli::Fail(cmd, reopened.status(), a.data);
    dataset = std::move(reopened);
    background_reason = a.init.empty() ? "set by the config" : "the --init asset's";
  } else if (!a.init.empty()) {
    background_reason = "the --init asset's";
  }
  const auto& bg = config->background;
  std::cerr << "atex train: background [" << bg[0] << ", " << bg[1] << ", " << bg[2] << "] (" << background_reason
            << ")\n";
  if (Status s = train::CrossCheckConfig(*config, **dataset, stages, nullptr); !s.ok()) return cli::Fail(cmd, s);

  train::TrainerOptions options;
  options.config = *config;
  options.stages = stages;
  options.checkpoint_dir = a.checkpoint_dir;
  options.resume_dir = a.resume;
  options.metrics_csv = a.metrics;
  options.communicator = group_comm.get();

  choice.tf32 = !a.fp32;
  choice.profile = a.profile;
  options.time_limit_seconds = a.time_limit;
  auto backend = cli::SelectBackend(a.backend, choice);
  if (!backend.ok()) return cli::Fail(cmd, backend.status());
  if (!backend->note.empty()) std::cerr << "atex train: " << backend->note << "\n";
  std::cerr << "atex train: " << (*dataset)->name() << ", " << (*dataset)->train_views().size() << " training and "
            << (*dataset)->test_views().size() << " test views; backend " << backend->description << "\n";

  PhaseProgress bar;
  options.progress = [&bar](const train::TrainProgress& p) { return bar.Show(p); };
  const Asset* init = a.init.empty() ? nullptr : &initial;
  StatusOr<train::TrainSummary> summary = MakeError(StatusCode::kInternal, "no rank trained");
  if (a.ranks > 1) {
    // Rank 0 trains on the selected backend; the others on CPU backends of their own.
    const Status status = cli::RunThreadRanks(a.ranks, [&](int rank, train::Communicator& comm) -> Status {
      train::TrainerOptions mine = options;
      mine.communicator = &comm;
      std::unique_ptr<train::Backend> own = rank == 0 ? nullptr : train::MakeCpuBackend();
      auto trained = train::Train(**dataset, rank == 0 ? *backend->backend : *own, mine, init);
      if (rank == 0) summary = std::move(trained);
      return trained.ok() || rank == 0 ? Status::Ok() : trained.status();
    });
    if (!status.ok() && summary.ok()) summary = status;
  } else {
    summary = train::Train(**dataset, *backend->backend, options, init);
  }
  bar.Finish();
  if (!summary.ok()) return cli::Fail(cmd, summary.status());
  if (!root) return cli::kExitOk;  // rank 0 writes the asset and the report
  return WriteTrainOutputs(a, *summary, {{"rgb", config->background}, {"reason", background_reason}}, *backend);
}

atex::cli::Runner SetupTrain(CLI::App& app) {
  auto a = std::make_shared<TrainArgs>();
  app.add_option("--data", a->data, "Dataset folder (Panoptic, D-NeRF, N3DV) or the tiny-lego .npz");
  app.add_option("--out,-o", a->out, "Output .atex");
  app.add_option("--config", a->config_file, "JSON training config (a copy of --print-config's output, changed)");
  app.add_option("--set", a->overrides, "Override one config value, e.g. --set stage1.batch_size=2 (repeatable)");
  app.add_option("--stage", a->stage, "1 (4DGS), 2 (textures on --init), or all")->capture_default_str();
  app.add_option("--textures", a->textures,
                 "Stage-2 texture mode: adaptive, uniform or none (with --stage 2: the same fine-tuning without "
                 "textures; with --stage all: stage 1 only)");
  app.add_option("--backend", a->backend, "auto, cuda or cpu")->capture_default_str();
  app.add_option("--gpus", a->gpus,
                 "GPU indices, e.g. 0,1: one rank per GPU (data parallel, NCCL; docs/multi_gpu.md); the batch "
                 "sizes are the global ones (multiples of the GPU count); each GPU keeps its share of the "
                 "training images (--set images_on_every_gpu=true: every image, faster, more memory)");
  atex::cli::AddInt(app, "--ranks", &a->ranks, 1, 64,
                    "With --backend cpu: this many data-parallel ranks as threads (checks multi-GPU semantics)");
  app.add_option("--init", a->init, "Stage-1 asset to start stage 2 from");
  app.add_option("--checkpoint-dir", a->checkpoint_dir, "Write periodic checkpoints here (atomically)");
  atex::cli::AddInt(app, "--checkpoint-every", &a->checkpoint_every, 0, 100000000,
                    "Steps between checkpoints (overrides the config)");
  app.add_option("--resume", a->resume,
                 "Continue from a checkpoint folder, with its config (--config/--set may change schedules, not the "
                 "model) on the dataset it was trained on");
  app.add_option("--metrics", a->metrics, "Write a metrics CSV (one row per logged step)");
  atex::cli::AddDatasetOptions(app, &a->dataset);
  atex::cli::AddInt64(app, "--seed", &a->seed, 0, std::numeric_limits<long long>::max(),
                      "Random seed (default: the config's, 6666)");
  app.add_flag("--print-config", a->print_config,
               "Print the default config as JSON and exit (of --data's dataset kind, or --dataset-kind)");
  app.add_flag("--fp32", a->fp32, "CUDA: full FP32 for the deformation MLP (default: TF32 tensor cores)");
  app.add_flag("--profile", a->profile, "CUDA: time each stage of a training step (in the --json report)");
  atex::cli::AddReal(app, "--time-limit", &a->time_limit, 0, 1e9,
                     "Stop after this many seconds of training and write what there is (0 = no limit)");
  atex::cli::AddForceFlag(app, &a->force);
  app.add_flag("--json", a->json, "Machine-readable report on stdout");
  return [a]() { return RunTrain(*a); };
}

ATEX_REGISTER_COMMAND("train", "Train a 4DGS model (stage 1) and AdaTex4D textures (stage 2) on a dataset",
                      SetupTrain);

}  // namespace
