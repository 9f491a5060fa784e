// `atex version`: what this build contains (optional formats, CUDA backend).
#include "atex/version.h"
#include "cli.h"

namespace {

atex::cli::Runner SetupVersion(CLI::App& app) {
  auto json = std::make_shared<bool>(false);
  app.add_flag("--json", *json, "Machine-readable output");
  return [json]() {
    nlohmann::json info = {{"version", atex::kVersion},
                           {"format_version", std::to_string(atex::kFormatVersionMajor) + "." +
                                                  std::to_string(atex::kFormatVersionMinor)},
#ifdef ATEX_HAVE_CUDA
                           {"cuda_backend", true},
#else
                           {"cuda_backend", false},
#endif
    };
    if (*json) {
      atex::cli::PrintJson(info);
    } else {
      std::printf("atex %s (.atex format %s; CUDA backend: %s)\n", atex::kVersion,
                  info["format_version"].get<std::string>().c_str(),
                  info["cuda_backend"].get<bool>() ? "built" : "not built");
    }
    return atex::cli::kExitOk;
  };
}

ATEX_REGISTER_COMMAND("version", "Print the version and the optional parts this build contains", SetupVersion);

}  // namespace
