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

nlohmann::json FitReport(const Asset& input, uint64_t input_bytes, const fit::Fitted& fitted, uint64_t budget,
                         const fit::Plan& plan, const std::string& backend) {
  nlohmann::json r;
  r["budget_bytes"] = budget;
  r["input_bytes"] = input_bytes;
  r["bytes"] = fitted.bytes.size();
  r["components"] = fit::ComponentsToJson(fitted.bytes);
  r["gaussians"] = {{"before", input.gaussians.size()}, {"after", fitted.asset.gaussians.size()}};
  r["sh_degree"] = {{"before", input.gaussians.sh_degree}, {"after", fitted.asset.gaussians.sh_degree}};
  if (input.textures) {
    r["texels"] = {{"before", input.textures->texel_count()},
                   {"after", fitted.asset.textures ? fitted.asset.textures->texel_count() : 0}};
  }
  nlohmann::json moves = nlohmann::json::array();
  for (const fit::Move& m : fitted.moves) moves.push_back(fit::MoveToJson(m));
  r["moves"] = moves;
  if (fitted.smallest_fallback) {
    // The levers' smallest asset, never measured by the plan: no estimate to give.
    r["smallest_fallback"] = {{"plan_end_bytes", fitted.plan_end_bytes}, {"bytes", fitted.bytes.size()}};
  } else {
    const double d = fitted.moves.empty() ? plan.initial_distortion : fitted.moves.back().distortion_after;
    r["estimated_psnr_vs_input"] = d > 0 ? -10.0 * std::log10(d) : 99.0;
  }
  r["plan_timing"] = fit::TimingToJson(plan.timing);
  r["backend"] = backend;
  return r;
}

py::object Fit(const AssetPtr& holder, py::object budget, py::object dataset_arg, const std::string& levers_text,
               int probes, int probe_size, const std::string& backend_name, uint64_t seed, bool keep_stats,
               py::object progress) {
  if (budget.is_none()) ThrowStatus(MakeError(StatusCode::kInvalidArgument, "atex.fit needs budget="));
  bool single = true;
  const std::vector<uint64_t> budgets = ParseBudgets(budget, &single);
  const fit::LeverSet levers = ValueOrThrow(fit::ParseLevers(levers_text));
  if (probes < 1 || probe_size < 8) {
    ThrowStatus(MakeError(StatusCode::kInvalidArgument, "probes must be >= 1 and probe_size >= 8"));
  }
  std::shared_ptr<Dataset> dataset;
  if (!dataset_arg.is_none()) dataset = AsDatasetArg(dataset_arg);
  WriteOptions write = holder->file_encodings.value_or(WriteOptions{});
  write.write_stats = keep_stats;
  Callback callback(progress);

  std::vector<fit::Fitted> results;
  fit::Plan plan;
  std::string description;
  uint64_t input_bytes = 0;
  Status status;
  {
    py::gil_scoped_release release;
    status = [&]() -> Status {
      Asset input = holder->asset;
      ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> encoded, EncodeAsset(input, write));
      input_bytes = encoded.size();
      std::vector<fit::Probe> probe_views;
      if (dataset) {
        const auto& views = dataset->train_views();
        const size_t count = std::min<size_t>(probes, views.size());
        for (size_t k = 0; k < count; ++k) {
          probe_views.push_back({fit::ScaleCamera(views[k * views.size() / count].camera, probe_size)});
        }
      } else {
        probe_views = fit::OrbitProbes(input, probes, probe_size, std::max(1, probe_size * 3 / 4));
      }
      ATEX_RETURN_IF_ERROR(fit::EnsureImportance(&input, probe_views));
      ATEX_ASSIGN_OR_RETURN(auto backend, MakeBackend(backend_name, &description));
      const uint64_t smallest = *std::min_element(budgets.begin(), budgets.end());
      fit::PlanOptions o;
      o.write = write;
      o.seed = seed;
      o.floor_bytes = smallest;
      o.levers = levers;
      ATEX_RETURN_IF_ERROR(fit::CheckBudget(input, write, smallest, o.min_grid_resolution, o.levers));
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
      // The plan's only way to stop early with an error: cancellation after a callback said so.
      o.accept_more = [&](const Asset&, const fit::Move&) -> StatusOr<bool> {
        if (!callback.Poll()) {
          return MakeError(StatusCode::kCancelled, "fit cancelled by the progress callback");
        }
        return true;
      };
      fit::ProbeRenderer renderer(backend.get(), probe_views);
      ATEX_ASSIGN_OR_RETURN(plan, fit::BuildPlan(input, &renderer, o));
      for (uint64_t b : budgets) {
        ATEX_ASSIGN_OR_RETURN(fit::Fitted fitted, fit::ApplyPlan(input, plan, write, b));
        results.push_back(std::move(fitted));
      }
      return Status::Ok();
    }();
  }
  callback.Rethrow();
  ThrowIfError(status);
  py::list out;
  for (size_t k = 0; k < results.size(); ++k) {
    auto asset = std::make_shared<AssetHolder>();
    nlohmann::json report = FitReport(holder->asset, input_bytes, results[k], budgets[k], plan, description);
    asset->asset = std::move(results[k].asset);
    asset->file_encodings = results[k].write;
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
        "Fits an asset to a byte budget (atex/fit.h; docs/fit.md explains the method) and returns\n"
        "(fitted asset, report dict); with a list of budgets, one plan serves them all and a list of pairs\n"
        "comes back.\n\n"
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
        "The report has bytes, components, gaussians/sh_degree/texels before and after, the moves and\n"
        "estimated_psnr_vs_input (proxy PSNR against the untrimmed renders, interpolated where the last move\n"
        "was cut to the budget: docs/fit.md); when the plan ended above a\n"
        "budget that is not below the smallest asset, that asset is the output, the report has\n"
        "smallest_fallback (plan_end_bytes, bytes) instead of the estimate.");
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
