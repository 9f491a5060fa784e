#include "cli.h"
#include "cli_parse.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <regex>
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

namespace {
bool json_errors = false;

// The first byte offset a message names ("at byte 1184", "offset 12", "byte offset 7").
nlohmann::json OffsetIn(const std::string& message) {
  static const std::regex kOffset(R"((?:byte|offset)\s+(\d+))");
  std::smatch match;
  if (!std::regex_search(message, match, kOffset)) return nullptr;
  try {
    return std::stoull(match[1].str());
  } catch (...) {
    return nullptr;
  }
}
}  // namespace

void SetJsonErrors(bool on) { json_errors = on; }
bool JsonErrors() { return json_errors; }

nlohmann::json ErrorJson(const Status& status, std::string_view path) {
  return {{"error",
           {{"code", static_cast<int>(status.code())},
            {"name", std::string(StatusCodeName(status.code()))},
            {"message", status.message()},
            {"path", path.empty() ? nlohmann::json(nullptr) : nlohmann::json(std::string(path))},
            {"offset", OffsetIn(status.message())}}}};
}

int Fail(std::string_view command, const Status& status, std::string_view path, const nlohmann::json& extra) {
  std::cerr << "atex " << command << ": " << status.ToString() << "\n";
  if (json_errors) {
    nlohmann::json j = extra.is_object() ? extra : nlohmann::json::object();
    j.update(ErrorJson(status, path));
    PrintJson(j);
  }
  return kExitFailure;
}

int Usage(std::string_view command, std::string_view message) {
  std::cerr << "atex " << command << ": " << message << "\n";
  if (json_errors) PrintJson(ErrorJson(Status(StatusCode::kInvalidArgument, std::string(message)), {}));
  return kExitUsage;
}

const char* const kOutputRule =
    "Outputs: an existing file is never replaced unless --force (-f) is given. An output that is also the "
    "input is replaced only with --force, after the input was read whole, through a temporary file renamed "
    "into place; it is refused where the command reads its input while writing. The output's extension must "
    "name the format written.";

void AddForceFlag(CLI::App& app, bool* force) {
  app.add_flag("-f,--force", *force, "Replace an existing output (see 'Outputs' below)");
  app.footer(kOutputRule);
}

namespace {
// Whether two paths name the same existing file (hard links and symlinks included).
bool SameFile(const std::string& a, const std::string& b) {
  std::error_code ec;
  const bool same = std::filesystem::equivalent(a, b, ec);
  return !ec && same;
}
std::string LowerExtension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}
}  // namespace

Status CheckOutput(const std::string& path, bool force, const OutputCheck& check) {
  if (path.empty()) return MakeError(StatusCode::kInvalidArgument, "no ", check.what, " path given");
  if (!check.folder && !check.extensions.empty()) {
    const std::string ext = LowerExtension(path);
    if (std::find(check.extensions.begin(), check.extensions.end(), ext) == check.extensions.end()) {
      std::string allowed;
      for (const auto& e : check.extensions) allowed += (allowed.empty() ? "" : ", ") + e;
      return MakeError(StatusCode::kInvalidArgument, check.what, " '", path,
                       "' does not end in the extension of what this writes (", allowed, "); it ends in '", ext, "'");
    }
  }
  for (const std::string& input : check.inputs) {
    if (input.empty() || !SameFile(input, path)) continue;
    if (!check.in_place_allowed) {
      return MakeError(StatusCode::kInvalidArgument, check.what, " '", path, "' is the input '", input,
                       "', which this command reads while it writes: choose another path");
    }
    if (!force) {
      return MakeError(StatusCode::kInvalidArgument, check.what, " '", path, "' is the input '", input,
                       "': pass --force to replace it");
    }
    return Status::Ok();
  }
  std::error_code ec;
  if (std::filesystem::exists(path, ec) && !force) {
    return MakeError(StatusCode::kInvalidArgument, check.what, " '", path,
                     "' exists: pass --force (-f) to replace it");
  }
  return Status::Ok();
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
  app.add_option("--dataset-kind", args->kind, "auto, panoptic, dnerf, dnerf-npz, n3dv, nerfstudio, colmap")
      ->capture_default_str();
  AddInt(app, "--timesteps", &args->timesteps, 0, 1 << 20, "Use only the first N timesteps (0 = all present)");
  AddInt(app, "--downscale", &args->downscale, 1, 64, "Integer image downscale factor");
  AddInt(app, "--timestep-stride", &args->timestep_stride, 1, 1 << 20,
         "Keep every K-th timestep (both splits; times unchanged): K times faster motion");
  AddInt(app, "--train-cameras", &args->train_cameras, 0, 1 << 20,
         "Use N evenly spaced training cameras (sorted ids, ids[i*M/N]; 0 = all)");
  AddIntList(
      app, "--test-cameras", &args->test_cameras, 0, 1 << 20,
      "Hold out these camera ids for testing instead of the dataset's split (Panoptic, N3DV, nerfstudio camera_id)");
}

}  // namespace atex::cli
