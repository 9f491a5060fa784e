// The cameras of a .splatv file: the scene's bounds, the default camera that frames them, the
// JSON the viewer reads and the same camera for libatex's renderer. Internal header.
#pragma once

#include <array>
#include <cstddef>
#include <vector>

#include <nlohmann/json.hpp>

#include "atex/camera.h"
#include "atex/converters/splatv.h"

namespace atex::splatv {

// The axis-aligned box of the Gaussians' centres.
struct Bounds {
  std::array<double, 3> lo, hi;
  double diagonal() const;
};
Bounds PositionBounds(const Gaussians& g);

// options.cameras, or else one camera that frames `bounds` from the front, looking horizontally
// with the up axis of the options, else of the asset's metadata, else -y.
std::vector<SplatvCamera> ChooseCameras(const Asset& asset, const SplatvOptions& options, const Bounds& bounds);

// Camera `id` as splaTV's JSON lists it.
nlohmann::json CameraJson(const SplatvCamera& c, size_t id);

// The same camera for libatex's renderer, with the viewer's principal point (the image centre).
Camera ToCamera(const SplatvCamera& c);

}  // namespace atex::splatv
