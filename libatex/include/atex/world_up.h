// The world's up axis of an asset (metadata.up, format_spec/atex.md §7.1), kept apart
// from the camera convention the asset was trained with (metadata.axes).
//
// Exporters turn the world so that this axis is up in the target format (glTF's
// +Y, SPZ's RUB +Y, the 3DGS PLY convention's -Y); the trainer records it from the
// training cameras (UpAxisFromCameras).
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "atex/camera.h"
#include "atex/model.h"
#include "atex/status.h"

namespace atex {

// True for the six names metadata.up may hold: "+x", "-x", "+y", "-y", "+z", "-z".
bool IsUpAxisName(std::string_view name);

// The up axis older files imply by metadata.axes alone (files written before
// metadata.up existed): "opencv", "colmap", "y_down" -> "-y"; "blender", "z_up" ->
// "+z"; "gltf", "opengl", "y_up" -> "+y"; "z_down" -> "-z"; any other name -> "".
std::string LegacyUpAxis(std::string_view axes);

// metadata.up when recorded, else LegacyUpAxis(metadata.axes). kInvalidArgument
// when neither says which way is up (the caller then needs an explicit axis).
StatusOr<std::string> WorldUpAxis(const Metadata& metadata);

// The world axis the cameras agree is up: the signed coordinate axis nearest to
// the mean of the cameras' up vectors (each camera's -y axis in world
// coordinates, the OpenCV convention of atex/camera.h). nullopt when there are no
// cameras or the mean's length is below `min_agreement` (the cameras' up vectors
// spread too widely, e.g. cameras all around a sphere, to tell).
std::optional<std::string> UpAxisFromCameras(const std::vector<Camera>& cameras, double min_agreement = 0.5);

}  // namespace atex
