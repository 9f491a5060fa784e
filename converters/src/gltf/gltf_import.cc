// glTF -> Asset. NormalizeGltf resolves buffers and meshopt; tinygltf parses the
// document; this file turns KHR_gaussian_splatting primitives (and our extensions)
// back into the model of atex/model.h.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>

#include "atex/converters/gltf.h"
#include "atex/deform.h"
#include "atex/file_io.h"
#include "gltf/gltf_container.h"
#include "gltf/gltf_json_util.h"
#include "gltf/gltf_import_extensions.h"
#include "gltf/gltf_import_scene.h"
#include "gltf/gltf_names.h"
#include "gltf/gltf_spz.h"

#ifdef ATEX_HAVE_TINYGLTF
#include "gltf/tinygltf_config.h"

#include "gltf/gltf_accessors.h"
#include "gltf/gltf_import_base.h"
#include "gltf/sh_rotation.h"
#endif

namespace atex {

#ifdef ATEX_HAVE_TINYGLTF
namespace {

using gltf::ReadAttribute;
using nlohmann::json;

const std::initializer_list<int> kFloatOnly = {gltf::kComponentFloat};

// Bakes a node transform (rotation + uniform scale + translation) into the Gaussians.
Status BakeTransform(const gltf::Mat4& m, Gaussians& g) {
  if (m == gltf::kIdentity) return Status::Ok();
  double col[3][3];
  double scale[3];
  for (int c = 0; c < 3; ++c) {
    for (int r = 0; r < 3; ++r) col[c][r] = m[c * 4 + r];
    scale[c] = std::sqrt(col[c][0] * col[c][0] + col[c][1] * col[c][1] + col[c][2] * col[c][2]);
  }
  if (m[3] != 0 || m[7] != 0 || m[11] != 0 || m[15] != 1) {
    return MakeError(StatusCode::kUnsupported, "node transform is projective");
  }
  const double s = scale[0];
  if (!(s > 0) || std::abs(scale[1] - s) > 1e-6 * s || std::abs(scale[2] - s) > 1e-6 * s) {
    return MakeError(StatusCode::kUnsupported, "node transform has a non-uniform or zero scale (", scale[0], ", ",
                     scale[1], ", ", scale[2], ")");
  }
  std::array<double, 9> r;  // row-major rotation
  for (int row = 0; row < 3; ++row) {
    for (int c = 0; c < 3; ++c) r[row * 3 + c] = col[c][row] / s;
  }
  const double det =
      r[0] * (r[4] * r[8] - r[5] * r[7]) - r[1] * (r[3] * r[8] - r[5] * r[6]) + r[2] * (r[3] * r[7] - r[4] * r[6]);
  if (det < 0) return MakeError(StatusCode::kUnsupported, "node transform mirrors (negative determinant)");
  // Rotation matrix -> quaternion (w, x, y, z).
  double qw, qx, qy, qz;
  const double trace = r[0] + r[4] + r[8];
  if (trace > 0) {
    const double k = 0.5 / std::sqrt(trace + 1.0);
    qw = 0.25 / k, qx = (r[7] - r[5]) * k, qy = (r[2] - r[6]) * k, qz = (r[3] - r[1]) * k;
  } else if (r[0] > r[4] && r[0] > r[8]) {
    const double k = 2.0 * std::sqrt(1.0 + r[0] - r[4] - r[8]);
    qw = (r[7] - r[5]) / k, qx = 0.25 * k, qy = (r[1] + r[3]) / k, qz = (r[2] + r[6]) / k;
  } else if (r[4] > r[8]) {
    const double k = 2.0 * std::sqrt(1.0 + r[4] - r[0] - r[8]);
    qw = (r[2] - r[6]) / k, qx = (r[1] + r[3]) / k, qy = 0.25 * k, qz = (r[5] + r[7]) / k;
  } else {
    const double k = 2.0 * std::sqrt(1.0 + r[8] - r[0] - r[4]);
    qw = (r[3] - r[1]) / k, qx = (r[2] + r[6]) / k, qy = (r[5] + r[7]) / k, qz = 0.25 * k;
  }
  const double log_s = std::log(s);
  const gltf::ShRotation sh_rotation = gltf::MakeShRotation(r, g.sh_degree);
  const size_t n = g.size(), k_count = size_t(g.sh_coeffs());
  for (size_t i = 0; i < n; ++i) {
    float* p = &g.positions[i * 3];
    const double x = p[0], y = p[1], z = p[2];
    for (int row = 0; row < 3; ++row) p[row] = float(m[row] * x + m[4 + row] * y + m[8 + row] * z + m[12 + row]);
    float* q = &g.rotations[i * 4];  // (w, x, y, z): q' = q_node * q
    const double w = q[0], a = q[1], b = q[2], c = q[3];
    q[0] = float(qw * w - qx * a - qy * b - qz * c);
    q[1] = float(qw * a + qx * w + qy * c - qz * b);
    q[2] = float(qw * b - qx * c + qy * w + qz * a);
    q[3] = float(qw * c + qx * b - qy * a + qz * w);
    for (int k = 0; k < 3; ++k) g.log_scales[i * 3 + k] = float(g.log_scales[i * 3 + k] + log_s);
    gltf::RotateSh(sh_rotation, g.sh_degree, &g.sh[i * k_count * 3]);
  }
  return Status::Ok();
}

// Our own files: the node's rotation is the upright turn (not applied: the data stays in asset
// coordinates), but its uniform scale and translation are a quantised file's dequantisation
// (world = T + R * s * q, so asset = s * q + R^T * T). Files without them are left bit for bit.
Status ApplyQuantizationFrame(const gltf::Mat4& m, Gaussians& g) {
  double s = 0;
  for (int r = 0; r < 3; ++r) s += m[r] * m[r];
  s = std::sqrt(s);  // column 0's length; BakeTransform refuses other columns of another length
  if (!(s > 0) || !std::isfinite(s)) return MakeError(StatusCode::kUnsupported, "node transform has a zero scale");
  std::array<double, 3> offset;  // R^T * T, with R = (upper 3x3) / s
  for (int c = 0; c < 3; ++c) {
    offset[c] = (m[c * 4 + 0] * m[12] + m[c * 4 + 1] * m[13] + m[c * 4 + 2] * m[14]) / s;
  }
  // A rotation-only node (every column of unit length, no offset, within rounding): nothing to apply.
  constexpr double kTiny = 1e-12;
  bool rotation_only = std::abs(offset[0]) <= kTiny && std::abs(offset[1]) <= kTiny && std::abs(offset[2]) <= kTiny;
  for (int c = 0; c < 3; ++c) {
    const double length = std::sqrt(m[c * 4] * m[c * 4] + m[c * 4 + 1] * m[c * 4 + 1] + m[c * 4 + 2] * m[c * 4 + 2]);
    rotation_only = rotation_only && std::abs(length - 1) <= kTiny;
  }
  if (rotation_only) return Status::Ok();
  gltf::Mat4 frame = gltf::kIdentity;
  for (int k = 0; k < 3; ++k) frame[size_t(k * 5)] = s;
  for (int k = 0; k < 3; ++k) frame[size_t(12 + k)] = offset[k];
  // The full matrix passes BakeTransform's checks (uniform, not mirrored, affine) first.
  Gaussians probe;
  ATEX_RETURN_IF_ERROR(BakeTransform(m, probe));
  return BakeTransform(frame, g);
}

// Appends `b` to `a` (SH degree: the larger; missing coefficients are zero).
void AppendGaussians(Gaussians& a, const Gaussians& b) {
  if (a.size() == 0) {
    a = b;
    return;
  }
  const int degree = std::max(a.sh_degree, b.sh_degree);
  auto widen = [degree](const Gaussians& g) {
    if (g.sh_degree == degree) return g.sh;
    const size_t n = g.size(), from = size_t(g.sh_coeffs()), to = size_t(ShCoeffCount(degree));
    std::vector<float> sh(n * to * 3, 0.0f);
    for (size_t i = 0; i < n; ++i) std::copy_n(&g.sh[i * from * 3], from * 3, &sh[i * to * 3]);
    return sh;
  };
  std::vector<float> sh = widen(a);
  const std::vector<float> sh_b = widen(b);
  sh.insert(sh.end(), sh_b.begin(), sh_b.end());
  a.sh = std::move(sh);
  a.sh_degree = degree;
  a.positions.insert(a.positions.end(), b.positions.begin(), b.positions.end());
  a.rotations.insert(a.rotations.end(), b.rotations.begin(), b.rotations.end());
  a.log_scales.insert(a.log_scales.end(), b.log_scales.begin(), b.log_scales.end());
  a.opacity_logits.insert(a.opacity_logits.end(), b.opacity_logits.begin(), b.opacity_logits.end());
}

// Replaces the base-derived parameters by the bit-exact raw ones when present.
Status ReadRawParameters(const tinygltf::Model& model, const tinygltf::Primitive& primitive, Gaussians& g) {
  const size_t n = g.size();
  std::vector<float> raw;
  bool present = false;
  ATEX_RETURN_IF_ERROR(ReadAttribute(model, primitive, gltf::kAttrRawRotation, 4, kFloatOnly, n, &raw, &present));
  if (present) {
    for (size_t i = 0; i < n; ++i) {
      g.rotations[i * 4 + 0] = raw[i * 4 + 3];
      g.rotations[i * 4 + 1] = raw[i * 4 + 0];
      g.rotations[i * 4 + 2] = raw[i * 4 + 1];
      g.rotations[i * 4 + 3] = raw[i * 4 + 2];
    }
  }
  ATEX_RETURN_IF_ERROR(ReadAttribute(model, primitive, gltf::kAttrRawLogScale, 3, kFloatOnly, n, &raw, &present));
  if (present) g.log_scales = raw;
  ATEX_RETURN_IF_ERROR(ReadAttribute(model, primitive, gltf::kAttrRawLogit, 1, kFloatOnly, n, &raw, &present));
  if (present) g.opacity_logits = raw;
  return Status::Ok();
}

Metadata ForeignMetadata(const Gaussians& g) {
  Metadata m;
  m.axes = "gltf";
  m.texture_mode = "none";
  if (g.size() > 0) {
    for (int k = 0; k < 3; ++k) {
      m.bounds_min[k] = std::numeric_limits<float>::infinity();
      m.bounds_max[k] = -std::numeric_limits<float>::infinity();
    }
    for (size_t i = 0; i < g.size(); ++i) {
      for (int k = 0; k < 3; ++k) {
        m.bounds_min[k] = std::min(m.bounds_min[k], g.positions[i * 3 + k]);
        m.bounds_max[k] = std::max(m.bounds_max[k], g.positions[i * 3 + k]);
      }
    }
  }
  m.extra = {{"imported_from", "glTF KHR_gaussian_splatting"}};
  return m;
}

const json* FindPath(const json& root, std::initializer_list<const char*> keys) {
  const json* cur = &root;
  for (const char* k : keys) {
    if (!cur->is_object()) return nullptr;
    auto it = cur->find(k);
    if (it == cur->end()) return nullptr;
    cur = &*it;
  }
  return cur;
}

// The base Gaussians of one splat primitive: from its SPZ stream when the primitive carries
// KHR_gaussian_splatting_compression_spz_2 (its accessors then have no data), else from the
// accessors.
StatusOr<Gaussians> ReadPrimitiveBase(const tinygltf::Model& model, const json& doc, const gltf::SplatPrimitive& sp,
                                      const GltfImportOptions& options, bool ours) {
  const tinygltf::Primitive& primitive = model.meshes[sp.mesh].primitives[sp.primitive];
  // FindSplatPrimitives found this primitive through the same path, so at() cannot throw here.
  const json& entry = doc.at("meshes").at(sp.mesh).at("primitives").at(sp.primitive);
  const json* khr = FindPath(entry, {"extensions", gltf::kKhrGaussianSplatting});
  const json* spz = khr ? FindPath(*khr, {"extensions", gltf::kKhrSpz2}) : nullptr;
  if (spz == nullptr) return gltf::ReadBase(model, primitive, options, ours);
  if (primitive.mode != gltf::kModePoints) {
    return MakeError(StatusCode::kCorrupt, "splat primitive has mode ", primitive.mode,
                     ", KHR_gaussian_splatting needs POINTS (0)");
  }
  return gltf::ReadSpzPrimitive(model, primitive, *khr, options.max_gaussians);
}

StatusOr<Asset> ModelToAsset(const tinygltf::Model& model, const json& doc, const GltfImportOptions& options) {
  ATEX_ASSIGN_OR_RETURN(std::vector<gltf::SplatPrimitive> splats, gltf::FindSplatPrimitives(model, doc));
  if (splats.empty())
    return MakeError(StatusCode::kUnsupported, "no KHR_gaussian_splatting primitive in the default scene");
  const json* atex = FindPath(doc, {"extras", "atex"});
  Asset asset;
  if (atex == nullptr) {
    // Someone else's file: base attributes of every splat primitive, transforms baked in, colours
    // in our colour space.
    int linear_primitives = 0;
    for (size_t i = 0; i < splats.size(); ++i) {
      const auto& sp = splats[i];
      auto g = ReadPrimitiveBase(model, doc, sp, options, false);
      if (!g.ok()) return g.status().WithContext(StrCat("meshes[", sp.mesh, "].primitives[", sp.primitive, "]"));
      const json& primitive = doc.at("meshes").at(sp.mesh).at("primitives").at(sp.primitive);
      const json* space = FindPath(primitive, {"extensions", gltf::kKhrGaussianSplatting, "colorSpace"});
      if (space != nullptr && *space == "lin_rec709_display") {
        gltf::LinearToDisplayColour(*g);
        linear_primitives++;
      }
      ATEX_RETURN_IF_ERROR(BakeTransform(sp.world, *g));
      if (asset.gaussians.size() + g->size() > options.max_gaussians) {
        return MakeError(StatusCode::kLimitExceeded, "more than ", options.max_gaussians, " Gaussians");
      }
      AppendGaussians(asset.gaussians, *g);
      if (options.progress && !options.progress(0.5 + 0.5 * double(i + 1) / double(splats.size()))) {
        return MakeError(StatusCode::kCancelled, "glTF import cancelled");
      }
    }
    asset.metadata = ForeignMetadata(asset.gaussians);
    if (linear_primitives > 0) {
      asset.metadata.extra["colour_space"] = StrCat(linear_primitives, " of ", splats.size(),
                                                    " primitives lin_rec709_display, converted to srgb_rec709_display");
    }
    ATEX_RETURN_IF_ERROR(ValidateAsset(asset));
    return asset;
  }

  // Ours: one primitive, data in asset coordinates (the node only turns it upright).
  if (!atex->is_object()) return MakeError(StatusCode::kCorrupt, "extras.atex is not an object");
  if (splats.size() != 1)
    return MakeError(StatusCode::kCorrupt, "an atex glTF has one splat primitive, this one has ", splats.size());
  int64_t version = 0;
  if (auto v = atex->find("version");
      v == atex->end() || !gltf::ReadIntValue(*v, "extras.atex.version", 1, INT32_MAX, &version).ok()) {
    return MakeError(StatusCode::kCorrupt, "extras.atex.version is missing or invalid");
  }
  if (version > gltf::kAtexGltfVersion) {
    return MakeError(StatusCode::kUnsupportedVersion, "extras.atex.version ", version, " is newer than this reader (",
                     gltf::kAtexGltfVersion, ")");
  }
  const auto& sp = splats[0];
  const tinygltf::Primitive& primitive = model.meshes[sp.mesh].primitives[sp.primitive];
  ATEX_ASSIGN_OR_RETURN(asset.gaussians, ReadPrimitiveBase(model, doc, sp, options, true));
  ATEX_RETURN_IF_ERROR(ApplyQuantizationFrame(sp.world, asset.gaussians));
  const json& khr = doc["meshes"][sp.mesh]["primitives"][sp.primitive]["extensions"][gltf::kKhrGaussianSplatting];
  if (!khr.is_object()) return MakeError(StatusCode::kCorrupt, gltf::kKhrGaussianSplatting, " is not an object");
  const json* sub = FindPath(khr, {"extensions"});
  const json* deformation = sub ? FindPath(*sub, {gltf::kAtexDeformation}) : nullptr;
  const json* textures = sub ? FindPath(*sub, {gltf::kAtexTextures}) : nullptr;
  if (deformation != nullptr) {
    if (!deformation->is_object()) return MakeError(StatusCode::kCorrupt, gltf::kAtexDeformation, " is not an object");
    ATEX_RETURN_IF_ERROR(ReadRawParameters(model, primitive, asset.gaussians));
    if (auto f = deformation->find("field"); f != deformation->end()) {
      ATEX_ASSIGN_OR_RETURN(DeformationField field, gltf::ReadField(model, *f));
      asset.deformation = std::move(field);
    }
  }
  if (textures != nullptr) {
    ATEX_ASSIGN_OR_RETURN(TexturePool pool, gltf::ReadTextures(model, primitive, *textures, asset.gaussians.size()));
    asset.textures = std::move(pool);
  }
  const json* metadata = FindPath(*atex, {"metadata"});
  if (metadata == nullptr) return MakeError(StatusCode::kCorrupt, "extras.atex.metadata is missing");
  auto md = MetadataFromJson(*metadata);
  if (!md.ok()) return md.status().WithContext("extras.atex.metadata");
  asset.metadata = std::move(md).value();
  // Exported without its textures (--no-textures, or a foreign edit): the metadata describes the
  // asset as it was, but what the file holds is untextured.
  if (!asset.textures) asset.metadata.texture_mode = "none";
  ATEX_RETURN_IF_ERROR(ValidateAsset(asset));
  return asset;
}

bool NoImageLoading(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int,
                    void*) {
  return true;  // splat data has no images; never decode hostile image bytes
}
bool DenyFileExists(const std::string&, void*) { return false; }
std::string DenyExpand(const std::string& path, void*) { return path; }
bool DenyRead(std::vector<unsigned char>*, std::string* err, const std::string& path, void*) {
  if (err) *err += "external file access is disabled: " + path;
  return false;
}
bool DenyWrite(std::string* err, const std::string& path, const std::vector<unsigned char>&, void*) {
  if (err) *err += "file writing is disabled: " + path;
  return false;
}

StatusOr<Asset> DecodeWithLoader(const uint8_t* data, size_t size, const gltf::UriLoader& loader,
                                 const GltfImportOptions& options) {
  ATEX_ASSIGN_OR_RETURN(gltf::NormalizedGltf normalized, gltf::NormalizeGltf(data, size, loader, options));
  if (options.progress && !options.progress(0.3)) return MakeError(StatusCode::kCancelled, "glTF import cancelled");
  std::vector<uint8_t> glb = std::move(normalized.glb);
  tinygltf::TinyGLTF parser;
  parser.SetImageLoader(NoImageLoading, nullptr);
  parser.SetFsCallbacks({DenyFileExists, DenyExpand, DenyRead, DenyWrite, nullptr});
  tinygltf::Model model;
  std::string err, warn;
  if (!parser.LoadBinaryFromMemory(&model, &err, &warn, glb.data(), static_cast<unsigned int>(glb.size()), "")) {
    return MakeError(StatusCode::kCorrupt, "glTF document: ", err.empty() ? "tinygltf rejected it" : err);
  }
  std::vector<uint8_t>().swap(glb);  // tinygltf holds its own copy of the buffer
  return ModelToAsset(model, normalized.doc, options);
}

}  // namespace
#endif  // ATEX_HAVE_TINYGLTF

StatusOr<Asset> DecodeGltf(const uint8_t* data, size_t size, const GltfImportOptions& options) {
#ifdef ATEX_HAVE_TINYGLTF
  try {
    return DecodeWithLoader(data, size, {}, options);
  } catch (const std::bad_alloc&) {
    return MakeError(StatusCode::kLimitExceeded, "glTF import: out of memory");
  } catch (const std::exception& e) {
    return MakeError(StatusCode::kCorrupt, "glTF import: ", e.what());
  }
#else
  (void)data, (void)size, (void)options;
  return MakeError(StatusCode::kUnsupported, "glTF import needs tinygltf, which this build lacks");
#endif
}

StatusOr<Asset> ReadGltfFile(const std::string& path, const GltfImportOptions& options) {
#ifdef ATEX_HAVE_TINYGLTF
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, ReadFileBytes(path, options.max_decoded_bytes));
  const std::filesystem::path folder = std::filesystem::path(path).parent_path();
  gltf::UriLoader loader = [folder](const std::string& uri, uint64_t max_bytes) -> StatusOr<std::vector<uint8_t>> {
    const std::filesystem::path relative(uri);
    if (uri.empty() || relative.is_absolute() || uri.find(':') != std::string::npos) {
      return MakeError(StatusCode::kUnsupported, "buffer URI '", uri, "' is not a relative file name");
    }
    for (const auto& part : relative) {
      if (part == "..") return MakeError(StatusCode::kCorrupt, "buffer URI '", uri, "' leaves the glTF's folder");
    }
    return ReadFileBytes((folder / relative).string(), max_bytes);
  };
  try {
    auto asset = DecodeWithLoader(bytes.data(), bytes.size(), loader, options);
    if (!asset.ok()) return asset.status().WithContext(path);
    return asset;
  } catch (const std::bad_alloc&) {
    return MakeError(StatusCode::kLimitExceeded, path, ": out of memory");
  } catch (const std::exception& e) {
    return MakeError(StatusCode::kCorrupt, path, ": ", e.what());
  }
#else
  (void)options;
  return MakeError(StatusCode::kUnsupported, "glTF import of '", path, "' needs tinygltf, which this build lacks");
#endif
}

}  // namespace atex
