// Shared plumbing of the `atex` subcommands: registration, error reporting,
// JSON output and a progress line. Only tools/ prints or chooses exit codes.
#pragma once

#include <chrono>
#include <functional>
#include <string>
#include <string_view>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "asset_view.h"  // DatasetArgs
#include "atex/status.h"

namespace atex::cli {

// Exit codes of every subcommand.
inline constexpr int kExitOk = 0;
inline constexpr int kExitFailure = 1;  // the operation failed (message on stderr)
inline constexpr int kExitUsage = 2;    // bad command line (CLI11 prints the reason)

// A subcommand's setup adds its options to `app` and returns the function that
// runs it after parsing.
using Runner = std::function<int()>;
using Setup = Runner (*)(CLI::App& app);

struct CommandEntry {
  const char* name;
  const char* description;
  Setup setup;
};

bool RegisterCommand(const char* name, const char* description, Setup setup);
const std::vector<CommandEntry>& Commands();

// Prints "atex <command>: <status>" on stderr and returns kExitFailure.
int Fail(std::string_view command, const Status& status);

// Writes JSON (indented) to stdout followed by a newline.
void PrintJson(const nlohmann::json& json);

// Registers --dataset-kind, --timesteps, --downscale, --timestep-stride, --train-cameras, --test-cameras.
void AddDatasetOptions(CLI::App& app, DatasetArgs* args);

// A single-line progress display on stderr (redrawn in place on a terminal,
// one line per ~2 s otherwise so that logs stay short).
class Progress {
 public:
  Progress(std::string label, long long total);
  // `detail` is appended after the counter, e.g. "loss 0.031 PSNR 27.1".
  void Update(long long done, const std::string& detail = "");
  void Finish(const std::string& detail = "");
  bool tty() const { return tty_; }

 private:
  std::string label_;
  long long total_;
  bool tty_;
  bool finished_ = false;
  long long first_done_ = -1;
  long long drawn_done_ = -1;  // the rate counts from the first update (work before it is not timed)
  std::chrono::steady_clock::time_point first_, last_;
};

}  // namespace atex::cli

#define ATEX_CLI_CONCAT_INNER(a, b) a##b
#define ATEX_CLI_CONCAT(a, b) ATEX_CLI_CONCAT_INNER(a, b)
// ATEX_REGISTER_COMMAND("info", "Summarise an .atex file", SetupInfo);
#define ATEX_REGISTER_COMMAND(name, description, setup) \
  static const bool ATEX_CLI_CONCAT(atex_command_registered_, __LINE__) = ::atex::cli::RegisterCommand(name, description, setup)
