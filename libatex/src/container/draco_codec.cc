#include "container/draco_codec.h"

#include <cstring>
#include <memory>

#include "container/byte_io.h"

#ifdef ATEX_HAVE_DRACO
#include <draco/compression/config/compression_shared.h>
#include <draco/compression/decode.h>
#include <draco/compression/encode.h>
#include <draco/point_cloud/point_cloud_builder.h>
#endif

namespace atex::container {

#ifdef ATEX_HAVE_DRACO

bool HaveDraco() { return true; }

StatusOr<std::vector<uint8_t>> DracoEncodePositions(const float* xyz, size_t n, int bits) {
  if (bits < 1 || bits > 30)
    return MakeError(StatusCode::kInvalidArgument, "Draco position bits ", bits, " outside 1..30");
  if (n == 0 || n > 0x7FFFFFFFu)
    return MakeError(StatusCode::kInvalidArgument, "Draco needs 1..2^31-1 points, got ", n);
  try {
    draco::PointCloudBuilder builder;
    builder.Start(static_cast<draco::PointIndex::ValueType>(n));
    const int attribute = builder.AddAttribute(draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32);
    builder.SetAttributeValuesForAllPoints(attribute, xyz, 3 * sizeof(float));
    std::unique_ptr<draco::PointCloud> cloud = builder.Finalize(false);
    if (!cloud) return MakeError(StatusCode::kInternal, "Draco point cloud builder failed");
    draco::Encoder encoder;
    encoder.SetAttributeQuantization(draco::GeometryAttribute::POSITION, bits);
    encoder.SetEncodingMethod(draco::POINT_CLOUD_SEQUENTIAL_ENCODING);  // keeps the Gaussian order
    draco::EncoderBuffer buffer;
    const draco::Status status = encoder.EncodePointCloudToBuffer(*cloud, &buffer);
    if (!status.ok()) return MakeError(StatusCode::kInternal, "Draco encoding failed: ", status.error_msg());
    return std::vector<uint8_t>(buffer.data(), buffer.data() + buffer.size());
  } catch (const std::bad_alloc&) {
    return MakeError(StatusCode::kLimitExceeded, "out of memory in Draco encoding of ", n, " points");
  }
}

Status DracoDecodePositions(const uint8_t* data, size_t size, uint64_t expected_points, std::vector<uint8_t>* out) {
  // Draco 2.2 header: "DRACO", major, minor, encoder type (0 point cloud),
  // method (0 sequential), u16 flags; the sequential point cloud then states its
  // point count as an int32. Checking it here keeps a forged count away from
  // Draco's allocations.
  constexpr size_t kHeader = 11;
  if (size < kHeader + 4 || std::memcmp(data, "DRACO", 5) != 0) {
    return MakeError(StatusCode::kCorrupt, "Draco bitstream has no Draco header");
  }
  if (data[7] != 0 || data[8] != 0) {
    return MakeError(StatusCode::kCorrupt, "Draco bitstream is not a sequential point cloud (type ", int{data[7]},
                     ", method ", int{data[8]}, ")");
  }
  if (LoadLE<uint16_t>(data + 9) != 0) return MakeError(StatusCode::kCorrupt, "Draco bitstream has flags/metadata");
  const int32_t points = LoadLE<int32_t>(data + kHeader);
  if (points < 0 || static_cast<uint64_t>(points) != expected_points) {
    return MakeError(StatusCode::kCorrupt, "Draco bitstream holds ", points, " points, expected ", expected_points);
  }
  try {
    draco::DecoderBuffer buffer;
    buffer.Init(reinterpret_cast<const char*>(data), size);
    draco::Decoder decoder;
    auto decoded = decoder.DecodePointCloudFromBuffer(&buffer);
    if (!decoded.ok()) return MakeError(StatusCode::kCorrupt, "Draco decoding failed: ", decoded.status().error_msg());
    const std::unique_ptr<draco::PointCloud> cloud = std::move(decoded).value();
    if (cloud->num_points() != expected_points || cloud->num_attributes() != 1) {
      return MakeError(StatusCode::kCorrupt, "Draco point cloud has ", cloud->num_points(), " points and ",
                       cloud->num_attributes(), " attributes; expected ", expected_points, " and 1");
    }
    const draco::PointAttribute* position = cloud->attribute(0);
    if (position == nullptr || position->attribute_type() != draco::GeometryAttribute::POSITION ||
        position->num_components() != 3) {
      return MakeError(StatusCode::kCorrupt, "Draco attribute is not a 3-component POSITION");
    }
    const size_t at = out->size();
    out->resize(at + static_cast<size_t>(expected_points) * 12);
    for (uint32_t i = 0; i < expected_points; ++i) {
      float xyz[3];
      if (!position->ConvertValue<float, 3>(position->mapped_index(draco::PointIndex(i)), xyz)) {
        return MakeError(StatusCode::kCorrupt, "Draco position of point ", i, " cannot be read");
      }
      for (int k = 0; k < 3; ++k) StoreLE<float>(out->data() + at + (size_t{i} * 3 + k) * 4, xyz[k]);
    }
    return Status::Ok();
  } catch (const std::bad_alloc&) {
    return MakeError(StatusCode::kLimitExceeded, "out of memory in Draco decoding of ", expected_points, " points");
  }
}

#else  // !ATEX_HAVE_DRACO

bool HaveDraco() { return false; }

StatusOr<std::vector<uint8_t>> DracoEncodePositions(const float*, size_t, int) {
  return MakeError(StatusCode::kUnsupportedCodec, "this build has no Draco (codec 4)");
}

Status DracoDecodePositions(const uint8_t*, size_t, uint64_t, std::vector<uint8_t>*) {
  return MakeError(StatusCode::kUnsupportedCodec, "this build has no Draco (codec 4)");
}

#endif

}  // namespace atex::container
