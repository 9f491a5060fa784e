// Deformation-field structure: shape checks, initialisation, zeros, counts.
#include <cmath>
#include <cstdint>
#include <limits>

#include "atex/deform.h"
#include "atex/detail/hexplane.h"

namespace atex {
namespace {

// The plane order of model.h and of the device-side helpers must agree.
constexpr bool PlaneAxesAgree() {
  for (int p = 0; p < kNumHexPlanes; ++p) {
    if (kHexPlaneAxes[p][0] != detail::HexPlaneAxis(p, 0) || kHexPlaneAxes[p][1] != detail::HexPlaneAxis(p, 1)) {
      return false;
    }
  }
  return true;
}
static_assert(PlaneAxesAgree(), "kHexPlaneAxes and detail::HexPlaneAxis disagree");
static_assert(kNumHexPlanes == detail::kHexPlanes);

constexpr uint64_t kMaxParameters = uint64_t{1} << 31;
constexpr int kMaxDimension = 1 << 16;  // any single resolution, width or channel count

uint64_t PlaneSize(const HexPlaneConfig& grid, int s, int p) {
  return static_cast<uint64_t>(grid.channels) * static_cast<uint64_t>(grid.resolution(s, kHexPlaneAxes[p][1])) *
         static_cast<uint64_t>(grid.resolution(s, kHexPlaneAxes[p][0]));
}

const char* HeadName(int h) {
  static const char* kNames[kNumDeformHeads] = {"position", "scale", "rotation", "opacity", "sh"};
  return kNames[h];
}

template <typename T>
Status CheckLinear(const BasicLinear<T>& l, int in, int out, const std::string& name) {
  if (l.in != in || l.out != out) {
    return MakeError(StatusCode::kInvalidArgument, name, " is ", l.in, "->", l.out, ", expected ", in, "->", out);
  }
  if (l.weight.size() != static_cast<size_t>(in) * out || l.bias.size() != static_cast<size_t>(out)) {
    return MakeError(StatusCode::kInvalidArgument, name, " has ", l.weight.size(), " weights and ", l.bias.size(),
                     " biases, expected ", static_cast<size_t>(in) * out, " and ", out);
  }
  return Status::Ok();
}

// Knuth/Vigna-style 64-bit generator with a fixed mapping to doubles, so that
// an initialisation is the same on every standard library.
struct SplitMix64 {
  uint64_t state;
  uint64_t Next() {
    uint64_t z = (state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  double Uniform(double lo, double hi) {  // [lo, hi)
    return lo + (hi - lo) * static_cast<double>(Next() >> 11) * 0x1.0p-53;
  }
};

Linear XavierLinear(int in, int out, float gain, SplitMix64& rng) {
  Linear l;
  l.in = in;
  l.out = out;
  const double bound = std::sqrt(6.0 / (in + out));
  l.weight.resize(static_cast<size_t>(in) * out);
  for (float& w : l.weight) w = static_cast<float>(rng.Uniform(-bound, bound) * gain);
  l.bias.assign(out, 0.0f);
  return l;
}

}  // namespace

Status CheckDeformationConfig(const DeformationConfig& config) {
  const HexPlaneConfig& grid = config.grid;
  if (grid.channels < 1 || grid.channels > kMaxDimension) {
    return MakeError(StatusCode::kInvalidArgument, "deformation grid: channels ", grid.channels, " outside 1..",
                     kMaxDimension);
  }
  if (grid.multires.empty() || grid.multires.size() > 16) {
    return MakeError(StatusCode::kInvalidArgument, "deformation grid: ", grid.multires.size(),
                     " scales (multires entries), expected 1..16");
  }
  for (int axis = 0; axis < 4; ++axis) {
    if (grid.base_resolution[axis] < 1 || grid.base_resolution[axis] > kMaxDimension) {
      return MakeError(StatusCode::kInvalidArgument, "deformation grid: base resolution of axis ", axis, " is ",
                       grid.base_resolution[axis]);
    }
  }
  uint64_t parameters = 0;
  for (int s = 0; s < grid.scales(); ++s) {
    if (grid.multires[s] < 1 || grid.multires[s] > kMaxDimension ||
        static_cast<int64_t>(grid.multires[s]) * grid.base_resolution[0] > kMaxDimension ||
        static_cast<int64_t>(grid.multires[s]) * grid.base_resolution[1] > kMaxDimension ||
        static_cast<int64_t>(grid.multires[s]) * grid.base_resolution[2] > kMaxDimension) {
      return MakeError(StatusCode::kInvalidArgument, "deformation grid: multires[", s, "] = ", grid.multires[s],
                       " gives a resolution outside 1..", kMaxDimension);
    }
    for (int p = 0; p < kNumHexPlanes; ++p) parameters += PlaneSize(grid, s, p);
  }
  if (config.mlp_width < 1 || config.mlp_width > kMaxDimension) {
    return MakeError(StatusCode::kInvalidArgument, "deformation MLP: width ", config.mlp_width);
  }
  if (config.trunk_layers < 1 || config.trunk_layers > 64) {
    return MakeError(StatusCode::kInvalidArgument, "deformation MLP: ", config.trunk_layers,
                     " trunk layers, expected 1..64");
  }
  if (config.sh_coeffs < 1 || config.sh_coeffs > ShCoeffCount(kMaxShDegree)) {
    return MakeError(StatusCode::kInvalidArgument, "deformation MLP: sh_coeffs ", config.sh_coeffs,
                     " outside 1..16");
  }
  const uint64_t w = static_cast<uint64_t>(config.mlp_width);
  parameters += static_cast<uint64_t>(grid.feature_dim()) * w + w;
  parameters += static_cast<uint64_t>(config.trunk_layers - 1) * (w * w + w);
  for (int h = 0; h < kNumDeformHeads; ++h) {
    if (config.heads[h]) parameters += w * w + w + w * config.head_outputs(h) + config.head_outputs(h);
  }
  if (parameters > kMaxParameters) {
    return MakeError(StatusCode::kLimitExceeded, "deformation field: ", parameters, " parameters, limit ",
                     kMaxParameters);
  }
  for (int a = 0; a < 3; ++a) {
    const float lo = config.aabb_lo[a], hi = config.aabb_hi[a];
    const float scale = 2.0f / (hi - lo);  // as computed for float fields
    if (!std::isfinite(lo) || !std::isfinite(hi) || lo == hi || !std::isfinite(scale) || scale == 0.0f) {
      return MakeError(StatusCode::kInvalidArgument, "deformation AABB axis ", a, ": lo ", lo, ", hi ", hi,
                       " (must be finite, distinct and not overflow 2 / (hi - lo))");
    }
  }
  if (!std::isfinite(config.time_scale) || !std::isfinite(config.time_offset)) {
    return MakeError(StatusCode::kInvalidArgument, "deformation time mapping: scale ", config.time_scale,
                     ", offset ", config.time_offset, " (must be finite)");
  }
  return Status::Ok();
}

template <typename T>
Status CheckDeformationField(const BasicDeformationField<T>& field) {
  const DeformationConfig& config = field.config;
  ATEX_RETURN_IF_ERROR(CheckDeformationConfig(config));
  const HexPlaneConfig& grid = config.grid;
  if (field.planes.size() != static_cast<size_t>(grid.scales())) {
    return MakeError(StatusCode::kInvalidArgument, "deformation field: ", field.planes.size(),
                     " plane scales, config has ", grid.scales());
  }
  for (int s = 0; s < grid.scales(); ++s) {
    for (int p = 0; p < kNumHexPlanes; ++p) {
      if (field.planes[s][p].size() != PlaneSize(grid, s, p)) {
        return MakeError(StatusCode::kInvalidArgument, "deformation plane (scale ", s, ", plane ", p, ") has ",
                         field.planes[s][p].size(), " values, expected ", PlaneSize(grid, s, p), " = ",
                         grid.channels, " x ", grid.resolution(s, kHexPlaneAxes[p][1]), " x ",
                         grid.resolution(s, kHexPlaneAxes[p][0]));
      }
    }
  }
  if (field.trunk.size() != static_cast<size_t>(config.trunk_layers)) {
    return MakeError(StatusCode::kInvalidArgument, "deformation trunk: ", field.trunk.size(), " layers, config has ",
                     config.trunk_layers);
  }
  const int w = config.mlp_width;
  for (size_t i = 0; i < field.trunk.size(); ++i) {
    ATEX_RETURN_IF_ERROR(CheckLinear(field.trunk[i], i == 0 ? grid.feature_dim() : w, w,
                                     StrCat("deformation trunk layer ", i)));
  }
  for (int h = 0; h < kNumDeformHeads; ++h) {
    if (config.heads[h]) {
      ATEX_RETURN_IF_ERROR(CheckLinear(field.heads[h][0], w, w, StrCat("deformation ", HeadName(h), " head layer 0")));
      ATEX_RETURN_IF_ERROR(CheckLinear(field.heads[h][1], w, config.head_outputs(h),
                                       StrCat("deformation ", HeadName(h), " head layer 1")));
    } else {
      for (int k = 0; k < 2; ++k) {
        if (!field.heads[h][k].weight.empty() || !field.heads[h][k].bias.empty()) {
          return MakeError(StatusCode::kInvalidArgument, "deformation ", HeadName(h), " head is disabled but layer ",
                           k, " holds values");
        }
      }
    }
  }
  return Status::Ok();
}

StatusOr<DeformationField> InitDeformationField(const DeformationConfig& config, uint64_t seed) {
  ATEX_RETURN_IF_ERROR(CheckDeformationConfig(config));
  SplitMix64 rng{seed};
  DeformationField field;
  field.config = config;
  const HexPlaneConfig& grid = config.grid;
  field.planes.resize(grid.scales());
  for (int s = 0; s < grid.scales(); ++s) {
    for (int p = 0; p < kNumHexPlanes; ++p) {
      std::vector<float>& plane = field.planes[s][p];
      plane.resize(PlaneSize(grid, s, p));
      if (detail::IsTimePlane(p)) {
        std::fill(plane.begin(), plane.end(), 1.0f);
      } else {
        for (float& v : plane) v = static_cast<float>(rng.Uniform(0.1, 0.5));
      }
    }
  }
  const int w = config.mlp_width;
  for (int i = 0; i < config.trunk_layers; ++i) {
    field.trunk.push_back(XavierLinear(i == 0 ? grid.feature_dim() : w, w, 1.0f, rng));
  }
  for (int h = 0; h < kNumDeformHeads; ++h) {
    if (!config.heads[h]) continue;
    field.heads[h][0] = XavierLinear(w, w, 1.0f, rng);
    // [choice] near-identity start: docs/conventions.md §3.
    field.heads[h][1] = XavierLinear(w, config.head_outputs(h), 0.01f, rng);
  }
  return field;
}

template <typename T>
BasicDeformationField<T> ZerosLike(const BasicDeformationField<T>& field) {
  return MapDeformationField<T>(field, [](const std::vector<T>& v) { return std::vector<T>(v.size(), T(0)); });
}

template <typename T>
size_t ParameterCount(const BasicDeformationField<T>& field) {
  size_t count = 0;
  for (const auto& scale : field.planes) {
    for (const auto& plane : scale) count += plane.size();
  }
  for (const auto& l : field.trunk) count += l.weight.size() + l.bias.size();
  for (const auto& head : field.heads) {
    for (const auto& l : head) count += l.weight.size() + l.bias.size();
  }
  return count;
}

template <typename T>
size_t BasicDeformCache<T>::bytes() const {
  size_t values = samples.size() + features.size();
  for (const auto& t : trunk) values += t.size();
  for (const auto& h : head_hidden) values += h.size();
  return values * sizeof(T);
}

#define ATEX_INSTANTIATE_DEFORM_FIELD(T)                                          \
  template Status CheckDeformationField<T>(const BasicDeformationField<T>&);      \
  template BasicDeformationField<T> ZerosLike<T>(const BasicDeformationField<T>&); \
  template size_t ParameterCount<T>(const BasicDeformationField<T>&);             \
  template struct BasicDeformCache<T>;
ATEX_INSTANTIATE_DEFORM_FIELD(float)
ATEX_INSTANTIATE_DEFORM_FIELD(double)
#undef ATEX_INSTANTIATE_DEFORM_FIELD

}  // namespace atex
