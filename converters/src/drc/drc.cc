// Draco point-cloud export/import of Gaussian centres and attributes.
#include "atex/converters/drc.h"

#include <algorithm>
#include <cmath>
#include <exception>

#include "atex/file_io.h"
#include "convert/gaussian_checks.h"

#ifdef ATEX_HAVE_DRACO
#include <draco/compression/decode.h>
#include <draco/compression/expert_encode.h>
#include <draco/metadata/geometry_metadata.h>
#include <draco/point_cloud/point_cloud_builder.h>
#endif

namespace atex {

#ifdef ATEX_HAVE_DRACO

namespace {

constexpr float kShC0 = 0.28209479177387814f;

std::unique_ptr<draco::AttributeMetadata> NameMetadata(const char* name) {
  auto metadata = std::make_unique<draco::AttributeMetadata>();
  metadata->AddEntryString("name", name);
  return metadata;
}

// Copies attribute values of every point into `out` ([N][components]).
template <typename T, int kComponents>
bool ReadAttribute(const draco::PointCloud& pc, const draco::PointAttribute& att, std::vector<T>* out) {
  if (att.num_components() != kComponents) return false;
  const size_t n = pc.num_points();
  out->resize(n * kComponents);
  for (draco::PointIndex i(0); i < static_cast<uint32_t>(n); ++i) {
    if (!att.ConvertValue<T, kComponents>(att.mapped_index(i), out->data() + size_t{i.value()} * kComponents)) {
      return false;
    }
  }
  return true;
}

}  // namespace

StatusOr<std::vector<uint8_t>> EncodeDracoPointCloud(const Gaussians& g, const DracoExportOptions& options) {
  ATEX_RETURN_IF_ERROR(converters::CheckGaussianShapes(g, "Draco writer"));
  ATEX_RETURN_IF_ERROR(converters::CheckGaussiansFinite(g, "Draco writer"));
  if (options.position_bits < 1 || options.position_bits > 30 || options.attribute_bits < 1 ||
      options.attribute_bits > 30) {
    return MakeError(StatusCode::kInvalidArgument, "Draco writer: quantisation bits ", options.position_bits, "/",
                     options.attribute_bits, " outside 1..30");
  }
  const size_t n = g.size();
  if (n == 0 || n > 0x7fffffffu) {
    return MakeError(StatusCode::kInvalidArgument, "Draco writer: ", n, " points (Draco needs 1..2^31-1)");
  }
  try {
    draco::PointCloudBuilder builder;
    builder.Start(static_cast<uint32_t>(n));
    const int pos = builder.AddAttribute(draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32);
    builder.SetAttributeValuesForAllPoints(pos, g.positions.data(), 3 * sizeof(float));
    std::vector<std::pair<int, int>> quantised = {{pos, options.position_bits}};  // (attribute id, bits)
    std::vector<std::pair<int, const char*>> names;
    if (options.colors) {
      std::vector<uint8_t> rgb(n * 3);  // [N][3]
      const size_t stride = static_cast<size_t>(g.sh_coeffs()) * 3;
      for (size_t i = 0; i < n; ++i) {
        for (int c = 0; c < 3; ++c) {
          const float v = std::clamp(0.5f + kShC0 * g.sh[i * stride + c], 0.0f, 1.0f);
          rgb[i * 3 + c] = static_cast<uint8_t>(std::lround(v * 255.0f));
        }
      }
      const int att = builder.AddAttribute(draco::GeometryAttribute::COLOR, 3, draco::DT_UINT8);
      builder.SetAttributeValuesForAllPoints(att, rgb.data(), 3);
      names.emplace_back(att, "color");
    }
    if (options.opacity) {
      std::vector<float> alpha(n);  // [N]
      for (size_t i = 0; i < n; ++i) alpha[i] = 1.0f / (1.0f + std::exp(-g.opacity_logits[i]));
      const int att = builder.AddAttribute(draco::GeometryAttribute::GENERIC, 1, draco::DT_FLOAT32);
      builder.SetAttributeValuesForAllPoints(att, alpha.data(), sizeof(float));
      quantised.emplace_back(att, options.attribute_bits);
      names.emplace_back(att, "opacity");
    }
    if (options.scales) {
      const int att = builder.AddAttribute(draco::GeometryAttribute::GENERIC, 3, draco::DT_FLOAT32);
      builder.SetAttributeValuesForAllPoints(att, g.log_scales.data(), 3 * sizeof(float));
      quantised.emplace_back(att, options.attribute_bits);
      names.emplace_back(att, "log_scale");
    }
    if (options.rotations) {
      std::vector<float> q(n * 4);  // [N][4] unit (w, x, y, z)
      for (size_t i = 0; i < n; ++i) {
        const float* r = &g.rotations[i * 4];
        const float norm = std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2] + r[3] * r[3]);
        for (int k = 0; k < 4; ++k) q[i * 4 + k] = norm > 0 ? r[k] / norm : (k == 0 ? 1.0f : 0.0f);
      }
      const int att = builder.AddAttribute(draco::GeometryAttribute::GENERIC, 4, draco::DT_FLOAT32);
      builder.SetAttributeValuesForAllPoints(att, q.data(), 4 * sizeof(float));
      quantised.emplace_back(att, options.attribute_bits);
      names.emplace_back(att, "rotation");
    }
    for (const auto& [att, name] : names) builder.AddAttributeMetadata(att, NameMetadata(name));
    std::unique_ptr<draco::PointCloud> pc = builder.Finalize(/*deduplicate_points=*/false);
    if (!pc) return MakeError(StatusCode::kInternal, "Draco writer: PointCloudBuilder failed");

    draco::ExpertEncoder encoder(*pc);
    for (const auto& [att, bits] : quantised) encoder.SetAttributeQuantization(att, bits);
    encoder.SetSpeedOptions(std::clamp(options.encoding_speed, 0, 10), std::clamp(options.decoding_speed, 0, 10));
    encoder.SetEncodingMethod(options.kd_tree ? draco::POINT_CLOUD_KD_TREE_ENCODING
                                              : draco::POINT_CLOUD_SEQUENTIAL_ENCODING);
    draco::EncoderBuffer buffer;
    const draco::Status status = encoder.EncodeToBuffer(&buffer);
    if (!status.ok()) {
      return MakeError(StatusCode::kInternal, "Draco writer: encoding failed: ", status.error_msg_string());
    }
    return std::vector<uint8_t>(buffer.data(), buffer.data() + buffer.size());
  } catch (const std::exception& e) {
    return MakeError(StatusCode::kInternal, "Draco writer: ", e.what());
  }
}

StatusOr<DracoPointCloud> DecodeDracoPointCloud(const uint8_t* data, size_t size) {
  try {
    draco::DecoderBuffer buffer;
    buffer.Init(reinterpret_cast<const char*>(data), size);
    auto geometry = draco::Decoder::GetEncodedGeometryType(&buffer);
    if (!geometry.ok() || geometry.value() != draco::POINT_CLOUD) {
      return MakeError(StatusCode::kBadMagic, "not a Draco point cloud",
                       geometry.ok() ? " (it holds a mesh)" : "");
    }
    draco::Decoder decoder;
    auto decoded = decoder.DecodePointCloudFromBuffer(&buffer);
    if (!decoded.ok()) {
      return MakeError(StatusCode::kCorrupt, "Draco: ", decoded.status().error_msg_string());
    }
    const draco::PointCloud& pc = *decoded.value();
    DracoPointCloud out;
    const draco::PointAttribute* pos = pc.GetNamedAttribute(draco::GeometryAttribute::POSITION);
    if (pos == nullptr || !ReadAttribute<float, 3>(pc, *pos, &out.positions)) {
      return MakeError(StatusCode::kCorrupt, "Draco point cloud has no 3-component POSITION attribute");
    }
    for (int a = 0; a < pc.num_attributes(); ++a) {
      const draco::PointAttribute& att = *pc.attribute(a);
      std::string name;
      const draco::AttributeMetadata* metadata = pc.GetAttributeMetadataByAttributeId(a);
      if (metadata != nullptr) metadata->GetEntryString("name", &name);
      bool ok = true;
      if (att.attribute_type() == draco::GeometryAttribute::COLOR) {
        ok = ReadAttribute<uint8_t, 3>(pc, att, &out.colors);
      } else if (name == "opacity") {
        ok = ReadAttribute<float, 1>(pc, att, &out.opacity);
      } else if (name == "log_scale") {
        ok = ReadAttribute<float, 3>(pc, att, &out.log_scales);
      } else if (name == "rotation") {
        ok = ReadAttribute<float, 4>(pc, att, &out.rotations);
      }
      if (!ok) return MakeError(StatusCode::kCorrupt, "Draco attribute ", a, " ('", name, "') has an unexpected shape");
    }
    return out;
  } catch (const std::exception& e) {
    return MakeError(StatusCode::kCorrupt, "Draco: ", e.what());
  }
}

#else  // no Draco in this build

StatusOr<std::vector<uint8_t>> EncodeDracoPointCloud(const Gaussians&, const DracoExportOptions&) {
  return MakeError(StatusCode::kUnsupportedCodec, "Draco export needs libdraco, which this build does not include");
}

StatusOr<DracoPointCloud> DecodeDracoPointCloud(const uint8_t*, size_t) {
  return MakeError(StatusCode::kUnsupportedCodec, "Draco import needs libdraco, which this build does not include");
}

#endif

Status WriteDracoPointCloud(const std::string& path, const Gaussians& g, const DracoExportOptions& options) {
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, EncodeDracoPointCloud(g, options));
  return WriteFileAtomic(path, bytes).WithContext(path);
}

}  // namespace atex
