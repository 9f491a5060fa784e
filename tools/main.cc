// atex: the AdaTex4D toolkit's command line. Subcommands live in cmd_*.cc.
#include <string_view>

#include <CLI/CLI.hpp>

#include "atex/version.h"
#include "cli.h"

int main(int argc, char** argv) {
  CLI::App app{"atex - adaptive textured 4D Gaussian splatting toolkit"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("atex ") + atex::kVersion + " (.atex format " +
                                         std::to_string(atex::kFormatVersionMajor) + "." +
                                         std::to_string(atex::kFormatVersionMinor) + ")");
  std::vector<std::pair<CLI::App*, atex::cli::Runner>> runners;
  for (const auto& command : atex::cli::Commands()) {
    CLI::App* sub = app.add_subcommand(command.name, command.description);
    runners.emplace_back(sub, command.setup(*sub));
  }
  // Errors are JSON on stdout too when the command line asks for JSON (cli.h, Fail): the one
  // place that decides it, before any command runs.
  for (int i = 1; i < argc; ++i) {
    if (std::string_view(argv[i]) == "--json") atex::cli::SetJsonErrors(true);
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    if (code == 0) return atex::cli::kExitOk;  // --help, --version
    if (atex::cli::JsonErrors()) {
      atex::cli::PrintJson(atex::cli::ErrorJson(atex::Status(atex::StatusCode::kInvalidArgument, e.what()), {}));
    }
    return atex::cli::kExitUsage;
  }
  for (auto& [sub, run] : runners) {
    if (sub->parsed()) return run();
  }
  return atex::cli::kExitUsage;
}
