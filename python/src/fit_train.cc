// atex.fit, atex.train and atex.convert: long C++ work without the GIL; progress callbacks
// take the GIL back, and an exception in them (KeyboardInterrupt included) stops the work
// through libatex's cancellation (kCancelled) and is re-raised.
#include <pybind11/functional.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <string>
#include <utility>

#include "atex/converters/convert.h"
#include "atex/dataset.h"
#include "atex/fit.h"
#include "atex/fit_run.h"
#include "atex/train/trainer.h"
#include "common.h"

namespace atex::python {

WriteOptions WriteOptionsFrom(const AssetHolder& holder, const std::string& codec, int zstd_level,
                              const py::object& encodings, bool keep_stats);
py::dict EncodingsToPython(const WriteOptions& o);
std::shared_ptr<Dataset> AsDatasetArg(py::handle dataset);

namespace {

// Calls a Python progress callback from C++ work that runs without the GIL. The first
// exception (or a False return, or a pending signal such as Ctrl-C) cancels: Continue()
// returns false from then on, and Rethrow() raises what the callback raised.
class Callback {
 public:
  explicit Callback(py::object function) : function_(std::move(function)) {}

  // Needs no GIL on entry. Returns false when the work should stop.
  bool Call(const std::function<py::object()>& make_argument) {
    if (cancelled_) return false;
    py::gil_scoped_acquire acquire;
    if (PyErr_CheckSignals() != 0) {
      error_ = std::make_unique<py::error_already_set>();
      cancelled_ = true;
      return false;
    }
    if (function_.is_none()) return true;
    try {
      py::object result = function_(make_argument());
      if (!result.is_none() && !result.cast<bool>()) cancelled_ = true;
    } catch (py::error_already_set& e) {
      error_ = std::make_unique<py::error_already_set>(std::move(e));
      cancelled_ = true;
    }
    return !cancelled_;
  }
  // Needs no GIL on entry: notices a pending signal (Ctrl-C) without calling the callback.
  bool Poll() {
    if (cancelled_) return false;
    py::gil_scoped_acquire acquire;
    if (PyErr_CheckSignals() != 0) {
      error_ = std::make_unique<py::error_already_set>();
      cancelled_ = true;
    }
    return !cancelled_;
  }
  bool cancelled() const { return cancelled_; }
  // With the GIL: re-raises the callback's exception, if any.
  void Rethrow() {
    if (error_) {
      auto error = std::move(error_);
      error->restore();
      throw py::error_already_set();
    }
  }
  ~Callback() {
    if (error_) {  // dropping a Python exception object needs the GIL
      py::gil_scoped_acquire acquire;
      error_.reset();
    }
  }

 private:
  py::object function_;
  std::atomic<bool> cancelled_{false};
  std::unique_ptr<py::error_already_set> error_;
};

std::vector<uint64_t> ParseBudgets(py::handle budget, bool* single) {
  std::vector<uint64_t> out;
  const auto one = [&](py::handle b) {
    if (py::isinstance<py::str>(b)) {
      out.push_back(ValueOrThrow(fit::ParseByteSize(b.cast<std::string>())));
    } else {
      const long long v = b.cast<long long>();
      if (v <= 0) ThrowStatus(MakeError(StatusCode::kInvalidArgument, "budget must be positive, not ", v));
      out.push_back(static_cast<uint64_t>(v));
    }
  };
  *single = py::isinstance<py::str>(budget) || py::isinstance<py::int_>(budget);
  if (*single) {
    one(budget);
  } else {
    for (py::handle b : budget) one(b);
  }
  if (out.empty()) ThrowStatus(MakeError(StatusCode::kInvalidArgument, "no budget given"));
  return out;
}

// atex.fit's report of one output of `run`: the output's own report (fit_run.h: budget, bytes,
// components, levers, test metrics, the estimate or smallest_fallback), with the input's size,
// the levers' before and after at the top level, the moves, the plan's timing and the backend.
nlohmann::json FitReport(const fit::FitRunReport& run, const fit::FitRunOutput& output, uint64_t input_bytes,
                         const std::string& backend) {
  nlohmann::json r = output.report;
  r["input_bytes"] = input_bytes;
  for (const char* key : {"gaussians", "sh_degree", "texels"}) {
    if (r["levers"].contains(key)) r[key] = r["levers"][key];
  }
  nlohmann::json moves = nlohmann::json::array();
  for (const fit::Move& m : output.fitted.moves) moves.push_back(fit::MoveToJson(m));
  r["moves"] = moves;
  // The plan every output was applied from (with a fine-tune, the re-fit's).
  if (run.json.contains("plan_timing")) r["plan_timing"] = run.json["plan_timing"].back();
  if (run.json["input"].contains("test")) r["input_test"] = run.json["input"]["test"];
  if (run.json.contains("keep_count")) r["keep_count"] = run.json["keep_count"];
  r["backend"] = backend;
  return r;
}

// atex.fit: fit::RunFit (what `atex fit` runs) on the asset's encoded bytes.
py::object Fit(const AssetPtr& holder, py::object budget, py::object dataset_arg, const std::string& levers_text,
               int probes, int probe_size, const std::string& backend_name, uint64_t seed, bool keep_stats,
               py::object progress, double quality, double keep_count, int eval_views, double step_growth,
               double min_texture_step, int parallel_candidates) {
  bool single = true;
  fit::FitRunOptions o;
  if (!budget.is_none()) o.budgets = ParseBudgets(budget, &single);
  if (o.budgets.empty() && !(quality > 0) && !(keep_count > 0)) {
    ThrowStatus(MakeError(StatusCode::kInvalidArgument, "atex.fit needs budget=, quality= or keep_count="));
  }
  o.levers = ValueOrThrow(fit::ParseLevers(levers_text));
  o.probes = probes;
  o.probe_size = probe_size;
  o.seed = seed;
  o.keep_stats = keep_stats;
  o.quality = quality;
  o.keep_count = keep_count;
  o.eval_views = eval_views;
  o.step_growth = step_growth;
  o.min_texture_step = min_texture_step;
  o.parallel_candidates = parallel_candidates;
  std::shared_ptr<Dataset> dataset;
  if (!dataset_arg.is_none()) dataset = AsDatasetArg(dataset_arg);
  ThrowIfError(fit::ValidateFitRunOptions(o, dataset != nullptr));
  Callback callback(progress);
  o.progress = [&](const fit::FitProgress& p) {
    callback.Call([&] {
      py::dict d;
      d["move"] = p.move;
      d["bytes"] = p.bytes;
      d["target_bytes"] = p.target_bytes;
      d["text"] = p.text;
      return d;
    });
  };
  // Also notices Ctrl-C between moves when there is no callback.
  o.cancelled = [&] { return !callback.Poll(); };

  StatusOr<fit::FitRunReport> run = MakeError(StatusCode::kInternal, "atex.fit did not run");
  std::string description;
  uint64_t input_bytes = 0;
  {
    py::gil_scoped_release release;
    run = [&]() -> StatusOr<fit::FitRunReport> {
      // The asset as its file would hold it, with its statistics: they are its importance, which
      // the fit would otherwise recompute from the probes. The outputs keep them only with keep_stats.
      WriteOptions write = holder->file_encodings.value_or(WriteOptions{});
      write.write_stats = true;
      ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> encoded, EncodeAsset(holder->asset, write));
      input_bytes = encoded.size();
      ATEX_ASSIGN_OR_RETURN(auto backend, MakeBackend(backend_name, &description));
      return fit::RunFit(encoded, dataset.get(), backend.get(), o);
    }();
  }
  callback.Rethrow();
  ThrowIfError(run.status());
  // RunFit's outputs: the main one (smallest budget) first; returned in the order of the budgets.
  std::vector<fit::FitRunOutput*> in_order(run->outputs.size());
  for (size_t k = 0, other = 1; k < run->outputs.size(); ++k) {
    in_order[k] = k == run->main_budget_index ? &run->outputs[0] : &run->outputs[other++];
  }
  py::list out;
  for (fit::FitRunOutput* output : in_order) {
    auto asset = std::make_shared<AssetHolder>();
    nlohmann::json report = FitReport(*run, *output, input_bytes, description);
    asset->asset = std::move(output->fitted.asset);
    asset->file_encodings = output->fitted.write;
    out.append(py::make_tuple(py::cast(asset), JsonToPython(report)));
  }
  return single ? out[0] : py::object(out);
}

py::object Train(py::handle dataset_arg, py::object config, py::object progress, const std::string& backend_name,
                 const std::string& stages, py::object init, double time_limit, const std::string& checkpoint_dir) {
  std::shared_ptr<Dataset> dataset = AsDatasetArg(dataset_arg);
  const std::string kind = train::DefaultConfigKind(dataset->kind());
  train::TrainerOptions options;
  options.config = train::DefaultConfig(kind);
  options.config.background = dataset->background();
  if (!config.is_none()) {
    options.config = ValueOrThrow(train::ConfigFromJson(PythonToJson(config), options.config));
  }
  if (stages == "1") {
    options.stages = train::kStage1;
  } else if (stages == "2") {
    options.stages = train::kStage2;
  } else if (stages == "all") {
    options.stages = train::kBothStages;
  } else {
    ThrowStatus(MakeError(StatusCode::kInvalidArgument, "stages must be '1', '2' or 'all', not '", stages, "'"));
  }
  AssetPtr initial;
  if (!init.is_none()) initial = init.cast<AssetPtr>();
  if (options.stages == train::kStage2 && !initial) {
    ThrowStatus(MakeError(StatusCode::kInvalidArgument, "stages='2' needs init= (a stage-1 asset)"));
  }
  options.time_limit_seconds = time_limit;
  options.checkpoint_dir = checkpoint_dir;
  Callback callback(progress);
  options.progress = [&](const train::TrainProgress& p) {
    return callback.Call([&] {
      py::dict d;
      d["phase"] = p.phase;
      d["step"] = p.step;
      d["total"] = p.total;
      d["loss"] = p.loss;
      d["psnr"] = p.psnr;
      d["gaussians"] = p.gaussians;
      d["event"] = p.event;
      return d;
    });
  };
  StatusOr<train::TrainSummary> summary = Status(StatusCode::kInternal, "not trained");
  std::string description;
  {
    py::gil_scoped_release release;
    auto backend = MakeBackend(backend_name, &description);
    if (backend.ok()) {
      summary = train::Train(*dataset, **backend, options, initial ? &initial->asset : nullptr);
    } else {
      summary = backend.status();
    }
  }
  callback.Rethrow();
  train::TrainSummary result = ValueOrThrow(std::move(summary));
  nlohmann::json report = train::SummaryToJson(result);
  report["backend"] = description;
  auto asset = std::make_shared<AssetHolder>();
  asset->asset = std::move(result.asset);
  return py::make_tuple(py::cast(asset), JsonToPython(report));
}

py::object Convert(const std::string& input, const std::string& output, const std::string& from,
                   const std::string& to, py::object time, py::object frames, int spz_version, py::object progress) {
  ConvertOptions o;
  if (!from.empty()) o.from = ValueOrThrow(ParseFileFormat(from));
  if (!to.empty()) o.to = ValueOrThrow(ParseFileFormat(to));
  if (!time.is_none()) o.time = time.cast<double>();
  if (!frames.is_none()) o.frames = ValueOrThrow(ParseFrameRange(frames.cast<std::string>()));
  o.spz_version = spz_version;
  Callback callback(progress);
  o.progress = [&](std::string_view stage, double fraction) {
    return callback.Call([&] { return py::make_tuple(std::string(stage), fraction); });
  };
  StatusOr<ConvertReport> report = Status(StatusCode::kInternal, "not converted");
  {
    py::gil_scoped_release release;
    report = ConvertFile(input, output, o);
  }
  callback.Rethrow();
  return JsonToPython(ValueOrThrow(std::move(report)).ToJson());
}

}  // namespace

void RegisterFitTrain(py::module_& m) {
  m.def("fit", &Fit, py::arg("asset"), py::arg("budget") = py::none(), py::kw_only(), py::arg("dataset") = py::none(),
        py::arg("levers") = "default", py::arg("probes") = 8, py::arg("probe_size") = 256, py::arg("backend") = "auto",
        py::arg("seed") = 6666, py::arg("keep_stats") = false, py::arg("progress") = py::none(),
        py::arg("quality") = 0.0, py::arg("keep_count") = 0.0, py::arg("eval_views") = 0, py::arg("step_growth") = 2.0,
        py::arg("min_texture_step") = fit::PlanOptions{}.min_texture_step, py::arg("parallel_candidates") = 0,
        "Fits an asset to a byte budget (atex/fit.h; docs/fit.md explains the method) and returns\n"
        "(fitted asset, report dict); with a list of budgets, one plan serves them all and a list of pairs\n"
        "comes back. It runs what `atex fit` runs (atex/fit_run.h, RunFit) on the asset's encoded bytes.\n\n"
        "The fitter trims capacity with levers (prune, textures, sh, encoding, grid; 'all-textures' on\n"
        "request) and spends the budget where it matters most: at every step each lever proposes its next\n"
        "move, the move is applied, the asset encoded (exact file bytes), decoded and rendered from probe\n"
        "views; the move with the least distortion per byte saved wins. Distortion is measured against the\n"
        "untrimmed asset's renders of the dataset's training views when `dataset` is given, else of orbit views\n"
        "(the documented proxy).\n\n"
        "Guarantees: the fitted asset's encoded size is at most the budget (checked on the exact bytes) and\n"
        "the asset is valid; a budget below the smallest asset the levers can reach raises atex.Error\n"
        "'budget-too-small' naming that size.\n\n"
        "budget: bytes (int) or text such as '1MiB', '80MB', '1.5GiB'; levers: comma-separated names or\n"
        "'default'; progress(dict(move, bytes, target_bytes, text)) is called after each accepted move;\n"
        "returning False, raising, or Ctrl-C stops the fit (atex.Error 'cancelled', or the callback's exception).\n"
        "Instead of a budget, or beside one: quality=PSNR (needs dataset) keeps the smallest asset whose test\n"
        "PSNR stays at or above it; keep_count=F keeps the fraction F of the Gaussians, most important first.\n"
        "eval_views: test views for the PSNR (evenly spaced; 0 = all); step_growth, min_texture_step and\n"
        "parallel_candidates: as `atex fit`'s --step-growth, --min-texture-step, --parallel-candidates.\n"
        "The report has budget_bytes, input_bytes, bytes, components, levers (encodings, grid), gaussians/\n"
        "sh_degree/texels before and after, the moves, plan_timing, backend and estimated_psnr_vs_input\n"
        "(proxy PSNR against the untrimmed renders, interpolated where the last move was cut to the budget:\n"
        "docs/fit.md); with a dataset, test (the output's PSNR and SSIMs on its test views) and input_test.\n"
        "When the plan ended above a budget that is not below the smallest asset, that asset is the output,\n"
        "and the report has smallest_fallback (plan_end_bytes, bytes) instead of the estimate.");
  m.def("train", &Train, py::arg("dataset"), py::arg("config") = py::none(), py::kw_only(),
        py::arg("progress") = py::none(), py::arg("backend") = "auto", py::arg("stages") = "all",
        py::arg("init") = py::none(), py::arg("time_limit") = 0.0, py::arg("checkpoint_dir") = "",
        "Trains stage 1 (4DGS) and/or stage 2 (AdaTex4D textures) on a dataset (atex/train/trainer.h, Train)\n"
        "and returns (asset, summary dict) as `atex train --json` reports it.\n\n"
        "config: a dict (or None) over the dataset kind's defaults (`atex train --print-config` lists every\n"
        "key); unknown keys raise atex.Error. stages: '1', '2' (needs init=, a stage-1 asset) or 'all'.\n"
        "progress(dict(phase, step, total, loss, psnr, gaussians, event)) is called every few steps with the\n"
        "GIL held; returning False, raising, or Ctrl-C stops training (atex.Error 'cancelled', or the\n"
        "callback's exception). time_limit: seconds (0 = none). The work runs without the GIL.");
  m.def("convert", &Convert, py::arg("input"), py::arg("output"), py::kw_only(), py::arg("from_format") = "",
        py::arg("to_format") = "", py::arg("time") = py::none(), py::arg("frames") = py::none(),
        py::arg("spz_version") = 4, py::arg("progress") = py::none(),
        "Converts between the formats libatex reads and writes (atex/converters/convert.h, ConvertFile), as\n"
        "`atex convert`: .ply (INRIA 3DGS), .spz, .atex, .exr texel atlas, .drc, 4DGaussians folders; formats\n"
        "from the extensions unless named. time: deform to this scene time for .ply/.spz/.drc output;\n"
        "frames: 'START:END:STEP' writes one file per time into the output folder. Returns the report dict\n"
        "(dropped parts, warnings, bytes, timings). progress(stage, fraction) may return False to cancel.");
}

}  // namespace atex::python
