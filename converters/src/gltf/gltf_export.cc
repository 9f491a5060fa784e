// Asset -> glTF document: KHR_gaussian_splatting base attributes, our two
// extensions, the up-axis node rotation and the metadata (gltf.h has the layout).
#include <algorithm>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>

#include "atex/converters/gltf.h"
#include "atex/deform.h"
#include "atex/file_io.h"
#include "atex/version.h"
#include "gltf/gltf_container.h"
#include "gltf/gltf_json_util.h"
#include "gltf/gltf_names.h"
#include "gltf/gltf_quantize.h"
#include "gltf/gltf_spz.h"
#include "gltf/gltf_writer.h"

namespace atex {
namespace {

using gltf::GltfWriter;
using gltf::MeshoptFilter;
using nlohmann::json;

static_assert(std::endian::native == std::endian::little, "the glTF writer stores host floats as little-endian bytes");

template <typename T>
const uint8_t* Bytes(const std::vector<T>& v) {
  return reinterpret_cast<const uint8_t*>(v.data());
}

double Sigmoid(double x) { return 1.0 / (1.0 + std::exp(-x)); }
// The inverse of the sRGB transfer function (IEC 61966-2-1), v in [0, 1].
double SrgbToLinear(double v) { return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4); }

class SplatExporter {
 public:
  explicit SplatExporter(const GltfExportOptions& options) : options_(options), writer_(options.meshopt) {}

  Status Build(const Asset& asset);
  GltfWriter& writer() { return writer_; }

 private:
  // A float view of [count][components] values. With meshopt and `lossy` allowed, the
  // EXPONENTIAL filter is applied; `decoded` receives the values a reader will see.
  StatusOr<int> FloatView(const float* data, size_t count, size_t components, bool vertex, bool lossy,
                          std::vector<float>* decoded);
  // FloatView + one accessor over all of it.
  StatusOr<int> FloatAccessor(const std::vector<float>& data, size_t count, size_t components, const char* type,
                              bool vertex, bool lossy, bool min_max);
  Status AddBase(const Gaussians& g, json& attributes);
  Status AddBaseSpz(const Gaussians& g, json& attributes, json& khr_extensions);
  Status AddTextures(const TexturePool& textures, size_t n, json& attributes, json& khr_extensions);
  Status AddDeformation(const Gaussians& g, const DeformationField* field, json& attributes, json& khr_extensions);
  StatusOr<json> AddLinear(const Linear& layer, const std::string& where);
  Status Progress(double fraction) {
    if (options_.progress && !options_.progress(fraction))
      return MakeError(StatusCode::kCancelled, "glTF export cancelled");
    return Status::Ok();
  }
  bool lossy() const { return options_.meshopt && options_.meshopt_float_bits > 0; }

  const GltfExportOptions& options_;
  GltfWriter writer_;
  gltf::PositionFrame position_frame_;  // --quantize: the node's dequantisation (identity otherwise)
};

StatusOr<int> SplatExporter::FloatView(const float* data, size_t count, size_t components, bool vertex, bool lossy,
                                       std::vector<float>* decoded) {
  gltf::ViewSpec spec;
  spec.count = count;
  spec.stride = components * 4;
  spec.vertex_attribute = vertex;
  std::vector<uint8_t> filtered;
  if (options_.meshopt && lossy) {
    ATEX_ASSIGN_OR_RETURN(filtered, gltf::EncodeExponential(data, count, components, options_.meshopt_float_bits));
    spec.bytes = filtered.data();
    spec.filter = MeshoptFilter::kExponential;
    if (decoded != nullptr) {
      std::vector<uint8_t> copy = filtered;
      ATEX_RETURN_IF_ERROR(gltf::DecodeFilter(MeshoptFilter::kExponential, copy.data(), count, spec.stride));
      decoded->resize(count * components);
      std::memcpy(decoded->data(), copy.data(), copy.size());
    }
  } else {
    spec.bytes = reinterpret_cast<const uint8_t*>(data);
    if (decoded != nullptr) decoded->assign(data, data + count * components);
  }
  return writer_.AddView(spec);
}

StatusOr<int> SplatExporter::FloatAccessor(const std::vector<float>& data, size_t count, size_t components,
                                           const char* type, bool vertex, bool lossy, bool min_max) {
  std::vector<float> decoded;
  ATEX_ASSIGN_OR_RETURN(int view,
                        FloatView(data.data(), count, components, vertex, lossy, min_max ? &decoded : nullptr));
  json min = nullptr, max = nullptr;
  if (min_max) {
    std::vector<float> lo(components, std::numeric_limits<float>::infinity());
    std::vector<float> hi(components, -std::numeric_limits<float>::infinity());
    for (size_t i = 0; i < count; ++i) {
      for (size_t c = 0; c < components; ++c) {
        lo[c] = std::min(lo[c], decoded[i * components + c]);
        hi[c] = std::max(hi[c], decoded[i * components + c]);
      }
    }
    min = json::array();
    max = json::array();
    // The exact double of each float: a reader comparing in either precision finds equality.
    for (size_t c = 0; c < components; ++c) {
      min.push_back(double(lo[c]));
      max.push_back(double(hi[c]));
    }
  }
  return writer_.AddAccessor(view, 0, gltf::kComponentFloat, false, count, type, min, max);
}

// With --quantize, POSITION, SCALE and OPACITY are normalized integers in the node's frame
// (gltf_quantize.h; Build puts the frame on the node) and ROTATION int8 unless meshopt's filter
// packs it; otherwise floats. Views and accessors come in the same order either way.
Status SplatExporter::AddBase(const Gaussians& g, json& attributes) {
  const size_t n = g.size();
  std::vector<float> opacities(n);  // [N] in [0, 1]
  for (size_t i = 0; i < n; ++i) opacities[i] = float(Sigmoid(g.opacity_logits[i]));
  gltf::QuantizedGeometry q;
  if (options_.quantize) {
    ATEX_ASSIGN_OR_RETURN(q, gltf::QuantizeGeometry(g, opacities));
    ATEX_ASSIGN_OR_RETURN(int view, writer_.AddView({q.positions.data(), n, 8, true, MeshoptFilter::kNone}));
    attributes[gltf::kAttrPosition] =
        writer_.AddAccessor(view, 0, gltf::kComponentShort, true, n, "VEC3", q.position_min, q.position_max);
    position_frame_ = q.frame;
    writer_.UseExtension(gltf::kKhrMeshQuantization, true);
  } else {
    ATEX_ASSIGN_OR_RETURN(int position, FloatAccessor(g.positions, n, 3, "VEC3", true, lossy(), true));
    attributes[gltf::kAttrPosition] = position;
  }

  const std::vector<float> xyzw = gltf::UnitQuaternionsXyzw(g);  // [N][4]
  if (options_.meshopt) {
    ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> packed,
                          gltf::EncodeQuaternion(xyzw.data(), n, options_.meshopt_rotation_bits));
    gltf::ViewSpec spec{packed.data(), n, 8, true, MeshoptFilter::kQuaternion};
    ATEX_ASSIGN_OR_RETURN(int view, writer_.AddView(spec));
    attributes[gltf::kAttrRotation] = writer_.AddAccessor(view, 0, gltf::kComponentShort, true, n, "VEC4");
  } else if (options_.quantize) {
    const std::vector<uint8_t> packed = gltf::QuantizeRotations(xyzw);
    ATEX_ASSIGN_OR_RETURN(int view, writer_.AddView({packed.data(), n, 4, true, MeshoptFilter::kNone}));
    attributes[gltf::kAttrRotation] = writer_.AddAccessor(view, 0, gltf::kComponentByte, true, n, "VEC4");
  } else {
    ATEX_ASSIGN_OR_RETURN(int rotation, FloatAccessor(xyzw, n, 4, "VEC4", true, false, false));
    attributes[gltf::kAttrRotation] = rotation;
  }

  if (options_.quantize) {
    ATEX_ASSIGN_OR_RETURN(int sview, writer_.AddView({q.scales.data(), n, 8, true, MeshoptFilter::kNone}));
    attributes[gltf::kAttrScale] = writer_.AddAccessor(sview, 0, gltf::kComponentUnsignedShort, true, n, "VEC3");
    ATEX_ASSIGN_OR_RETURN(int oview, writer_.AddView({q.opacities.data(), n, 4, true, MeshoptFilter::kNone}));
    attributes[gltf::kAttrOpacity] = writer_.AddAccessor(oview, 0, gltf::kComponentUnsignedShort, true, n, "SCALAR");
  } else {
    // [N][3] linear, kept positive and finite in float (a log-scale of -200 underflows to 0,
    // which the extension forbids; the raw attributes keep the exact value).
    std::vector<float> scales(n * 3);
    for (size_t i = 0; i < n * 3; ++i) {
      scales[i] = float(std::clamp(std::exp(double(g.log_scales[i])), double(std::numeric_limits<float>::min()),
                                   double(std::numeric_limits<float>::max())));
    }
    ATEX_ASSIGN_OR_RETURN(int scale, FloatAccessor(scales, n, 3, "VEC3", true, lossy(), false));
    attributes[gltf::kAttrScale] = scale;
    ATEX_ASSIGN_OR_RETURN(int opacity, FloatAccessor(opacities, n, 1, "SCALAR", true, lossy(), false));
    attributes[gltf::kAttrOpacity] = opacity;
  }

  // SH: one interleaved view [N][K][3] (our layout), one VEC3 accessor per coefficient.
  const size_t k_count = size_t(g.sh_coeffs());
  ATEX_ASSIGN_OR_RETURN(int sh_view, FloatView(g.sh.data(), n, 3 * k_count, true, lossy(), nullptr));
  for (int degree = 0; degree <= g.sh_degree; ++degree) {
    for (int coef = 0; coef <= 2 * degree; ++coef) {
      const size_t k = size_t(degree * degree + coef);
      attributes[gltf::ShAttribute(degree, coef)] =
          writer_.AddAccessor(sh_view, k * 12, gltf::kComponentFloat, false, n, "VEC3");
    }
  }

  if (options_.color_fallback) {
    // clamp(0.5 + C0 * SH_0) is in our colour space (srgb_rec709_display); COLOR_0 is linear (glTF
    // 2.0), so it is decoded from sRGB, as the extension's fallback section says. Alpha: the opacity.
    constexpr double kC0 = 0.28209479177387814;
    std::vector<uint8_t> rgba(n * 4);  // [N][4]
    for (size_t i = 0; i < n; ++i) {
      for (int c = 0; c < 3; ++c) {
        const double v = std::clamp(0.5 + kC0 * g.sh[i * k_count * 3 + c], 0.0, 1.0);
        rgba[i * 4 + c] = uint8_t(std::lround(SrgbToLinear(v) * 255));
      }
      rgba[i * 4 + 3] = uint8_t(std::lround(double(opacities[i]) * 255));
    }
    ATEX_ASSIGN_OR_RETURN(int view, writer_.AddView({rgba.data(), n, 4, true, MeshoptFilter::kNone}));
    attributes[gltf::kAttrColor] = writer_.AddAccessor(view, 0, gltf::kComponentUnsignedByte, true, n, "VEC4");
  }
  return Status::Ok();
}

// The base attributes as accessors without bufferViews (their type and count only, POSITION with
// its bounds, as glTF requires) and the SPZ stream that holds their data.
Status SplatExporter::AddBaseSpz(const Gaussians& g, json& attributes, json& khr_extensions) {
  const size_t n = g.size();
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> stream, gltf::EncodeSpzForGltf(g));
  ATEX_ASSIGN_OR_RETURN(int view, writer_.AddBlobView(stream.data(), stream.size()));
  json min = {std::numeric_limits<float>::max(), std::numeric_limits<float>::max(), std::numeric_limits<float>::max()};
  json max = {-std::numeric_limits<float>::max(), -std::numeric_limits<float>::max(),
              -std::numeric_limits<float>::max()};
  for (size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) {
      min[k] = std::min(min[k].get<float>(), g.positions[i * 3 + size_t(k)]);
      max[k] = std::max(max[k].get<float>(), g.positions[i * 3 + size_t(k)]);
    }
  }
  attributes[gltf::kAttrPosition] = writer_.AddAccessor(-1, 0, gltf::kComponentFloat, false, n, "VEC3", min, max);
  attributes[gltf::kAttrRotation] = writer_.AddAccessor(-1, 0, gltf::kComponentFloat, false, n, "VEC4");
  attributes[gltf::kAttrScale] = writer_.AddAccessor(-1, 0, gltf::kComponentFloat, false, n, "VEC3");
  attributes[gltf::kAttrOpacity] = writer_.AddAccessor(-1, 0, gltf::kComponentFloat, false, n, "SCALAR");
  for (int degree = 0; degree <= g.sh_degree; ++degree) {
    for (int coef = 0; coef <= 2 * degree; ++coef) {
      attributes[gltf::ShAttribute(degree, coef)] = writer_.AddAccessor(-1, 0, gltf::kComponentFloat, false, n, "VEC3");
    }
  }
  khr_extensions[gltf::kKhrSpz2] = {{"bufferView", view}};
  writer_.UseExtension(gltf::kKhrSpz2, true);
  return Status::Ok();
}

Status SplatExporter::AddTextures(const TexturePool& t, size_t n, json& attributes, json& khr_extensions) {
  std::vector<uint8_t> layout(n * 4);  // [N][4]: height, width, axis_u, axis_v
  for (size_t i = 0; i < n; ++i) {
    layout[i * 4 + 0] = t.heights[i];
    layout[i * 4 + 1] = t.widths[i];
    layout[i * 4 + 2] = t.axis_u[i];
    layout[i * 4 + 3] = t.axis_v[i];
  }
  ATEX_ASSIGN_OR_RETURN(int layout_view, writer_.AddView({layout.data(), n, 4, true, MeshoptFilter::kNone}));
  attributes[gltf::kAttrTextureLayout] =
      writer_.AddAccessor(layout_view, 0, gltf::kComponentUnsignedByte, false, n, "VEC4");

  const size_t texels = t.texel_count();
  ATEX_ASSIGN_OR_RETURN(int texel_accessor, FloatAccessor(t.texels, texels, 4, "VEC4", false, lossy(), false));
  khr_extensions[gltf::kAtexTextures] = {
      {"texels", texel_accessor}, {"colorScale", gltf::kTextureColorScale}, {"alphaScale", gltf::kTextureAlphaScale}};
  writer_.UseExtension(gltf::kAtexTextures, false);
  return Status::Ok();
}

StatusOr<json> SplatExporter::AddLinear(const Linear& layer, const std::string& where) {
  if (layer.weight.size() != size_t(layer.in) * layer.out || layer.bias.size() != size_t(layer.out) || layer.out <= 0 ||
      layer.in <= 0) {
    return MakeError(StatusCode::kInvalidArgument, where, " has inconsistent shapes (", layer.out, "x", layer.in, ")");
  }
  ATEX_ASSIGN_OR_RETURN(int weight,
                        FloatAccessor(layer.weight, layer.weight.size(), 1, "SCALAR", false, lossy(), false));
  ATEX_ASSIGN_OR_RETURN(int bias, FloatAccessor(layer.bias, layer.bias.size(), 1, "SCALAR", false, lossy(), false));
  return json{{"weight", weight}, {"bias", bias}};
}

Status SplatExporter::AddDeformation(const Gaussians& g, const DeformationField* field, json& attributes,
                                     json& khr_extensions) {
  const size_t n = g.size();
  json ext = json::object();
  if (options_.raw_parameters && !options_.spz && !options_.quantize) {
    std::vector<float> raw_rotation(n * 4);  // [N][4] (x, y, z, w), unnormalised, bit-exact
    for (size_t i = 0; i < n; ++i) {
      raw_rotation[i * 4 + 0] = g.rotations[i * 4 + 1];
      raw_rotation[i * 4 + 1] = g.rotations[i * 4 + 2];
      raw_rotation[i * 4 + 2] = g.rotations[i * 4 + 3];
      raw_rotation[i * 4 + 3] = g.rotations[i * 4 + 0];
    }
    ATEX_ASSIGN_OR_RETURN(int rot, FloatAccessor(raw_rotation, n, 4, "VEC4", true, false, false));
    ATEX_ASSIGN_OR_RETURN(int scale, FloatAccessor(g.log_scales, n, 3, "VEC3", true, false, false));
    ATEX_ASSIGN_OR_RETURN(int logit, FloatAccessor(g.opacity_logits, n, 1, "SCALAR", true, false, false));
    attributes[gltf::kAttrRawRotation] = rot;
    attributes[gltf::kAttrRawLogScale] = scale;
    attributes[gltf::kAttrRawLogit] = logit;
  }
  if (field != nullptr) {
    const DeformationConfig& c = field->config;
    json grid = {
        {"channels", c.grid.channels}, {"baseResolution", c.grid.base_resolution}, {"multires", c.grid.multires}};
    json planes = json::array();
    for (size_t s = 0; s < field->planes.size(); ++s) {
      json scale_planes = json::array();
      for (int p = 0; p < kNumHexPlanes; ++p) {
        const std::vector<float>& plane = field->planes[s][p];
        ATEX_ASSIGN_OR_RETURN(int accessor, FloatAccessor(plane, plane.size(), 1, "SCALAR", false, lossy(), false));
        scale_planes.push_back(accessor);
      }
      planes.push_back(scale_planes);
    }
    grid["planes"] = planes;
    json trunk = json::array();
    for (size_t l = 0; l < field->trunk.size(); ++l) {
      ATEX_ASSIGN_OR_RETURN(json layer, AddLinear(field->trunk[l], StrCat("trunk layer ", l)));
      trunk.push_back(layer);
    }
    json heads = json::object();
    for (int h = 0; h < kNumDeformHeads; ++h) {
      if (!c.heads[h]) continue;
      json layers = json::array();
      for (int k = 0; k < 2; ++k) {
        ATEX_ASSIGN_OR_RETURN(json layer,
                              AddLinear(field->heads[h][k], StrCat(gltf::kHeadNames[h], " head layer ", k)));
        layers.push_back(layer);
      }
      heads[gltf::kHeadNames[h]] = layers;
    }
    auto vec3 = [](const std::array<float, 3>& v) {
      return json::array({gltf::FloatJson(v[0]), gltf::FloatJson(v[1]), gltf::FloatJson(v[2])});
    };
    ext["field"] = {{"aabbLo", vec3(c.aabb_lo)},
                    {"aabbHi", vec3(c.aabb_hi)},
                    {"timeScale", gltf::FloatJson(c.time_scale)},
                    {"timeOffset", gltf::FloatJson(c.time_offset)},
                    {"grid", grid},
                    {"mlpWidth", c.mlp_width},
                    {"trunk", trunk},
                    {"heads", heads},
                    {"shCoefficients", c.sh_coeffs}};
  }
  if ((!options_.raw_parameters || options_.spz || options_.quantize) && field == nullptr) return Status::Ok();
  khr_extensions[gltf::kAtexDeformation] = ext;
  writer_.UseExtension(gltf::kAtexDeformation, false);
  return Status::Ok();
}

Status SplatExporter::Build(const Asset& asset) {
  ATEX_RETURN_IF_ERROR(ValidateAsset(asset));
  const size_t n = asset.gaussians.size();
  if (n == 0)
    return MakeError(StatusCode::kInvalidArgument,
                     "glTF export: the asset has no Gaussians (glTF accessors need count >= 1)");
  if (n > UINT32_MAX) return MakeError(StatusCode::kLimitExceeded, "glTF export: ", n, " Gaussians exceed 2^32");
  if (options_.spz && options_.meshopt) {
    return MakeError(StatusCode::kInvalidArgument,
                     "glTF export: SPZ compression and EXT_meshopt_compression exclude "
                     "each other (the SPZ stream is already compressed); choose one");
  }
  if (options_.spz && options_.quantize) {
    return MakeError(StatusCode::kInvalidArgument,
                     "glTF export: SPZ compression and quantised accessors exclude each other (the SPZ stream "
                     "replaces the accessors' data); choose one");
  }
  if (options_.meshopt && !gltf::MeshoptAvailable()) {
    return MakeError(StatusCode::kUnsupported, "EXT_meshopt_compression needs meshoptimizer, which this build lacks");
  }
  UpAxis up = UpAxis::kPosY;
  if (options_.up) {
    up = *options_.up;
  } else {
    ATEX_ASSIGN_OR_RETURN(up, UpAxisOf(asset.metadata));
  }
  ATEX_RETURN_IF_ERROR(Progress(0.0));

  if (!options_.time && asset.gaussians.has_time_windows()) {
    // The base attributes would be the canonical Gaussians, which a player draws at every time, and
    // the deformation extension has no place for the windows.
    return MakeError(StatusCode::kUnsupported,
                     "glTF export: the asset has time-local Gaussians (GTWN), which glTF cannot carry; export "
                     "one time with --time T (or a sequence with --frames)");
  }
  // The Gaussians the base shows: canonical, or deformed to the requested time.
  const Gaussians* shown = &asset.gaussians;
  Gaussians deformed;
  if (options_.time) {
    if (!std::isfinite(*options_.time)) return MakeError(StatusCode::kOutOfRange, "glTF export: time is not finite");
    if (!asset.deformation)
      return MakeError(StatusCode::kInvalidArgument, "glTF export: --time needs an asset with a deformation field");
    if (options_.deform) {
      ATEX_RETURN_IF_ERROR(options_.deform(asset, *options_.time, &deformed));
    } else {
      ATEX_RETURN_IF_ERROR(DeformForward(*asset.deformation, asset.gaussians, *options_.time, &deformed, nullptr));
    }
    if (deformed.size() != n)
      return MakeError(StatusCode::kInternal, "deformation returned ", deformed.size(), " Gaussians, expected ", n);
    shown = &deformed;
  }
  Gaussians baked;
  const bool bake = options_.bake_textures && asset.textures.has_value();
  if (bake) {
    ATEX_ASSIGN_OR_RETURN(baked, BakeTextures(*shown, *asset.textures, options_.bake, options_.bake_report));
    if (baked.size() > UINT32_MAX)
      return MakeError(StatusCode::kLimitExceeded, "glTF export: ", baked.size(), " baked Gaussians exceed 2^32");
    shown = &baked;
  }
  ATEX_RETURN_IF_ERROR(Progress(0.2));

  json attributes = json::object();
  json khr_extensions = json::object();
  if (options_.spz) {
    ATEX_RETURN_IF_ERROR(AddBaseSpz(*shown, attributes, khr_extensions));
  } else {
    ATEX_RETURN_IF_ERROR(AddBase(*shown, attributes));
  }
  ATEX_RETURN_IF_ERROR(Progress(0.6));
  if (options_.textures && asset.textures && !bake)
    ATEX_RETURN_IF_ERROR(AddTextures(*asset.textures, n, attributes, khr_extensions));
  const DeformationField* field =
      (options_.deformation && !options_.time && asset.deformation) ? &*asset.deformation : nullptr;
  ATEX_RETURN_IF_ERROR(AddDeformation(*shown, field, attributes, khr_extensions));
  ATEX_RETURN_IF_ERROR(Progress(0.9));

  json khr = {{"kernel", "ellipse"},
              {"colorSpace", "srgb_rec709_display"},
              {"projection", "perspective"},
              {"sortingMethod", "cameraDistance"}};
  if (!khr_extensions.empty()) khr["extensions"] = khr_extensions;
  json primitive = {
      {"mode", gltf::kModePoints}, {"attributes", attributes}, {"extensions", {{gltf::kKhrGaussianSplatting, khr}}}};
  writer_.UseExtension(gltf::kKhrGaussianSplatting, false);

  json& doc = writer_.doc();
  doc["asset"] = {{"version", "2.0"}, {"generator", std::string("atex ") + kVersion}};
  doc["meshes"] = json::array({{{"name", "gaussians"}, {"primitives", json::array({primitive})}}});
  json node = {{"name", "atex"}, {"mesh", 0}};
  const std::array<double, 4> rotation = GltfRootRotation(up);
  if (rotation != std::array<double, 4>{0, 0, 0, 1}) node["rotation"] = rotation;
  if (options_.quantize) {
    // node = T * R * S: world = R * (center + s * q), so T = R * center (R's entries are 0 and +-1: exact).
    const std::array<double, 9> r = UpRotationMatrix(up);
    const auto& c = position_frame_.center;
    json translation = json::array();
    for (int row = 0; row < 3; ++row)
      translation.push_back(float(r[row * 3] * c[0] + r[row * 3 + 1] * c[1] + r[row * 3 + 2] * c[2]));
    node["translation"] = translation;
    const double s = position_frame_.scale;
    node["scale"] = json::array({s, s, s});
  }
  doc["nodes"] = json::array({node});
  doc["scenes"] = json::array({{{"nodes", json::array({0})}}});
  doc["scene"] = 0;
  Metadata metadata = asset.metadata;
  // No texture extension written (baked into the Gaussians, or left out): the metadata must not
  // promise one, or our importer refuses the file.
  if (bake || !options_.textures) metadata.texture_mode = "none";
  json atex = {{"version", gltf::kAtexGltfVersion}, {"metadata", MetadataToJson(metadata)}};
  if (options_.time) atex["bakedTime"] = *options_.time;
  if (bake) atex["bakedTextures"] = {{"sourceGaussians", n}, {"gaussians", shown->size()}};
  if (options_.up) {
    static const char* kUpNames[] = {"+y", "-y", "+z", "-z"};
    atex["up"] = kUpNames[static_cast<int>(up)];
  }
  doc["extras"] = {{"atex", atex}};
  return Status::Ok();
}

}  // namespace

StatusOr<std::vector<uint8_t>> EncodeGlb(const Asset& asset, const GltfExportOptions& options) {
  try {
    SplatExporter exporter(options);
    ATEX_RETURN_IF_ERROR(exporter.Build(asset));
    return exporter.writer().FinishGlb();
  } catch (const std::bad_alloc&) {
    return MakeError(StatusCode::kLimitExceeded, "glTF export: out of memory");
  } catch (const std::exception& e) {
    return MakeError(StatusCode::kInternal, "glTF export: ", e.what());
  }
}

StatusOr<GltfTextFiles> EncodeGltfText(const Asset& asset, const std::string& bin_uri,
                                       const GltfExportOptions& options) {
  try {
    SplatExporter exporter(options);
    ATEX_RETURN_IF_ERROR(exporter.Build(asset));
    return exporter.writer().FinishText(bin_uri);
  } catch (const std::bad_alloc&) {
    return MakeError(StatusCode::kLimitExceeded, "glTF export: out of memory");
  } catch (const std::exception& e) {
    return MakeError(StatusCode::kInternal, "glTF export: ", e.what());
  }
}

Status WriteGltfFile(const std::string& path, const Asset& asset, const GltfExportOptions& options) {
  const std::filesystem::path p(path);
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  if (ext == ".glb") {
    ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, EncodeGlb(asset, options));
    return WriteFileAtomic(path, bytes);
  }
  if (ext == ".gltf") {
    const std::string bin_name = p.stem().string() + ".bin";
    ATEX_ASSIGN_OR_RETURN(GltfTextFiles files, EncodeGltfText(asset, gltf::PercentEncode(bin_name), options));
    ATEX_RETURN_IF_ERROR(WriteFileAtomic((p.parent_path() / bin_name).string(), files.bin));
    return WriteFileAtomic(path, files.json.data(), files.json.size());
  }
  return MakeError(StatusCode::kInvalidArgument, "glTF export: '", path, "' does not end in .glb or .gltf");
}

}  // namespace atex
