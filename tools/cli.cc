#include "cli.h"

#include <unistd.h>

#include <cstdio>
#include <iostream>
#include <vector>

namespace atex::cli {

static std::vector<CommandEntry>& MutableCommands() {
  static std::vector<CommandEntry> commands;
  return commands;
}

bool RegisterCommand(const char* name, const char* description, Setup setup) {
  MutableCommands().push_back({name, description, setup});
  return true;
}

const std::vector<CommandEntry>& Commands() { return MutableCommands(); }

int Fail(std::string_view command, const Status& status) {
  std::cerr << "atex " << command << ": " << status.ToString() << "\n";
  return kExitFailure;
}

void PrintJson(const nlohmann::json& json) { std::cout << json.dump(2) << "\n"; }

Progress::Progress(std::string label, long long total)
    : label_(std::move(label)), total_(total), tty_(isatty(STDERR_FILENO) != 0),
      first_(std::chrono::steady_clock::now()), last_(first_ - std::chrono::hours(1)) {}

void Progress::Update(long long done, const std::string& detail) {
  auto now = std::chrono::steady_clock::now();
  if (first_done_ < 0) {
    first_done_ = done;
    first_ = now;
  }
  const double since_last = std::chrono::duration<double>(now - last_).count();
  if (since_last < (tty_ ? 0.1 : 2.0) && done < total_) return;
  last_ = now;
  drawn_done_ = done;
  const double elapsed = std::chrono::duration<double>(now - first_).count();
  const double rate = elapsed > 0 ? (done - first_done_) / elapsed : 0.0;
  const double eta = rate > 0 && total_ > done ? (total_ - done) / rate : 0.0;
  const int width = 24;
  const int filled = total_ > 0 ? static_cast<int>(width * static_cast<double>(done) / total_) : 0;
  std::string bar(filled, '#');
  bar.resize(width, '.');
  char head[160];
  std::snprintf(head, sizeof head, "%s [%s] %lld/%lld %.1f it/s eta %.0fs", label_.c_str(), bar.c_str(), done,
                total_, rate, eta);
  if (tty_) {
    std::cerr << "\r\033[K" << head << (detail.empty() ? "" : "  ") << detail << std::flush;
  } else {
    std::cerr << head << (detail.empty() ? "" : "  ") << detail << "\n";
  }
}

void Progress::Finish(const std::string& detail) {
  if (finished_) return;
  finished_ = true;
  if (drawn_done_ != total_) {
    last_ = first_ - std::chrono::hours(1);  // draw the final state once
    Update(total_, detail);
  }
  if (tty_) std::cerr << "\n";
}

void AddDatasetOptions(CLI::App& app, DatasetArgs* args) {
  app.add_option("--dataset-kind", args->kind, "auto, panoptic, dnerf, dnerf-npz, n3dv")->capture_default_str();
  app.add_option("--timesteps", args->timesteps, "Use only the first N timesteps (0 = all present)");
  app.add_option("--downscale", args->downscale, "Integer image downscale factor")->capture_default_str();
  app.add_option("--timestep-stride", args->timestep_stride,
                 "Keep every K-th timestep (both splits; times unchanged): K times faster motion")
      ->capture_default_str();
  app.add_option("--train-cameras", args->train_cameras,
                 "Use N evenly spaced training cameras (sorted ids, ids[i*M/N]; 0 = all)")
      ->capture_default_str();
  app.add_option("--test-cameras", args->test_cameras,
                 "Hold out these camera ids for testing instead of the dataset's split (Panoptic, N3DV)")
      ->delimiter(',');
}

}  // namespace atex::cli
