// The per-layout dataset loaders behind OpenDataset (not a public header).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "atex/dataset.h"

namespace atex::data_detail {

Status ValidateOptions(const DatasetOptions& options);
// Intrinsics and size for an integer downscale (pixel-centre convention: x' = x/f).
Camera ScaleCamera(Camera camera, int factor);
// Parses a JSON file; kNotFound / kCorrupt (with the byte offset) on failure.
StatusOr<nlohmann::json> ReadJsonFile(const std::string& path);
// The last non-empty component of a path ("data/lego/" -> "lego").
std::string DatasetNameFromPath(const std::string& path);
// Sets the time range from the views (0, 0 when there are none).
void FinishTimeRange(const std::vector<View>& train, const std::vector<View>& test, float* time_min, float* time_max);

StatusOr<std::unique_ptr<Dataset>> OpenPanoptic(const std::string& folder, const DatasetOptions& options);
StatusOr<std::unique_ptr<Dataset>> OpenDNerf(const std::string& folder, const DatasetOptions& options);
StatusOr<std::unique_ptr<Dataset>> OpenDNerfNpz(const std::string& file, const DatasetOptions& options);
StatusOr<std::unique_ptr<Dataset>> OpenN3dv(const std::string& folder, const DatasetOptions& options);
// `path`: a transforms.json file or the folder holding one.
StatusOr<std::unique_ptr<Dataset>> OpenNerfstudio(const std::string& path, const DatasetOptions& options);
StatusOr<std::unique_ptr<Dataset>> OpenColmap(const std::string& folder, const DatasetOptions& options);
// Whether the folder holds a COLMAP model where OpenColmap looks for one.
bool LooksLikeColmap(const std::string& folder);

}  // namespace atex::data_detail
