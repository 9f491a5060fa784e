// Reading the base attributes of a KHR_gaussian_splatting primitive for gltf_import.cc: accessor
// shapes and component types as the extension's attribute table allows them, values converted to
// our raw parameters (atex/model.h). Internal header.
#pragma once

#ifdef ATEX_HAVE_TINYGLTF
#include <cstddef>
#include <initializer_list>
#include <string>
#include <vector>

#include "atex/converters/gltf.h"
#include "atex/model.h"
#include "atex/status.h"
#include "gltf/tinygltf_config.h"

namespace atex::gltf {

// Reads attribute `name` of a primitive as floats ([count][components]), checking its shape and
// that its component type is one of `types`. A missing attribute is kCorrupt, unless `present` is
// given (then *present says whether it was there). `normalized_integers`: integer component types
// must be normalized (KHR_gaussian_splatting's ROTATION and OPACITY).
Status ReadAttribute(const tinygltf::Model& model, const tinygltf::Primitive& primitive, const std::string& name,
                     int components, std::initializer_list<int> types, size_t count, std::vector<float>* out,
                     bool* present = nullptr, bool normalized_integers = false);

// The Gaussians of one splat primitive from its accessors: POSITION, the unit quaternion ROTATION
// (x, y, z, w), the linear SCALE (-> log-scales), the linear OPACITY in [0, 1] (-> logits; 0 and 1
// clamped to finite logits) and the complete SH degrees. `ours`: the file carries extras.atex, so
// the SHORT normalized SCALE of atex's earlier --quantize files is accepted too; a signed SCALE in
// any other file is kUnsupported (signed types belong to the superseded log-space draft, and the
// file does not say which text it follows). Wrong shapes or types are kCorrupt, negative scales
// and opacities outside [0, 1] kOutOfRange; messages name the attribute and element.
StatusOr<Gaussians> ReadBase(const tinygltf::Model& model, const tinygltf::Primitive& primitive,
                             const GltfImportOptions& options, bool ours);

// colorSpace "lin_rec709_display" of KHR_gaussian_splatting: the SH give linear colour, where ours
// (3DGS's convention, "srgb_rec709_display") give display colour, sRGB-encoded. Converts `g` in
// place: the diffuse colour 0.5 + C0·SH_0 exactly (clamped to [0, 1], then sRGB-encoded), the
// higher degrees scaled per channel by the sRGB curve's slope at that colour (first order: the
// view-dependent part is a small deviation around it). Blending in linear light, which such a
// file's author may have meant, is not reproduced: we blend display colours as 3DGS does.
void LinearToDisplayColour(Gaussians& g);

}  // namespace atex::gltf
#endif
