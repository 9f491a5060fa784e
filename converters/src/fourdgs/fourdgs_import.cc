// ImportFourDGaussians: a 4DGaussians output folder -> Asset.
#include <algorithm>
#include <cstring>
#include <filesystem>
#include <system_error>

#include "atex/converters/fourdgs.h"
#include "atex/converters/ply.h"
#include "atex/file_io.h"

namespace atex {
namespace {

namespace fs = std::filesystem;

constexpr const char* kPly = "point_cloud.ply";
constexpr const char* kPth = "deformation.pth";

bool IsFile(const fs::path& p) {
  std::error_code ec;
  return fs::is_regular_file(p, ec);
}

// The iteration folder to import and its iteration number (-1 if unknown).
StatusOr<std::pair<fs::path, int>> ResolveIterationDir(const fs::path& dir, int wanted) {
  if (IsFile(dir / kPly) && IsFile(dir / kPth)) {
    int iteration = -1;
    const std::string name = dir.filename().string();
    if (name.rfind("iteration_", 0) == 0) iteration = std::atoi(name.c_str() + 10);
    return std::make_pair(dir, iteration);
  }
  const fs::path clouds = dir / "point_cloud";
  std::error_code ec;
  if (!fs::is_directory(clouds, ec)) {
    return MakeError(StatusCode::kNotFound, "'", dir.string(), "' holds neither ", kPly, " + ", kPth,
                     " nor a point_cloud/iteration_N folder (not a 4DGaussians output)");
  }
  if (wanted >= 0) {
    const fs::path chosen = clouds / ("iteration_" + std::to_string(wanted));
    if (!IsFile(chosen / kPly) || !IsFile(chosen / kPth)) {
      return MakeError(StatusCode::kNotFound, "'", chosen.string(), "' does not hold ", kPly, " and ", kPth);
    }
    return std::make_pair(chosen, wanted);
  }
  int best = -1;
  for (fs::directory_iterator it(clouds, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind("iteration_", 0) != 0 || name.size() == 10 || name.size() > 19) continue;
    if (!std::all_of(name.begin() + 10, name.end(), [](char c) { return c >= '0' && c <= '9'; })) continue;
    const int n = std::atoi(name.c_str() + 10);
    if (n > best && IsFile(it->path() / kPly) && IsFile(it->path() / kPth)) best = n;
  }
  if (best < 0) {
    return MakeError(StatusCode::kNotFound, "'", clouds.string(), "' has no iteration_N folder with ", kPly, " and ",
                     kPth);
  }
  return std::make_pair(clouds / ("iteration_" + std::to_string(best)), best);
}

}  // namespace

StatusOr<Asset> ImportFourDGaussians(const std::string& folder_or_iteration_dir, const FourDgsImportOptions& options) {
  const fs::path dir(folder_or_iteration_dir);
  ATEX_ASSIGN_OR_RETURN(auto resolved, ResolveIterationDir(dir, options.iteration));
  const fs::path& iteration_dir = resolved.first;

  // Head flags: options > cfg_args > 4DGaussians' defaults.
  FourDgsHeadFlags flags;
  std::string flags_from = "4DGaussians defaults";
  if (options.read_cfg_args) {
    for (const fs::path& candidate : {dir / "cfg_args", iteration_dir / "cfg_args",
                                      iteration_dir.parent_path().parent_path() / "cfg_args"}) {
      if (!IsFile(candidate)) continue;
      ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> text, ReadFileBytes(candidate.string(), 1 << 20));
      const std::string cfg(text.begin(), text.end());
      const Status parsed = ParseFourDgsCfgArgs(cfg, &flags);
      if (!parsed.ok()) return parsed.WithContext(candidate.string());
      // 4DGaussians writes every ModelHiddenParams field: a cfg_args without all five head
      // switches is garbled, and its defaults would silently drop heads the checkpoint has.
      std::string missing;
      for (const char* key : {"no_dx=", "no_ds=", "no_dr=", "no_do=", "no_dshs="}) {
        if (cfg.rfind("Namespace(", 0) != 0 || cfg.find(key) == std::string::npos) {
          missing += StrCat(missing.empty() ? "" : ", ", std::string_view(key).substr(0, std::strlen(key) - 1));
        }
      }
      if (!missing.empty()) {
        return MakeError(StatusCode::kCorrupt, candidate.string(), ": not a 4DGaussians Namespace(...) with the head "
                         "switches (missing: ", missing, "); fix it, or pass read_cfg_args = false with the flags");
      }
      flags_from = candidate.string();
      break;
    }
  }
  bool overridden = false;
  auto apply = [&](const std::optional<bool>& option, bool* flag) {
    if (option.has_value()) {
      *flag = *option;
      overridden = true;
    }
  };
  apply(options.no_dx, &flags.no_dx);
  apply(options.no_ds, &flags.no_ds);
  apply(options.no_dr, &flags.no_dr);
  apply(options.no_do, &flags.no_do);
  apply(options.no_dshs, &flags.no_dshs);
  if (overridden) flags_from += " + options";

  Asset asset;
  const std::string ply_path = (iteration_dir / kPly).string();
  ATEX_ASSIGN_OR_RETURN(asset.gaussians, ReadPlyGaussians(ply_path));

  const std::string pth_path = (iteration_dir / kPth).string();
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> pth, ReadFileBytes(pth_path, options.max_checkpoint_bytes));
  ATEX_ASSIGN_OR_RETURN(TorchStateDict state, ReadTorchStateDict(pth.data(), pth.size(), pth_path));
  pth.clear();
  pth.shrink_to_fit();
  ATEX_ASSIGN_OR_RETURN(asset.deformation,
                        FourDgsFieldFromStateDict(state, flags, asset.gaussians.sh_coeffs(), pth_path));

  Metadata& meta = asset.metadata;
  const Gaussians& g = asset.gaussians;
  if (g.size() > 0) {
    for (int a = 0; a < 3; ++a) {
      meta.bounds_min[a] = meta.bounds_max[a] = g.positions[a];
      for (size_t i = 1; i < g.size(); ++i) {
        meta.bounds_min[a] = std::min(meta.bounds_min[a], g.positions[3 * i + a]);
        meta.bounds_max[a] = std::max(meta.bounds_max[a], g.positions[3 * i + a]);
      }
    }
  }
  meta.time_min = 0.0f;  // 4DGaussians' time axis
  meta.time_max = 1.0f;
  meta.texture_mode = "none";
  const DeformationConfig& config = asset.deformation->config;
  meta.extra["importer"] = "4DGaussians";
  meta.extra["source"] = iteration_dir.string();
  if (resolved.second >= 0) meta.extra["iteration"] = resolved.second;
  meta.extra["head_flags"] = {{"no_dx", flags.no_dx},
                              {"no_ds", flags.no_ds},
                              {"no_dr", flags.no_dr},
                              {"no_do", flags.no_do},
                              {"no_dshs", flags.no_dshs},
                              {"from", flags_from}};
  meta.extra["deformation"] = {{"channels", config.grid.channels},
                               {"base_resolution", config.grid.base_resolution},
                               {"multires", config.grid.multires},
                               {"mlp_width", config.mlp_width},
                               {"trunk_layers", config.trunk_layers}};
  const Status valid = ValidateAsset(asset);
  if (!valid.ok()) return valid.WithContext(StrCat("4DGaussians import of '", iteration_dir.string(), "'"));
  return asset;
}

}  // namespace atex
