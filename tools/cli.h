// Shared plumbing of the `atex` subcommands: registration, error reporting,
// JSON output and a progress line. Only tools/ prints or chooses exit codes.
#pragma once

#include <chrono>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

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

// Prints "atex <command>: <status>" on stderr and returns kExitFailure. When the command
// line has --json (SetJsonErrors), the error is also JSON on stdout,
// {"error": {"code", "name", "message", "path", "offset"}}, so a script that parses
// stdout reads the failure too: `path` is `path` when given (else null), `offset` the
// byte offset the message names ("at byte N", "offset N"; else null).
// `extra` (an object) adds fields beside "error" (e.g. verify's "valid": false).
int Fail(std::string_view command, const Status& status, std::string_view path = {},
         const nlohmann::json& extra = nlohmann::json::object());
// A bad command line: the message on stderr (and as JSON, as Fail), returns kExitUsage.
int Usage(std::string_view command, std::string_view message);
// The JSON error object of Fail (exposed for main's usage errors and for tests).
nlohmann::json ErrorJson(const Status& status, std::string_view path);
// main() turns JSON errors on when the arguments include --json.
void SetJsonErrors(bool on);
bool JsonErrors();

// The rule of every command that writes files, shown in its --help (AddForceFlag):
// an existing output is never replaced without --force; an output that is the input is
// replaced (atomically, after the input was read whole) only with --force, and never
// where the command reads its input lazily.
extern const char* const kOutputRule;
// Registers -f,--force and appends kOutputRule to the command's help footer.
void AddForceFlag(CLI::App& app, bool* force);

struct OutputCheck {
  std::vector<std::string> inputs;      // files the command reads (an output equal to one is "in place")
  std::vector<std::string> extensions;  // lower-case, with the dot; empty: any
  std::string_view what = "output";     // how the message names it
  bool in_place_allowed = true;         // false: the command reads an input while it writes
  bool folder = false;                  // the output is a folder (extensions unchecked)
};
// Before any work: the output's extension says what the command writes; an existing
// output needs `force`; an output that is one of the inputs needs `force` and
// in_place_allowed. kInvalidArgument naming the path otherwise.
Status CheckOutput(const std::string& path, bool force, const OutputCheck& check);

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
#define ATEX_REGISTER_COMMAND(name, description, setup)                   \
  static const bool ATEX_CLI_CONCAT(atex_command_registered_, __LINE__) = \
      ::atex::cli::RegisterCommand(name, description, setup)
