// Public SPZ API: axis handling around the container and quantisation layers.
#include "atex/converters/spz.h"

#include "atex/file_io.h"
#include "spz/spz_container.h"
#include "spz/spz_packed.h"

namespace atex {

namespace {

// libatex's world (RDF) <-> the spec's storage convention (RUB).
const converters::spz::AxisFlip kRubRdf{{1.0f, -1.0f, -1.0f}};

}  // namespace

StatusOr<Gaussians> DecodeSpz(const uint8_t* data, size_t size, const SpzReadOptions& options, SpzInfo* info) {
  using namespace converters::spz;
  ATEX_ASSIGN_OR_RETURN(ParsedSpz parsed, ParseSpzContainer(data, size, options));
  AxisFlip flip;  // identity: kStored
  if (options.axes == SpzAxes::kOpenCv) {
    auto to_rdf = FlipToRdf(parsed.coordinate_system);
    if (!to_rdf) {
      return MakeError(StatusCode::kUnsupported, "SPZ: data stored in coordinate system ",
                       CoordinateSystemName(parsed.coordinate_system),
                       ", which is a rotation away from RDF; read it with axes 'stored'");
    }
    flip = *to_rdf;
  }
  if (info != nullptr) {
    const PackedSpz& p = parsed.packed;
    info->version = p.version;
    info->num_points = p.num_points;
    info->sh_degree = p.sh_degree;
    info->fractional_bits = p.fractional_bits;
    info->antialiased = (p.flags & kFlagAntialiased) != 0;
    info->extension_records = parsed.extension_records;
    info->stored_axes = CoordinateSystemName(parsed.coordinate_system == 0 ? 4 : parsed.coordinate_system);
    info->sh_truncated = p.sh_degree > kMaxShDegree;
  }
  return UnpackGaussians(parsed.packed, flip);
}

StatusOr<Gaussians> ReadSpzGaussians(const std::string& path, const SpzReadOptions& options, SpzInfo* info) {
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, ReadFileBytes(path));
  auto result = DecodeSpz(bytes.data(), bytes.size(), options, info);
  if (!result.ok()) return result.status().WithContext(path);
  return result;
}

StatusOr<std::vector<uint8_t>> EncodeSpz(const Gaussians& g, const SpzWriteOptions& options) {
  using namespace converters::spz;
  const AxisFlip flip = options.axes == SpzAxes::kOpenCv ? kRubRdf : AxisFlip{};
  ATEX_ASSIGN_OR_RETURN(PackedSpz packed, PackGaussians(g, options, flip));
  return SerializeSpz(packed, options);
}

Status WriteSpzGaussians(const std::string& path, const Gaussians& g, const SpzWriteOptions& options) {
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, EncodeSpz(g, options));
  return WriteFileAtomic(path, bytes).WithContext(path);
}

}  // namespace atex
