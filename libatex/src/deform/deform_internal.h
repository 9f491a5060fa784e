// Shared pieces of the deform module's translation units (not public API):
// Eigen views of the row-major arrays, the fixed block partition that keeps
// results independent of the thread count, and input checks.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cstddef>
#include <vector>

#include "atex/deform.h"
#include "atex/detail/hexplane.h"
#include "atex/model.h"
#include "atex/status.h"

namespace atex::deform_internal {

template <typename T>
using RowMat = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
template <typename T>
using MatMap = Eigen::Map<RowMat<T>>;
template <typename T>
using ConstMatMap = Eigen::Map<const RowMat<T>>;
template <typename T>
using Vec = Eigen::Matrix<T, Eigen::Dynamic, 1>;
template <typename T>
using ConstVecMap = Eigen::Map<const Vec<T>>;

// Gaussians per block of the batched MLP. Fixed (never derived from the thread
// count) so that every GEMM, and so every rounding, is the same however many
// threads run.
inline constexpr size_t kBlock = 256;
// Upper bound on the number of partial MLP-gradient buffers of the backward
// pass; consecutive blocks form a group whose partial sums are reduced in
// group order.
inline constexpr size_t kMaxGroups = 32;

// Matrix products of this module. Eigen parallelises a GEMM with OpenMP when
// it runs outside a team, choosing its blocking (and so its rounding) from the
// thread count. Our products either run inside our own parallel regions,
// where Eigen sees a team and stays serial, or, for a single block (no team
// is opened), as coefficient-based lazy products, which Eigen never threads.
// Either way the result does not depend on the number of threads.
template <typename Dst, typename A, typename B>
void Multiply(Dst&& dst, const A& a, const B& b, bool lazy) {
  if (lazy) {
    dst.noalias() = a.lazyProduct(b);
  } else {
    dst.noalias() = a * b;
  }
}
template <typename Dst, typename A, typename B>
void MultiplyAdd(Dst&& dst, const A& a, const B& b, bool lazy) {
  if (lazy) {
    dst.noalias() += a.lazyProduct(b);
  } else {
    dst.noalias() += a * b;
  }
}

inline size_t BlockCount(size_t n) { return (n + kBlock - 1) / kBlock; }
inline size_t BlocksPerGroup(size_t blocks) { return std::max<size_t>(1, (blocks + kMaxGroups - 1) / kMaxGroups); }

// Sizes derived once per call.
struct Layout {
  size_t n = 0;       // Gaussians
  int scales = 0;     // S
  int channels = 0;   // C
  int feat = 0;       // S*C
  int width = 0;      // W
  int layers = 0;     // trunk layers
  std::array<bool, kNumDeformHeads> heads{};

  size_t samples_per_gaussian() const { return static_cast<size_t>(scales) * detail::kHexPlanes * channels; }
};

template <typename T>
Layout MakeLayout(const BasicDeformationField<T>& field, size_t n) {
  Layout l;
  l.n = n;
  l.scales = field.config.grid.scales();
  l.channels = field.config.grid.channels;
  l.feat = field.config.grid.feature_dim();
  l.width = field.config.mlp_width;
  l.layers = static_cast<int>(field.trunk.size());
  l.heads = field.config.heads;
  return l;
}

// Per-scale plane views for the ATEX_HD sampling functions.
template <typename T>
std::vector<detail::HexPlaneScale<T>> ScaleViews(const BasicDeformationField<T>& field) {
  std::vector<detail::HexPlaneScale<T>> views(field.planes.size());
  for (size_t s = 0; s < field.planes.size(); ++s) {
    for (int axis = 0; axis < 4; ++axis) views[s].resolution[axis] = field.config.grid.resolution(int(s), axis);
    views[s].channels = field.config.grid.channels;
    for (int p = 0; p < detail::kHexPlanes; ++p) views[s].planes[p] = field.planes[s][p].data();
  }
  return views;
}

// Normalised-coordinate mapping of a field: coord = (x_norm, y_norm, z_norm, t_norm).
template <typename T>
struct CoordinateMap {
  T lo[3];
  T scale[3];  // 2 / (hi - lo): also d coord / d position
  T time;      // t_norm of this call

  CoordinateMap(const DeformationConfig& config, double t) {
    for (int a = 0; a < 3; ++a) {
      lo[a] = static_cast<T>(config.aabb_lo[a]);
      scale[a] = detail::AabbScale(lo[a], static_cast<T>(config.aabb_hi[a]));
    }
    time = static_cast<T>(static_cast<double>(config.time_scale) * t + static_cast<double>(config.time_offset));
  }
  void Apply(const T* position, T* coord) const {
    for (int a = 0; a < 3; ++a) coord[a] = detail::NormalizeCoordinate(position[a], lo[a], scale[a]);
    coord[3] = time;
  }
};

// Shapes of a Gaussian set: every array sized for size() and sh_degree.
template <typename T>
Status CheckGaussianShapes(const BasicGaussians<T>& g, const char* what) {
  const size_t n = g.size();
  if (g.sh_degree < 0 || g.sh_degree > kMaxShDegree) {
    return MakeError(StatusCode::kInvalidArgument, what, ": sh_degree ", g.sh_degree, " outside 0..3");
  }
  const size_t k = static_cast<size_t>(g.sh_coeffs());
  if (g.positions.size() != 3 * n || g.rotations.size() != 4 * n || g.log_scales.size() != 3 * n ||
      g.sh.size() != n * k * 3) {
    return MakeError(StatusCode::kInvalidArgument, what, ": array sizes disagree with N = ", n,
                     " (positions ", g.positions.size(), ", rotations ", g.rotations.size(), ", log_scales ",
                     g.log_scales.size(), ", sh ", g.sh.size(), " for K = ", k, ")");
  }
  if (!g.time_windows.empty() && g.time_windows.size() != 2 * n) {
    return MakeError(StatusCode::kInvalidArgument, what, ": time_windows has ", g.time_windows.size(),
                     " values for N = ", n, " (2 per Gaussian, or none)");
  }
  return Status::Ok();
}

// Input checks shared by forward and backward.
template <typename T>
Status CheckDeformInputs(const BasicDeformationField<T>& field, const BasicGaussians<T>& canonical) {
  ATEX_RETURN_IF_ERROR(CheckDeformationField(field));
  ATEX_RETURN_IF_ERROR(CheckGaussianShapes(canonical, "canonical Gaussians"));
  if (field.config.heads[kHeadSH] && field.config.sh_coeffs != canonical.sh_coeffs()) {
    return MakeError(StatusCode::kInvalidArgument, "the field's SH head has ", 3 * field.config.sh_coeffs,
                     " outputs but the Gaussians have K = ", canonical.sh_coeffs(), " (sh_degree ",
                     canonical.sh_degree, ")");
  }
  return Status::Ok();
}

// Pointer to the start of head h's slice of a Gaussian set and its row length.
template <typename T>
T* HeadTarget(BasicGaussians<T>& g, int head) {
  switch (head) {
    case kHeadPosition: return g.positions.data();
    case kHeadScale: return g.log_scales.data();
    case kHeadRotation: return g.rotations.data();
    case kHeadOpacity: return g.opacity_logits.data();
    default: return g.sh.data();
  }
}
template <typename T>
const T* HeadTarget(const BasicGaussians<T>& g, int head) {
  return HeadTarget(const_cast<BasicGaussians<T>&>(g), head);
}

}  // namespace atex::deform_internal
