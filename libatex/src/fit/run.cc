// RunFit (fit_run.h): one `atex fit` run, from the input's bytes to the fitted files
// and the report.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <future>
#include <numeric>
#include <optional>

#include "atex/container.h"
#include "atex/fit_run.h"
#include "atex/render.h"
#include "atex/train/config.h"

namespace atex::fit {
namespace {

// The report's note on an output that is the levers' smallest asset (Fitted::smallest_fallback).
nlohmann::json SmallestFallbackJson(const Fitted& fitted) {
  return {{"plan_end_bytes", fitted.plan_end_bytes}, {"bytes", fitted.bytes.size()}};
}

// Proxy PSNR of a distortion (mean squared difference to the input's renders).
double ProxyPsnr(double distortion) { return distortion > 0 ? -10.0 * std::log10(distortion) : 99.0; }

// Evenly spaced subset of `views` (all when count <= 0 or count >= size).
std::vector<View> Spread(const std::vector<View>& views, int count) {
  if (count <= 0 || static_cast<size_t>(count) >= views.size()) return views;
  std::vector<View> out;
  for (int k = 0; k < count; ++k) out.push_back(views[static_cast<size_t>(k) * views.size() / count]);
  return out;
}

// `metric_threads`: EvalOptions::metric_threads.
StatusOr<train::EvalResult> EvaluateAsset(const Dataset& dataset, train::Backend& backend, const Asset& asset,
                                          const std::vector<View>& views, int metric_threads = 0) {
  ATEX_RETURN_IF_ERROR(backend.Load(train::RenderStateFromAsset(asset)));
  // The report gives the mean PSNR and SSIMs (MetricsJson), not the dynamic-region PSNR,
  // whose regions would cost a pass over every frame of the test cameras.
  train::EvalOptions options;
  options.dynamic_region = false;
  options.metric_threads = metric_threads;
  return train::Evaluate(dataset, backend, views, train::RenderRequestFor(asset), options);
}

nlohmann::json MetricsJson(const train::EvalResult& e) {
  return {{"psnr", e.mean.psnr}, {"ssim", e.mean.ssim}, {"dssim1", e.mean.dssim1}, {"dssim2", e.mean.dssim2},
          {"views", e.views.size()}};
}

// Wall seconds per phase of the run, for the report: where a long fit spends its time.
class PhaseClock {
 public:
  void Done(const char* name) {
    const auto now = std::chrono::steady_clock::now();
    seconds_[name] = seconds_.value(name, 0.0) + std::chrono::duration<double>(now - start_).count();
    start_ = now;
  }
  const nlohmann::json& seconds() const { return seconds_; }

 private:
  nlohmann::json seconds_ = nlohmann::json::object();
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

// The state of one run shared by its steps.
class Run {
 public:
  Run(const Dataset* dataset, train::Backend* backend, const FitRunOptions& o)
      : dataset_(dataset), backend_(backend), o_(o) {}

  StatusOr<FitRunReport> Go(const std::vector<uint8_t>& input_bytes);

 private:
  Status ReadInput(const std::vector<uint8_t>& input_bytes);
  Status JoinInputTest();  // the input's test evaluation, when it runs beside the plan
  Status KeepCount();
  StatusOr<Fitted> FitOnce(const Asset& start, const WriteOptions& start_write, uint64_t target, bool quality_mode);
  Status Finetune(Fitted* result);
  StatusOr<nlohmann::json> Test(const Asset& asset);
  StatusOr<FitRunOutput> Output(uint64_t budget, Fitted fitted);

  const Dataset* dataset_;
  train::Backend* backend_;
  const FitRunOptions& o_;
  PhaseClock clock_;
  nlohmann::json report_;
  Asset input_;
  WriteOptions write_;
  std::vector<Probe> probes_;
  std::vector<View> eval_views_;
  std::optional<ProbeRenderer> renderer_;
  Asset working_;               // the input, or its keep-count subset
  std::vector<uint32_t> kept_;  // input indices of working_'s Gaussians
  Plan shared_plan_;
  std::optional<double> initial_distortion_;               // of the last plan built: an output without moves has it
  nlohmann::json plan_timings_ = nlohmann::json::array();  // one per plan built (two with fine-tuning)
  // The input's test evaluation on FitRunOptions::input_eval_backend. Last: destroyed first, its
  // destructor waits for the task, which reads the members above.
  double input_test_seconds_ = 0;
  std::future<StatusOr<nlohmann::json>> input_test_;
};

Status Run::ReadInput(const std::vector<uint8_t>& input_bytes) {
  ATEX_ASSIGN_OR_RETURN(input_, DecodeAsset(input_bytes.data(), input_bytes.size()));
  WriteOptions base;
  base.write_stats = o_.keep_stats;
  ATEX_ASSIGN_OR_RETURN(write_, EncodingsOfFile(input_bytes.data(), input_bytes.size(), base));
  clock_.Done("read_input");
  // Probes: training views (scaled down) with a dataset, orbit views without.
  if (dataset_ != nullptr) {
    for (const View& v : Spread(dataset_->train_views(), o_.probes))
      probes_.push_back({ScaleCamera(v.camera, o_.probe_size)});
    eval_views_ = Spread(dataset_->test_views(), o_.eval_views);
  } else {
    probes_ = OrbitProbes(input_, o_.probes, o_.probe_size, std::max(1, o_.probe_size * 3 / 4));
  }
  renderer_.emplace(backend_, probes_);
  ATEX_RETURN_IF_ERROR(renderer_->EnsureImportance(&input_));
  clock_.Done("backend_dataset_probes");
  report_["input"] = {{"bytes", input_bytes.size()}, {"components", ComponentsToJson(input_bytes)}};
  report_["backend"] = backend_ != nullptr ? backend_->name() : std::string("cpu");
  report_["distortion"] = dataset_ ? "mean squared difference to the input's renders of training views"
                                   : "mean squared difference to the input's renders of orbit views (proxy)";
  if (eval_views_.empty()) return Status::Ok();
  if (o_.input_eval_backend != nullptr && !(o_.quality > 0)) {
    // Beside the plan, on the second backend; joined by JoinInputTest. Reads input_, which no
    // step changes after this one.
    input_test_ = std::async(std::launch::async, [this]() -> StatusOr<nlohmann::json> {
      const auto start = std::chrono::steady_clock::now();
      // Two threads for its metrics: the plan's preparations keep the other cores, and the
      // evaluation still ends well before the plan.
      ATEX_ASSIGN_OR_RETURN(train::EvalResult e,
                            EvaluateAsset(*dataset_, *o_.input_eval_backend, input_, eval_views_, 2));
      input_test_seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      return MetricsJson(e);
    });
    return Status::Ok();
  }
  ATEX_ASSIGN_OR_RETURN(report_["input"]["test"], Test(input_));
  clock_.Done("evaluate_input");
  return Status::Ok();
}

Status Run::JoinInputTest() {
  if (!input_test_.valid()) return Status::Ok();
  ATEX_ASSIGN_OR_RETURN(report_["input"]["test"], input_test_.get());
  // The wait for it (the phase), and its own wall time beside the plan (not a phase).
  clock_.Done("evaluate_input");
  report_["input"]["test_seconds_beside_plan"] = input_test_seconds_;
  return Status::Ok();
}

StatusOr<nlohmann::json> Run::Test(const Asset& asset) {
  if (backend_ == nullptr) return MakeError(StatusCode::kInvalidArgument, "fit: test metrics need a backend");
  ATEX_ASSIGN_OR_RETURN(train::EvalResult e, EvaluateAsset(*dataset_, *backend_, asset, eval_views_));
  return MetricsJson(e);
}

// The fixed-count protocol (it may be combined with a budget).
Status Run::KeepCount() {
  working_ = input_;
  kept_.resize(input_.gaussians.size());
  std::iota(kept_.begin(), kept_.end(), 0u);
  if (o_.keep_count <= 0) return Status::Ok();
  std::vector<uint32_t> order;
  if (o_.order_from != nullptr) {
    Asset reference = *o_.order_from;
    ATEX_RETURN_IF_ERROR(EnsureImportance(&reference, probes_));
    order = ImportanceOrder(reference, o_.seed);
  } else {
    order = ImportanceOrder(input_, o_.seed);
  }
  ATEX_ASSIGN_OR_RETURN(working_, KeepMostImportant(input_, order, o_.keep_count, &kept_));
  report_["keep_count"] = {{"fraction", o_.keep_count}, {"kept", working_.gaussians.size()}};
  return Status::Ok();
}

StatusOr<Fitted> Run::FitOnce(const Asset& start, const WriteOptions& start_write, uint64_t target,
                              bool quality_mode) {
  PlanOptions p;
  p.write = start_write;
  p.seed = o_.seed;
  p.floor_bytes = quality_mode ? 0 : target;
  p.levers = o_.levers;
  p.step_growth = o_.step_growth;
  p.min_texture_step = o_.min_texture_step;
  p.parallel_candidates = o_.parallel_candidates;
  p.progress = o_.progress;
  p.cancelled = o_.cancelled;
  if (quality_mode) {
    p.accept_more = [&](const Asset& candidate, const Move&) -> StatusOr<bool> {
      ATEX_ASSIGN_OR_RETURN(train::EvalResult e, EvaluateAsset(*dataset_, *backend_, candidate, eval_views_));
      return e.mean.psnr >= o_.quality;
    };
  } else {
    ATEX_RETURN_IF_ERROR(CheckBudget(start, start_write, target, p.min_grid_resolution, p.levers));
  }
  ATEX_ASSIGN_OR_RETURN(Plan plan, BuildPlan(start, &*renderer_, p));
  shared_plan_ = plan;
  initial_distortion_ = plan.initial_distortion;
  const uint64_t goal =
      quality_mode ? (plan.moves.empty() ? plan.initial_bytes : plan.moves.back().bytes_after) : target;
  auto fitted = ApplyPlan(start, plan, start_write, goal);
  nlohmann::json timing = TimingToJson(plan.timing);
  if (fitted.ok()) {
    timing["apply_plan_seconds"] = fitted->apply_seconds;
    timing["refill_seconds"] = fitted->refill_seconds;
    timing["apply_plan_encodes"] = fitted->trial_encodes;
    timing["apply_plan_encode_seconds"] = fitted->trial_encode_seconds;
    timing["refill_encodes"] = fitted->refill_encodes;
    timing["refill_encode_seconds"] = fitted->refill_encode_seconds;
    timing["refill_state_seconds"] = fitted->refill_state_seconds;
    timing["refill_trials"] = fitted->refill_trials;
  }
  plan_timings_.push_back(std::move(timing));
  return fitted;
}

// Retrains the trimmed model (topology and texture sizes fixed), then fits it again.
Status Run::Finetune(Fitted* result) {
  train::TrainerOptions topts = FinetuneOptions(*dataset_, result->asset, o_.finetune, o_.seed);
  topts.progress = o_.finetune_progress;
  ATEX_ASSIGN_OR_RETURN(train::TrainSummary tuned, train::Train(*dataset_, *backend_, topts, &result->asset));
  Asset retrained = std::move(tuned.asset);
  retrained.metadata = result->asset.metadata;
  const uint64_t target = o_.budgets.empty() ? ~uint64_t{0} : o_.budgets.front();
  auto refit = FitOnce(retrained, result->write, target, false);
  const StatusCode code = refit.ok() ? StatusCode::kOk : refit.status().code();
  if (code == StatusCode::kBudgetTooSmall || code == StatusCode::kOutOfRange) {
    // Training moved the values, and with them the compressed size of the smallest asset: a
    // budget at the input's minimum may be a few bytes short for the retrained one. The fit
    // from before fine-tuning meets the budget; it is kept, and the report says why.
    report_["finetune"] = {{"steps", o_.finetune}, {"seconds", tuned.textures_seconds},
                           {"discarded", refit.status().ToString()}};
    clock_.Done("finetune_and_refit");
    return Status::Ok();
  }
  if (!refit.ok()) return refit.status().WithContext("re-fit after fine-tuning");
  for (uint32_t& k : refit->kept) k = result->kept[k];
  report_["finetune"] = {{"steps", o_.finetune}, {"seconds", tuned.textures_seconds},
                         {"refit_moves", refit->moves.size()}};
  *result = std::move(*refit);
  clock_.Done("finetune_and_refit");
  return Status::Ok();
}

StatusOr<FitRunOutput> Run::Output(uint64_t budget, Fitted fitted) {
  FitRunOutput out;
  out.budget_bytes = budget;
  out.report = {{"budget_bytes", budget},
                {"bytes", fitted.bytes.size()},
                {"components", ComponentsToJson(fitted.bytes)},
                {"levers", LeverSummary(input_, fitted.asset, fitted.write)}};
  if (fitted.smallest_fallback) {
    out.report["smallest_fallback"] = SmallestFallbackJson(fitted);
  } else if (!fitted.moves.empty()) {
    out.report["estimated_psnr_vs_input"] = ProxyPsnr(fitted.moves.back().distortion_after);
  } else if (initial_distortion_) {
    out.report["estimated_psnr_vs_input"] = ProxyPsnr(*initial_distortion_);
  }
  if (!eval_views_.empty()) {
    ATEX_ASSIGN_OR_RETURN(out.report["test"], Test(fitted.asset));
  }
  out.fitted = std::move(fitted);
  return out;
}

StatusOr<FitRunReport> Run::Go(const std::vector<uint8_t>& input_bytes) {
  ATEX_RETURN_IF_ERROR(ReadInput(input_bytes));
  const bool quality_mode = o_.quality > 0;
  if (quality_mode) {
    if (eval_views_.empty()) {
      return MakeError(StatusCode::kInvalidArgument, "fit: a quality floor needs the dataset's test views");
    }
    const double psnr = report_["input"]["test"]["psnr"].get<double>();
    if (psnr < o_.quality) {
      return MakeError(StatusCode::kOutOfRange, "fit: the quality floor of ", o_.quality,
                       " dB cannot be reached: the input itself scores ", psnr, " dB on ", eval_views_.size(),
                       " test views");
    }
  }
  ATEX_RETURN_IF_ERROR(KeepCount());
  size_t main = 0;
  for (size_t k = 0; k < o_.budgets.size(); ++k)
    if (o_.budgets[k] < o_.budgets[main]) main = k;
  const uint64_t budget = o_.budgets.empty() ? 0 : o_.budgets[main];

  Fitted result;
  if (!o_.budgets.empty() || quality_mode) {
    ATEX_ASSIGN_OR_RETURN(result, FitOnce(working_, write_, budget, quality_mode));
    for (uint32_t& k : result.kept) k = kept_[k];  // back to input indices
  } else {
    ATEX_ASSIGN_OR_RETURN(result.bytes, EncodeAsset(working_, write_));
    result.asset = working_;
    result.write = write_;
    result.kept = kept_;
  }
  clock_.Done("fit");  // plan and apply, or the encode of a --keep-count subset
  ATEX_RETURN_IF_ERROR(JoinInputTest());
  if (o_.finetune > 0) ATEX_RETURN_IF_ERROR(Finetune(&result));

  FitRunReport report;
  report.main_budget_index = main;
  // The other budgets of a list reuse the plan built for the smallest one.
  nlohmann::json others = nlohmann::json::array();
  std::vector<FitRunOutput> other_outputs;
  for (size_t k = 0; k < o_.budgets.size(); ++k) {
    if (k == main) continue;
    ATEX_ASSIGN_OR_RETURN(Fitted fitted, ApplyPlan(working_, shared_plan_, write_, o_.budgets[k]));
    for (uint32_t& i : fitted.kept) i = kept_[i];  // back to input indices
    ATEX_ASSIGN_OR_RETURN(FitRunOutput out, Output(o_.budgets[k], std::move(fitted)));
    others.push_back(out.report);
    other_outputs.push_back(std::move(out));
  }
  if (!others.empty()) report_["other_budgets"] = others;
  clock_.Done("other_budgets_and_write");

  // The main output's report as the others' (its test metrics with a dataset).
  ATEX_ASSIGN_OR_RETURN(FitRunOutput main_output, Output(budget, std::move(result)));
  const Fitted& fitted = main_output.fitted;
  nlohmann::json moves = nlohmann::json::array();
  for (const Move& m : fitted.moves) moves.push_back(MoveToJson(m));
  report_["output"] = {{"bytes", fitted.bytes.size()}, {"components", main_output.report["components"]}};
  if (!o_.budgets.empty()) report_["budget_bytes"] = budget;
  if (quality_mode) report_["quality_floor_psnr"] = o_.quality;
  report_["levers"] = main_output.report["levers"];
  if (!o_.budgets.empty() || quality_mode) report_["levers"]["allowed"] = LeverSetNames(o_.levers);
  report_["moves"] = moves;
  for (const char* key : {"smallest_fallback", "estimated_psnr_vs_input"}) {
    if (main_output.report.contains(key)) report_[key] = main_output.report[key];
  }
  if (!plan_timings_.empty()) report_["plan_timing"] = plan_timings_;
  if (!eval_views_.empty()) {
    report_["output"]["test"] = main_output.report["test"];
    clock_.Done("evaluate_output");
  }
  report_["seconds"] = clock_.seconds();
  report.outputs.push_back(std::move(main_output));
  for (FitRunOutput& out : other_outputs) report.outputs.push_back(std::move(out));
  report.json = std::move(report_);
  return report;
}

}  // namespace

Status ValidateFitRunOptions(const FitRunOptions& o, bool have_dataset) {
  const auto bad = [](auto... what) { return MakeError(StatusCode::kInvalidArgument, "fit: ", what...); };
  const bool budget = !o.budgets.empty();
  if (budget && o.quality > 0) return bad("--budget and --quality are alternatives");
  if (!budget && !(o.quality > 0) && !(o.keep_count > 0)) {
    return bad("give --budget SIZE, --keep-count FRACTION or --quality PSNR");
  }
  if (!std::isfinite(o.quality) || o.quality < 0) return bad("--quality ", o.quality, " is not a PSNR in dB");
  if (!(o.keep_count >= 0 && o.keep_count <= 1)) return bad("--keep-count ", o.keep_count, " is not in (0, 1]");
  if (o.probes < 1) return bad("--probes ", o.probes, ": at least one probe view is needed to measure distortion");
  if (o.probe_size < 8) return bad("--probe-size ", o.probe_size, ": at least 8 pixels");
  if (o.eval_views < 0) return bad("--eval-views ", o.eval_views, " is negative");
  if (o.finetune < 0) return bad("--finetune ", o.finetune, " is negative");
  if ((o.quality > 0 || o.finetune > 0) && !have_dataset) return bad("--quality and --finetune need --data");
  if (o.finetune > 0 && o.budgets.size() > 1) return bad("--finetune takes one budget");
  if (o.order_from != nullptr && !(o.keep_count > 0)) return bad("--order-from needs --keep-count");
  if ((o.levers & ~kAllLevers) != 0 || o.levers == 0) return bad("the lever set names no lever or an unknown one");
  if (!(o.step_growth >= 1 && o.step_growth <= 16)) return bad("--step-growth ", o.step_growth, " is not in [1, 16]");
  if (!(o.min_texture_step >= 0 && o.min_texture_step <= 1)) {
    return bad("--min-texture-step ", o.min_texture_step, " is not in [0, 1]");
  }
  if (o.parallel_candidates < 0 || o.parallel_candidates > 64) {
    return bad("--parallel-candidates ", o.parallel_candidates, " is not in 0..64");
  }
  return Status::Ok();
}

StatusOr<FitRunReport> RunFit(const std::vector<uint8_t>& input_bytes, const Dataset* dataset,
                              train::Backend* backend, const FitRunOptions& options) {
  ATEX_RETURN_IF_ERROR(ValidateFitRunOptions(options, dataset != nullptr));
  if (dataset != nullptr && backend == nullptr) {
    return MakeError(StatusCode::kInvalidArgument, "fit: a dataset's test metrics and fine-tuning need a backend");
  }
  if (options.input_eval_backend != nullptr && options.input_eval_backend == backend) {
    return MakeError(StatusCode::kInvalidArgument,
                     "fit: the input's evaluation beside the plan needs a second backend, not the run's");
  }
  Run run(dataset, backend, options);
  return run.Go(input_bytes);
}

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
  for (int s = 0; s < static_cast<int>(Stream::kCount); ++s) {
    enc[StreamName(static_cast<Stream>(s))] = ScalarEncodingName(GetEncoding(write, static_cast<Stream>(s)));
  }
  j["encodings"] = enc;
  return j;
}

train::TrainerOptions FinetuneOptions(const Dataset& dataset, const Asset& asset, int steps, uint64_t seed) {
  train::TrainerOptions t;
  t.config = train::DefaultConfig(dataset.kind() == DatasetKind::kPanoptic ? "panoptic" : "dnerf");
  t.config.seed = seed;
  t.config.stage1.sh_degree = asset.gaussians.sh_degree;
  t.config.stage2.iterations = steps;
  t.config.stage2.growth_steps.clear();
  t.config.background = asset.metadata.background;
  auto mode = ParseTextureMode(asset.metadata.texture_mode);
  t.config.stage2.textures = mode.ok() ? *mode : TextureMode::kNone;
  if (!asset.textures) t.config.stage2.textures = TextureMode::kNone;
  t.config.eval_every = 0;
  t.config.checkpoint_every = 0;
  t.stages = train::kStage2;
  return t;
}

}  // namespace atex::fit
