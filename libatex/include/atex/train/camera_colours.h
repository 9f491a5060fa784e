// The per-camera colour corrections of a training run (colour_correction.h): fitted from the
// current model, carried in the asset's metadata (so that a separate stage-2 run and a resumed
// run continue with them) and handed to the backend with every training view.
#pragma once

#include <map>
#include <string>

#include <nlohmann/json.hpp>

#include "atex/dataset.h"
#include "atex/status.h"
#include "atex/train/backend.h"
#include "atex/train/colour_correction.h"
#include "atex/train/config.h"

namespace atex::train {

class CameraColours {
 public:
  // The correction of a training camera; the identity for a camera without one.
  const ColourAffine& For(int camera_id) const;
  bool empty() const { return by_camera_.empty(); }
  size_t size() const { return by_camera_.size(); }

  // Renders views_per_camera frames of every training camera that has two or more frames (a
  // fixed rig camera; D-NeRF's one-frame cameras get none) with `request` (no correction),
  // fits each camera's correction against its frames (FitColourAffine) and normalises them over
  // the cameras (NormaliseColourAffines). Replaces the current set.
  Status Fit(const Dataset& dataset, Backend& backend, const RenderRequest& request,
             const CameraColourConfig& config);

  // {"<camera id>": {"gain": [r, g, b], "offset": [r, g, b]}, ...}
  nlohmann::json ToJson() const;
  // The inverse of ToJson; kInvalidArgument naming the camera for a malformed or non-finite entry.
  static StatusOr<CameraColours> FromJson(const nlohmann::json& json);
  // "27 cameras, gain R 0.93-1.06 G ... offset R -0.02-0.03 ..." for the training log.
  std::string Summary() const;

 private:
  std::map<int, ColourAffine> by_camera_;
};

}  // namespace atex::train
