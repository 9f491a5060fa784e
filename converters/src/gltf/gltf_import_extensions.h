// Readers of our glTF extensions' payloads (ATEX_gaussian_textures, ATEX_gaussian_deformation) for
// gltf_import.cc: the JSON of the extension plus the accessors it names, checked against the
// primitive's Gaussian count and the deformation config before anything is read.
#pragma once

#ifdef ATEX_HAVE_TINYGLTF
#include <cstddef>
#include <string>

#include "atex/deform.h"
#include "atex/model.h"
#include <nlohmann/json.hpp>

#include "atex/status.h"
#include "gltf/tinygltf_config.h"

namespace atex::gltf {

// The texture pool of `n` Gaussians from a primitive's ATEX_gaussian_textures extension `ext`:
// the per-Gaussian layout attribute (sides 1, 2 or 4; two distinct axes) and the texel accessor,
// whose count must be the layout's. kCorrupt / kOutOfRange name the attribute and element.
StatusOr<TexturePool> ReadTextures(const tinygltf::Model& model, const tinygltf::Primitive& primitive,
                                   const nlohmann::json& ext, size_t n);

// The deformation field of ATEX_gaussian_deformation's "field" object `f`: its config (checked by
// CheckDeformationConfig before any accessor is read), the HexPlane grids and the MLP layers
// (checked by CheckDeformationField). Errors name the JSON path.
StatusOr<DeformationField> ReadField(const tinygltf::Model& model, const nlohmann::json& f);

}  // namespace atex::gltf
#endif
