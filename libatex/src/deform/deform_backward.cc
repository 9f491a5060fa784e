// DeformBackward: the vector-Jacobian product of DeformForward.
//
// Three phases, each deterministic whatever the thread count:
//  A. per fixed block of Gaussians (blocks grouped into at most kMaxGroups
//     consecutive groups): MLP backward as matrix products, partial MLP
//     gradients per group; per Gaussian the plane-sample gradients (stored
//     plane-major for phase C) and the position gradient through the
//     sampling coordinates;
//  B. the group partials summed in group order and added to grad_field;
//  C. per plane and channel, plane gradients gathered over Gaussians in index
//     order (one owner per channel, so no two threads touch the same value).
#include <vector>

#include "deform/deform_internal.h"

namespace atex {
namespace {

using deform_internal::ConstMatMap;
using deform_internal::ConstVecMap;
using deform_internal::CoordinateMap;
using deform_internal::kBlock;
using deform_internal::Layout;
using deform_internal::MatMap;
using deform_internal::RowMat;
using deform_internal::Vec;

// dL/d(MLP parameters) of one group of blocks.
template <typename T>
struct MlpGrads {
  std::vector<RowMat<T>> trunk_w;  // [L] [out][in]
  std::vector<Vec<T>> trunk_b;     // [L] [out]
  std::array<std::array<RowMat<T>, 2>, kNumDeformHeads> head_w;
  std::array<std::array<Vec<T>, 2>, kNumDeformHeads> head_b;

  explicit MlpGrads(const BasicDeformationField<T>& field) {
    for (const auto& layer : field.trunk) {
      trunk_w.push_back(RowMat<T>::Zero(layer.out, layer.in));
      trunk_b.push_back(Vec<T>::Zero(layer.out));
    }
    for (int h = 0; h < kNumDeformHeads; ++h) {
      for (int k = 0; k < 2; ++k) {
        head_w[h][k] = RowMat<T>::Zero(field.heads[h][k].out, field.heads[h][k].in);
        head_b[h][k] = Vec<T>::Zero(field.heads[h][k].out);
      }
    }
  }
  void Add(const MlpGrads& other) {
    for (size_t i = 0; i < trunk_w.size(); ++i) {
      trunk_w[i] += other.trunk_w[i];
      trunk_b[i] += other.trunk_b[i];
    }
    for (int h = 0; h < kNumDeformHeads; ++h) {
      for (int k = 0; k < 2; ++k) {
        head_w[h][k] += other.head_w[h][k];
        head_b[h][k] += other.head_b[h][k];
      }
    }
  }
  static void AddTo(const RowMat<T>& w, const Vec<T>& b, BasicLinear<T>* layer) {
    MatMap<T>(layer->weight.data(), layer->out, layer->in) += w;
    deform_internal::Vec<T>::Map(layer->bias.data(), layer->out) += b;
  }
  void AddTo(BasicDeformationField<T>* grad) const {
    for (size_t i = 0; i < trunk_w.size(); ++i) AddTo(trunk_w[i], trunk_b[i], &grad->trunk[i]);
    for (int h = 0; h < kNumDeformHeads; ++h) {
      if (!grad->config.heads[h]) continue;
      for (int k = 0; k < 2; ++k) AddTo(head_w[h][k], head_b[h][k], &grad->heads[h][k]);
    }
  }
};

template <typename T>
ConstMatMap<T> Weights(const BasicLinear<T>& layer) {
  return ConstMatMap<T>(layer.weight.data(), layer.out, layer.in);
}

// Shapes of the cache against the field and the Gaussians.
template <typename T>
Status CheckCache(const BasicDeformCache<T>& cache, const Layout& l, double time) {
  bool ok = cache.count == l.n && cache.time == time && cache.samples.size() == l.n * l.samples_per_gaussian() &&
            cache.features.size() == l.n * l.feat && cache.trunk.size() == static_cast<size_t>(l.layers);
  for (size_t i = 0; ok && i < cache.trunk.size(); ++i) ok = cache.trunk[i].size() == l.n * l.width;
  for (int h = 0; ok && h < kNumDeformHeads; ++h) {
    ok = cache.head_hidden[h].size() == (l.heads[h] ? l.n * l.width : 0);
  }
  if (!ok) {
    return MakeError(StatusCode::kInvalidArgument,
                     "DeformBackward: the cache does not come from DeformForward with this field, these Gaussians "
                     "and time ",
                     time, " (cache: N = ", cache.count, ", time ", cache.time, ")");
  }
  return Status::Ok();
}

template <typename T>
bool SameShapes(const BasicDeformationField<T>& a, const BasicDeformationField<T>& b) {
  if (a.planes.size() != b.planes.size() || a.trunk.size() != b.trunk.size()) return false;
  for (size_t s = 0; s < a.planes.size(); ++s) {
    for (int p = 0; p < kNumHexPlanes; ++p) {
      if (a.planes[s][p].size() != b.planes[s][p].size()) return false;
    }
  }
  auto same = [](const BasicLinear<T>& x, const BasicLinear<T>& y) {
    return x.in == y.in && x.out == y.out && x.weight.size() == y.weight.size() && x.bias.size() == y.bias.size();
  };
  for (size_t i = 0; i < a.trunk.size(); ++i) {
    if (!same(a.trunk[i], b.trunk[i])) return false;
  }
  for (int h = 0; h < kNumDeformHeads; ++h) {
    if (a.config.heads[h] != b.config.heads[h]) return false;
    for (int k = 0; k < 2; ++k) {
      if (!same(a.heads[h][k], b.heads[h][k])) return false;
    }
  }
  return true;
}

template <typename T>
bool SameShapes(const BasicGaussians<T>& a, const BasicGaussians<T>& b) {
  return a.sh_degree == b.sh_degree && a.positions.size() == b.positions.size() &&
         a.rotations.size() == b.rotations.size() && a.log_scales.size() == b.log_scales.size() &&
         a.opacity_logits.size() == b.opacity_logits.size() && a.sh.size() == b.sh.size();
}

template <typename T>
void AddArray(const std::vector<T>& from, std::vector<T>* to) {
  const long long n = static_cast<long long>(from.size());
#pragma omp parallel for schedule(static) if (n > (1 << 16))
  for (long long i = 0; i < n; ++i) (*to)[i] += from[i];
}

// Phase A for one block [begin, end). `lazy`: see deform_internal::Multiply.
template <typename T>
void BackwardBlock(const BasicDeformationField<T>& field, const Layout& l,
                   const std::vector<detail::HexPlaneScale<T>>& views, const CoordinateMap<T>& map,
                   const BasicGaussians<T>& canonical, const BasicDeformCache<T>& cache,
                   const BasicGaussians<T>& grad_deformed, size_t begin, size_t end, bool lazy, MlpGrads<T>* mlp,
                   T* grad_samples /* [S][6][C][N] or null */, BasicGaussians<T>* grad_canonical) {
  using deform_internal::Multiply;
  using deform_internal::MultiplyAdd;
  const Eigen::Index rows = static_cast<Eigen::Index>(end - begin);
  const Eigen::Index w = l.width;
  ConstMatMap<T> h(cache.trunk[l.layers - 1].data() + begin * w, rows, w);
  auto positive = [](const auto& m) { return (m.array() > T(0)).template cast<T>().matrix(); };

  // Heads: dL/d(ReLU(h)) summed over the enabled heads.
  RowMat<T> d_relu_h = RowMat<T>::Zero(rows, w);
  RowMat<T> d_hidden(rows, w);
  bool any_head = false;
  for (int head = 0; head < kNumDeformHeads; ++head) {
    if (!l.heads[head]) continue;
    any_head = true;
    const int outputs = field.config.head_outputs(head);
    ConstMatMap<T> d_out(deform_internal::HeadTarget(grad_deformed, head) + begin * outputs, rows, outputs);
    ConstMatMap<T> hidden(cache.head_hidden[head].data() + begin * w, rows, w);
    if (mlp) {
      MultiplyAdd(mlp->head_w[head][1], d_out.transpose(), hidden.cwiseMax(T(0)), lazy);
      mlp->head_b[head][1] += d_out.colwise().sum().transpose();
    }
    Multiply(d_hidden, d_out, Weights(field.heads[head][1]), lazy);
    d_hidden.array() *= positive(hidden).array();
    if (mlp) {
      MultiplyAdd(mlp->head_w[head][0], d_hidden.transpose(), h.cwiseMax(T(0)), lazy);
      mlp->head_b[head][0] += d_hidden.colwise().sum().transpose();
    }
    MultiplyAdd(d_relu_h, d_hidden, Weights(field.heads[head][0]), lazy);
  }
  if (!any_head) return;  // no residual: nothing depends on the field

  // Trunk, last layer first. d_layer = dL/d(output of `layer`).
  RowMat<T> d_layer = d_relu_h.cwiseProduct(positive(h));
  RowMat<T> d_input(rows, w);
  RowMat<T> d_features(rows, l.feat);
  for (int layer = l.layers - 1; layer >= 0; --layer) {
    if (layer > 0) {
      ConstMatMap<T> input(cache.trunk[layer - 1].data() + begin * w, rows, w);
      if (mlp) {
        MultiplyAdd(mlp->trunk_w[layer], d_layer.transpose(), input.cwiseMax(T(0)), lazy);
        mlp->trunk_b[layer] += d_layer.colwise().sum().transpose();
      }
      Multiply(d_input, d_layer, Weights(field.trunk[layer]), lazy);
      d_layer = d_input.cwiseProduct(positive(input));
    } else {
      ConstMatMap<T> features(cache.features.data() + begin * l.feat, rows, l.feat);
      if (mlp) {
        MultiplyAdd(mlp->trunk_w[0], d_layer.transpose(), features, lazy);
        mlp->trunk_b[0] += d_layer.colwise().sum().transpose();
      }
      Multiply(d_features, d_layer, Weights(field.trunk[0]), lazy);
    }
  }

  // Grid: plane-sample gradients and the position gradient through the coordinates.
  const size_t per_gaussian = l.samples_per_gaussian();
  const size_t per_scale = static_cast<size_t>(detail::kHexPlanes) * l.channels;
  std::vector<T> d_samples(per_scale);  // [6][C] of one scale
  for (size_t i = begin; i < end; ++i) {
    const size_t row = i - begin;
    T coord[4];
    map.Apply(canonical.positions.data() + 3 * i, coord);
    T d_coord[4] = {T(0), T(0), T(0), T(0)};
    for (int s = 0; s < l.scales; ++s) {
      const T* samples = cache.samples.data() + i * per_gaussian + s * per_scale;
      detail::HexPlaneProductVjp(samples, l.channels, d_features.data() + row * l.feat + s * l.channels,
                                 d_samples.data());
      if (grad_samples) {
        for (size_t k = 0; k < per_scale; ++k) grad_samples[(s * per_scale + k) * l.n + i] = d_samples[k];
      }
      if (grad_canonical) detail::HexPlaneCoordVjp(views[s], coord, d_samples.data(), d_coord);
    }
    if (grad_canonical) {
      for (int a = 0; a < 3; ++a) grad_canonical->positions[3 * i + a] += d_coord[a] * map.scale[a];
    }
  }
}

// The four corners of one Gaussian's tap on one plane.
template <typename T>
struct Corners {
  int index[4];  // into one channel, [res_b][res_a]
  T weight[4];
};

// Phase C for plane (s, p): gather dL/d(plane). Each task owns a group of
// channels and adds the Gaussians' contributions in index order, so every
// plane value is summed in the same order whatever the thread count.
template <typename T>
void GatherPlaneGradient(const detail::HexPlaneScale<T>& view, int s, int p, const Layout& l,
                         const CoordinateMap<T>& map, const BasicGaussians<T>& canonical, const T* grad_samples,
                         std::vector<Corners<T>>& corners, T* grad_plane) {
  const long long n = static_cast<long long>(l.n);
  [[maybe_unused]] const bool parallel = l.n > deform_internal::kBlock;  // used by the pragmas
#pragma omp parallel for schedule(static) if (parallel)
  for (long long i = 0; i < n; ++i) {
    T coord[4];
    map.Apply(canonical.positions.data() + 3 * i, coord);
    const detail::PlaneTap<T> tap = view.tap(p, coord);
    for (int k = 0; k < 4; ++k) {
      corners[i].index[k] = tap.corner(k);
      corners[i].weight[k] = tap.weight(k);
    }
  }
  constexpr int kGroup = 4;  // channels per task: one pass over the corners feeds four channels
  const int groups = (l.channels + kGroup - 1) / kGroup;
  const size_t stride = static_cast<size_t>(view.res_a(p)) * view.res_b(p);
  const size_t plane_index = static_cast<size_t>(s) * detail::kHexPlanes + p;
#pragma omp parallel for schedule(dynamic, 1) if (parallel)
  for (int group = 0; group < groups; ++group) {
    const int c0 = group * kGroup;
    const int count = std::min(kGroup, l.channels - c0);
    T* channel[kGroup];
    const T* g[kGroup];
    for (int j = 0; j < count; ++j) {
      channel[j] = grad_plane + static_cast<size_t>(c0 + j) * stride;
      g[j] = grad_samples + (plane_index * l.channels + c0 + j) * l.n;
    }
    for (size_t i = 0; i < l.n; ++i) {
      const Corners<T>& k = corners[i];
      for (int j = 0; j < count; ++j) {
        const T value = g[j][i];
        for (int q = 0; q < 4; ++q) channel[j][k.index[q]] += k.weight[q] * value;
      }
    }
  }
}

}  // namespace

template <typename T>
Status DeformBackward(const BasicDeformationField<T>& field, const BasicGaussians<T>& canonical, double time,
                      const BasicDeformCache<T>& cache, const BasicGaussians<T>& grad_deformed,
                      std::type_identity_t<BasicDeformationField<T>>* grad_field,
                      std::type_identity_t<BasicGaussians<T>>* grad_canonical) {
  ATEX_RETURN_IF_ERROR(deform_internal::CheckDeformInputs(field, canonical));
  const Layout l = deform_internal::MakeLayout(field, canonical.size());
  ATEX_RETURN_IF_ERROR(CheckCache(cache, l, time));
  if (!SameShapes(grad_deformed, canonical)) {
    return MakeError(StatusCode::kInvalidArgument, "DeformBackward: grad_deformed has other shapes than canonical");
  }
  if (grad_field != nullptr) {
    if (grad_field->planes.empty() && grad_field->trunk.empty()) *grad_field = ZerosLike(field);
    if (!SameShapes(*grad_field, field)) {
      return MakeError(StatusCode::kInvalidArgument, "DeformBackward: grad_field has other shapes than the field");
    }
  }
  if (grad_canonical != nullptr) {
    if (grad_canonical->size() == 0 && grad_canonical->positions.empty() && grad_canonical->sh.empty()) {
      grad_canonical->sh_degree = canonical.sh_degree;
      grad_canonical->Resize(canonical.size());  // zeros
    }
    if (!SameShapes(*grad_canonical, canonical)) {
      return MakeError(StatusCode::kInvalidArgument, "DeformBackward: grad_canonical has other shapes than canonical");
    }
    // The residuals are added, so every canonical parameter receives its deformed gradient unchanged.
    AddArray(grad_deformed.positions, &grad_canonical->positions);
    AddArray(grad_deformed.rotations, &grad_canonical->rotations);
    AddArray(grad_deformed.log_scales, &grad_canonical->log_scales);
    AddArray(grad_deformed.opacity_logits, &grad_canonical->opacity_logits);
    AddArray(grad_deformed.sh, &grad_canonical->sh);
  }
  if (l.n == 0 || (grad_field == nullptr && grad_canonical == nullptr)) return Status::Ok();

  const auto views = deform_internal::ScaleViews(field);
  const CoordinateMap<T> map(field.config, time);
  const size_t blocks = deform_internal::BlockCount(l.n);
  const size_t per_group = deform_internal::BlocksPerGroup(blocks);
  const long long groups = static_cast<long long>((blocks + per_group - 1) / per_group);

  std::vector<T> grad_samples;  // [S][6][C][N]
  std::vector<MlpGrads<T>> partial;
  if (grad_field != nullptr) {
    grad_samples.assign(l.samples_per_gaussian() * l.n, T(0));
    partial.reserve(groups);
    for (long long g = 0; g < groups; ++g) partial.emplace_back(field);
  }

  // Phase A.
#pragma omp parallel for schedule(dynamic, 1) if (groups > 1)
  for (long long g = 0; g < groups; ++g) {
    for (size_t b = static_cast<size_t>(g) * per_group; b < std::min(blocks, (static_cast<size_t>(g) + 1) * per_group);
         ++b) {
      const size_t begin = b * kBlock;
      const size_t end = std::min(l.n, begin + kBlock);
      BackwardBlock(field, l, views, map, canonical, cache, grad_deformed, begin, end, /*lazy=*/blocks == 1,
                    grad_field ? &partial[g] : nullptr, grad_field ? grad_samples.data() : nullptr, grad_canonical);
    }
  }
  if (grad_field == nullptr) return Status::Ok();

  // Phase B.
  for (long long g = 1; g < groups; ++g) partial[0].Add(partial[g]);
  partial[0].AddTo(grad_field);

  // Phase C.
  std::vector<Corners<T>> corners(l.n);
  for (int s = 0; s < l.scales; ++s) {
    for (int p = 0; p < detail::kHexPlanes; ++p) {
      GatherPlaneGradient(views[s], s, p, l, map, canonical, grad_samples.data(), corners,
                          grad_field->planes[s][p].data());
    }
  }
  return Status::Ok();
}

template Status DeformBackward<float>(const BasicDeformationField<float>&, const BasicGaussians<float>&, double,
                                      const BasicDeformCache<float>&, const BasicGaussians<float>&,
                                      BasicDeformationField<float>*, BasicGaussians<float>*);
template Status DeformBackward<double>(const BasicDeformationField<double>&, const BasicGaussians<double>&, double,
                                       const BasicDeformCache<double>&, const BasicGaussians<double>&,
                                       BasicDeformationField<double>*, BasicGaussians<double>*);

}  // namespace atex
