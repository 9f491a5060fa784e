// PlayCanvas SOG (version 2) reading (see atex/converters/web_splats.h).
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>

#include <nlohmann/json.hpp>

#include "atex/converters/web_splats.h"
#include "atex/file_io.h"
#include "atex/zip.h"

#ifdef ATEX_HAVE_WEBP
#include <webp/decode.h>
#endif

namespace atex {
namespace {

using nlohmann::json;
// Loads a named image of the bundle (from the folder of meta.json or the zip).
using LoadFn = std::function<StatusOr<std::vector<uint8_t>>(const std::string& name)>;

struct Image {
  int width = 0, height = 0;
  std::vector<uint8_t> rgba;  // [height][width][4]
};

// Decodes one WebP after checking its declared size: at least `min_pixels` and
// at most `max_pixels`, so a forged header cannot ask for a huge allocation.
StatusOr<Image> DecodeWebp(const std::vector<uint8_t>& bytes, const std::string& name, uint64_t min_pixels,
                           uint64_t max_pixels) {
#ifdef ATEX_HAVE_WEBP
  int w = 0, h = 0;
  if (!WebPGetInfo(bytes.data(), bytes.size(), &w, &h)) {
    return MakeError(StatusCode::kCorrupt, "SOG image '", name, "' (", bytes.size(), " bytes) is not a WebP image");
  }
  const uint64_t pixels = uint64_t(w) * uint64_t(h);
  if (pixels < min_pixels || pixels > max_pixels) {
    return MakeError(StatusCode::kCorrupt, "SOG image '", name, "' is ", w, "x", h, " = ", pixels,
                     " pixels; it must have ", min_pixels, " to ", max_pixels, " for this file's counts");
  }
  std::unique_ptr<uint8_t, void (*)(void*)> decoded(WebPDecodeRGBA(bytes.data(), bytes.size(), &w, &h), WebPFree);
  if (!decoded) return MakeError(StatusCode::kCorrupt, "SOG image '", name, "': the WebP data does not decode");
  Image image;
  image.width = w, image.height = h;
  image.rgba.assign(decoded.get(), decoded.get() + size_t(pixels) * 4);
  return image;
#else
  (void)bytes, (void)min_pixels, (void)max_pixels;
  return MakeError(StatusCode::kUnsupported, "SOG image '", name, "': this build has no WebP decoder (libwebp-dev)");
#endif
}

StatusOr<const json*> Member(const json& object, const char* key, const char* where) {
  if (!object.is_object() || !object.contains(key)) {
    return MakeError(StatusCode::kCorrupt, "SOG meta.json: '", where, "' lacks '", key, "'");
  }
  return &object[key];
}

// An array of `n` finite numbers at object[key].
StatusOr<std::vector<double>> Numbers(const json& object, const char* key, const char* where, size_t n) {
  ATEX_ASSIGN_OR_RETURN(const json* value, Member(object, key, where));
  if (!value->is_array() || value->size() != n) {
    return MakeError(StatusCode::kCorrupt, "SOG meta.json: '", where, ".", key, "' is not an array of ", n, " numbers");
  }
  std::vector<double> out(n);
  for (size_t i = 0; i < n; ++i) {
    if (!(*value)[i].is_number() || !std::isfinite((*value)[i].get<double>())) {
      return MakeError(StatusCode::kCorrupt, "SOG meta.json: '", where, ".", key, "[", i, "]' is not a finite number");
    }
    out[i] = (*value)[i].get<double>();
  }
  return out;
}

StatusOr<std::string> FileName(const json& object, const char* where, size_t index) {
  ATEX_ASSIGN_OR_RETURN(const json* files, Member(object, "files", where));
  if (!files->is_array() || files->size() <= index || !(*files)[index].is_string()) {
    return MakeError(StatusCode::kCorrupt, "SOG meta.json: '", where, ".files' lacks image ", index);
  }
  return (*files)[index].get<std::string>();
}

double InverseLogTransform(double v) {
  const double e = std::exp(std::fabs(v)) - 1;
  return v < 0 ? -e : e;
}

// meta.json as a JSON object of SOG version 2.
StatusOr<json> ParseMeta(const std::vector<uint8_t>& meta_bytes) {
  json meta;
  try {
    meta = json::parse(meta_bytes.begin(), meta_bytes.end());
  } catch (const std::exception& e) {
    return MakeError(StatusCode::kCorrupt, "SOG meta.json is not JSON: ", e.what());
  }
  if (!meta.is_object()) return MakeError(StatusCode::kCorrupt, "SOG meta.json is not a JSON object");
  if (!meta.contains("version") || meta["version"] != 2) {
    return MakeError(StatusCode::kUnsupported, "SOG meta.json: version ",
                     meta.contains("version") ? meta["version"].dump() : std::string("absent (SOG v1)"),
                     "; only version 2 is read");
  }
  return meta;
}

// What meta.json says about each attribute: its section (which names the images) and its
// codebook or range. The sections point into the meta.json object.
struct SogLayout {
  uint64_t n = 0;  // Gaussians
  const json* means = nullptr;
  std::vector<double> mins, maxs;  // [3] each, in the log-transformed space
  const json* scales = nullptr;
  std::vector<double> scale_book;  // [256] log-scales
  const json* quats = nullptr;
  const json* sh0 = nullptr;
  std::vector<double> sh0_book;  // [256] DC coefficients
  const json* shn = nullptr;     // null without view-dependent colour
  int sh_degree = 0;
  uint64_t palette = 0;          // shN centroids
  std::vector<double> shn_book;  // [256] coefficients of the centroids
};

StatusOr<SogLayout> ReadLayout(json& meta, const WebSplatLimits& limits) {
  if (!meta.contains("count") || !meta["count"].is_number_unsigned()) {
    return MakeError(StatusCode::kCorrupt, "SOG meta.json: 'count' is not a non-negative integer");
  }
  SogLayout l;
  l.n = meta["count"].get<uint64_t>();
  if (l.n > limits.max_gaussians) {
    return MakeError(StatusCode::kLimitExceeded, "SOG: ", l.n, " Gaussians exceed the limit of ", limits.max_gaussians);
  }
  ATEX_ASSIGN_OR_RETURN(l.means, Member(meta, "means", "meta"));
  ATEX_ASSIGN_OR_RETURN(l.mins, Numbers(*l.means, "mins", "means", 3));
  ATEX_ASSIGN_OR_RETURN(l.maxs, Numbers(*l.means, "maxs", "means", 3));
  ATEX_ASSIGN_OR_RETURN(l.scales, Member(meta, "scales", "meta"));
  ATEX_ASSIGN_OR_RETURN(l.scale_book, Numbers(*l.scales, "codebook", "scales", 256));
  ATEX_ASSIGN_OR_RETURN(l.quats, Member(meta, "quats", "meta"));
  ATEX_ASSIGN_OR_RETURN(l.sh0, Member(meta, "sh0", "meta"));
  ATEX_ASSIGN_OR_RETURN(l.sh0_book, Numbers(*l.sh0, "codebook", "sh0", 256));

  l.shn = meta.contains("shN") ? &meta["shN"] : nullptr;
  if (l.shn != nullptr) {
    ATEX_ASSIGN_OR_RETURN(const json* bands, Member(*l.shn, "bands", "shN"));
    ATEX_ASSIGN_OR_RETURN(const json* count, Member(*l.shn, "count", "shN"));
    if (!bands->is_number_unsigned() || bands->get<uint64_t>() > 3) {
      return MakeError(StatusCode::kCorrupt, "SOG meta.json: 'shN.bands' is not 0..3");
    }
    if (!count->is_number_unsigned() || count->get<uint64_t>() > 65536) {
      return MakeError(StatusCode::kCorrupt, "SOG meta.json: 'shN.count' is not 0..65536 (labels are 16 bits)");
    }
    l.sh_degree = int(bands->get<uint64_t>());
    l.palette = count->get<uint64_t>();
    ATEX_ASSIGN_OR_RETURN(l.shn_book, Numbers(*l.shn, "codebook", "shN", 256));
  }
  return l;
}

// The images of one SOG: each per-Gaussian image is checked to hold n to max_pixels pixels
// before it is decoded.
struct SogImages {
  const LoadFn& load;
  uint64_t n;
  uint64_t max_pixels;

  // Image `index` of `section` (named `where` in messages), at least `min_pixels` large.
  StatusOr<Image> Get(const json& section, const char* where, size_t index, uint64_t min_pixels) const {
    ATEX_ASSIGN_OR_RETURN(std::string name, FileName(section, where, index));
    ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, load(name));
    return DecodeWebp(bytes, name, min_pixels, max_pixels);
  }
  StatusOr<Image> PerGaussian(const json& section, const char* where, size_t index) const {
    return Get(section, where, index, n);
  }
};

// Positions: 16 bits per axis split over two images, in the range of a log transform. Allocates
// the Gaussians, after the images' declared sizes were checked against the count.
Status DecodePositions(const SogLayout& l, const SogImages& images, Gaussians* g) {
  ATEX_ASSIGN_OR_RETURN(Image lo, images.PerGaussian(*l.means, "means", 0));
  ATEX_ASSIGN_OR_RETURN(Image hi, images.PerGaussian(*l.means, "means", 1));
  g->Resize(size_t(l.n));
  const std::vector<double>& mins = l.mins;
  const std::vector<double>& maxs = l.maxs;
  for (size_t i = 0; i < l.n; ++i) {
    for (int k = 0; k < 3; ++k) {
      const unsigned q = lo.rgba[i * 4 + size_t(k)] | unsigned(hi.rgba[i * 4 + size_t(k)]) << 8;
      const double range = (maxs[size_t(k)] - mins[size_t(k)]) != 0 ? maxs[size_t(k)] - mins[size_t(k)] : 1.0;
      const double p = InverseLogTransform(mins[size_t(k)] + range * (q / 65535.0));
      if (!std::isfinite(float(p))) {
        return MakeError(StatusCode::kCorrupt, "SOG: Gaussian ", i, " position is not a finite float (means range)");
      }
      g->positions[i * 3 + size_t(k)] = float(p);
    }
  }
  return Status::Ok();
}

// Rotations: the three smaller components in RGB, the largest one's index tagged in alpha.
Status DecodeRotations(const SogLayout& l, const SogImages& images, Gaussians* g) {
  ATEX_ASSIGN_OR_RETURN(Image quat, images.PerGaussian(*l.quats, "quats", 0));
  static constexpr int kOrder[4][3] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};  // the three smaller ones
  for (size_t i = 0; i < l.n; ++i) {
    const uint8_t* px = &quat.rgba[i * 4];
    float* q = &g->rotations[i * 4];  // (w, x, y, z)
    if (px[3] < 252) {  // not a largest-component tag: the identity, as PlayCanvas reads it
      q[0] = 1, q[1] = q[2] = q[3] = 0;
      continue;
    }
    const int largest = px[3] - 252;
    double sum = 0;
    for (int k = 0; k < 3; ++k) {
      const double v = (px[k] / 255.0 * 2 - 1) / std::sqrt(2.0);
      q[kOrder[largest][k]] = float(v);
      sum += v * v;
    }
    q[largest] = float(std::sqrt(std::max(0.0, 1 - sum)));
  }
  return Status::Ok();
}

// Scales: a codebook index per axis.
Status DecodeScales(const SogLayout& l, const SogImages& images, Gaussians* g) {
  ATEX_ASSIGN_OR_RETURN(Image scale, images.PerGaussian(*l.scales, "scales", 0));
  for (size_t i = 0; i < l.n; ++i) {
    for (int k = 0; k < 3; ++k) g->log_scales[i * 3 + size_t(k)] = float(l.scale_book[scale.rgba[i * 4 + size_t(k)]]);
  }
  return Status::Ok();
}

// DC colour (a codebook index per channel) and opacity (alpha).
Status DecodeColours(const SogLayout& l, const SogImages& images, Gaussians* g) {
  const size_t k_count = size_t(g->sh_coeffs());
  ATEX_ASSIGN_OR_RETURN(Image colour, images.PerGaussian(*l.sh0, "sh0", 0));
  for (size_t i = 0; i < l.n; ++i) {
    for (int c = 0; c < 3; ++c) g->sh[i * k_count * 3 + size_t(c)] = float(l.sh0_book[colour.rgba[i * 4 + size_t(c)]]);
    // Opacity byte = sigmoid(logit) x 255, clamped as PlayCanvas does so that the logit stays finite.
    const double alpha = std::clamp(colour.rgba[i * 4 + 3] / 255.0, 1e-6, 1 - 1e-6);
    g->opacity_logits[i] = float(std::log(alpha / (1 - alpha)));
  }
  return Status::Ok();
}

// View-dependent colour: a palette of centroids (64 per row, every coefficient of one in a run of
// pixels) and a 16-bit label per Gaussian.
Status DecodeShRest(const SogLayout& l, const SogImages& images, Gaussians* g) {
  const size_t k_count = size_t(g->sh_coeffs());
  const int coeffs = int(k_count) - 1;  // 3, 8 or 15 per channel
  const uint64_t rows = (l.palette + 63) / 64;
  ATEX_ASSIGN_OR_RETURN(std::string centroid_name, FileName(*l.shn, "shN", 0));
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> centroid_bytes, images.load(centroid_name));
  ATEX_ASSIGN_OR_RETURN(Image centroids, DecodeWebp(centroid_bytes, centroid_name, uint64_t(64) * coeffs * rows,
                                                    uint64_t(64) * coeffs * (rows + 4)));
  if (centroids.width != 64 * coeffs) {
    return MakeError(StatusCode::kCorrupt, "SOG image '", centroid_name, "' is ", centroids.width, " wide; ",
                     l.sh_degree, " SH bands need ", 64 * coeffs);
  }
  ATEX_ASSIGN_OR_RETURN(Image labels, images.PerGaussian(*l.shn, "shN", 1));
  for (size_t i = 0; i < l.n; ++i) {
    const unsigned label = labels.rgba[i * 4] | unsigned(labels.rgba[i * 4 + 1]) << 8;
    if (label >= l.palette) continue;  // outside the palette: no view-dependent colour (as PlayCanvas)
    const size_t row = label / 64, column = (label % 64) * size_t(coeffs);
    for (int j = 0; j < coeffs; ++j) {
      const uint8_t* px = &centroids.rgba[(row * size_t(centroids.width) + column + size_t(j)) * 4];
      for (int c = 0; c < 3; ++c) g->sh[(i * k_count + 1 + size_t(j)) * 3 + size_t(c)] = float(l.shn_book[px[c]]);
    }
  }
  return Status::Ok();
}

StatusOr<Gaussians> DecodeSog(const std::vector<uint8_t>& meta_bytes, const LoadFn& load,
                              const WebSplatLimits& limits) {
  ATEX_ASSIGN_OR_RETURN(json meta, ParseMeta(meta_bytes));
  ATEX_ASSIGN_OR_RETURN(const SogLayout layout, ReadLayout(meta, limits));
  Gaussians g;
  g.sh_degree = layout.sh_degree;
  if (layout.n == 0) return g;
  // Per-Gaussian images are about sqrt(n) square (padded); allow generous slack, no more.
  const SogImages images{load, layout.n, 2 * layout.n + (uint64_t{1} << 16)};
  // One attribute at a time: each image is freed before the next is decoded.
  ATEX_RETURN_IF_ERROR(DecodePositions(layout, images, &g));
  ATEX_RETURN_IF_ERROR(DecodeRotations(layout, images, &g));
  ATEX_RETURN_IF_ERROR(DecodeScales(layout, images, &g));
  ATEX_RETURN_IF_ERROR(DecodeColours(layout, images, &g));
  if (layout.sh_degree > 0) {
    ATEX_RETURN_IF_ERROR(DecodeShRest(layout, images, &g));
  }
  return g;
}

}  // namespace

bool SogAvailable() {
#ifdef ATEX_HAVE_WEBP
  return true;
#else
  return false;
#endif
}

StatusOr<Gaussians> ReadSogBundleFromMemory(const uint8_t* data, size_t size, const WebSplatLimits& limits) {
  ZipLimits zip_limits;
  zip_limits.max_entries = 4096;
  zip_limits.max_member_bytes = uint64_t{4} << 30;
  ATEX_ASSIGN_OR_RETURN(ZipArchive zip, ZipArchive::FromView(data, size, "SOG bundle", zip_limits));
  // Members are looked up by name, or by their last path part when the bundle has folders.
  auto find = [&](const std::string& name) -> const ZipEntry* {
    if (const ZipEntry* e = zip.Find(name)) return e;
    for (const ZipEntry& e : zip.entries()) {
      const size_t slash = e.name.rfind('/');
      if (slash != std::string::npos && e.name.substr(slash + 1) == name) return &e;
    }
    return nullptr;
  };
  auto load = [&](const std::string& name) -> StatusOr<std::vector<uint8_t>> {
    const ZipEntry* e = find(name);
    if (e == nullptr) return MakeError(StatusCode::kNotFound, "SOG bundle has no member '", name, "'");
    return zip.Extract(*e);
  };
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> meta, load("meta.json"));
  return DecodeSog(meta, load, limits);
}

StatusOr<Gaussians> ReadSogGaussians(const std::string& path, const WebSplatLimits& limits) {
  namespace fs = std::filesystem;
  StatusOr<Gaussians> result = MakeError(StatusCode::kInternal, "unset");
  std::error_code ec;
  if (fs::is_directory(path, ec) || fs::path(path).filename() == "meta.json") {
    const fs::path dir = fs::is_directory(path, ec) ? fs::path(path) : fs::path(path).parent_path();
    auto load = [&](const std::string& name) -> StatusOr<std::vector<uint8_t>> {
      // Image names are plain file names beside meta.json; refuse paths that leave the folder.
      if (name.empty() || name.find('/') != std::string::npos || name.find('\\') != std::string::npos || name == "..") {
        return MakeError(StatusCode::kCorrupt, "SOG meta.json names image '", name, "', not a plain file name");
      }
      return ReadFileBytes((dir / name).string(), uint64_t{4} << 30);
    };
    ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> meta, ReadFileBytes((dir / "meta.json").string(), uint64_t{256} << 20));
    result = DecodeSog(meta, load, limits);
  } else {
    ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, ReadFileBytes(path));
    result = ReadSogBundleFromMemory(bytes.data(), bytes.size(), limits);
  }
  if (!result.ok()) return result.status().WithContext(path);
  return result;
}

}  // namespace atex
