// DeformForward: HexPlane sampling per Gaussian, then the MLP as matrix
// products over fixed blocks of Gaussians (docs/conventions.md §3).
#include <vector>

#include "deform/deform_internal.h"

namespace atex {
namespace {

using deform_internal::CoordinateMap;
using deform_internal::kBlock;
using deform_internal::Layout;
using deform_internal::MatMap;
using deform_internal::RowMat;

// y = x * W^T + b for a row-major [rows][in] input (PyTorch nn.Linear).
template <typename T, typename Input>
void LinearInto(const BasicLinear<T>& layer, const Input& x, MatMap<T>& y, bool lazy) {
  deform_internal::ConstMatMap<T> w(layer.weight.data(), layer.out, layer.in);
  deform_internal::ConstVecMap<T> b(layer.bias.data(), layer.out);
  deform_internal::Multiply(y, x, w.transpose(), lazy);
  y.rowwise() += b.transpose();
}

// Where one block's intermediate values go: into the cache when there is one,
// else into per-thread scratch.
template <typename T>
struct BlockStorage {
  std::vector<T> samples;                          // [kBlock][S][6][C]
  std::vector<T> features;                         // [kBlock][S*C]
  std::vector<std::vector<T>> trunk;               // [L][kBlock][W]
  std::array<std::vector<T>, kNumDeformHeads> hidden;  // [kBlock][W]
  std::vector<T> out;                              // [kBlock][max head outputs]

  BlockStorage(const Layout& l, int max_outputs, bool without_cache) {
    out.resize(kBlock * max_outputs);
    if (!without_cache) return;
    samples.resize(kBlock * l.samples_per_gaussian());
    features.resize(kBlock * l.feat);
    trunk.assign(l.layers, std::vector<T>(kBlock * l.width));
    for (int h = 0; h < kNumDeformHeads; ++h) {
      if (l.heads[h]) hidden[h].resize(kBlock * l.width);
    }
  }
};

template <typename T>
void ForwardBlock(const BasicDeformationField<T>& field, const Layout& l,
                  const std::vector<detail::HexPlaneScale<T>>& views, const CoordinateMap<T>& map,
                  const BasicGaussians<T>& canonical, size_t begin, size_t end, bool lazy, BlockStorage<T>& scratch,
                  BasicDeformCache<T>* cache, BasicGaussians<T>* deformed) {
  const Eigen::Index rows = static_cast<Eigen::Index>(end - begin);
  const size_t per_gaussian = l.samples_per_gaussian();
  T* samples = cache ? cache->samples.data() + begin * per_gaussian : scratch.samples.data();
  T* features = cache ? cache->features.data() + begin * l.feat : scratch.features.data();

  // 1. Grid features: per Gaussian and scale, the product of six plane samples.
  for (size_t i = begin; i < end; ++i) {
    T coord[4];
    map.Apply(canonical.positions.data() + 3 * i, coord);
    const size_t row = i - begin;
    for (int s = 0; s < l.scales; ++s) {
      detail::SampleHexPlaneScale(
          views[s], coord, samples + row * per_gaussian + static_cast<size_t>(s) * detail::kHexPlanes * l.channels,
          features + row * l.feat + static_cast<size_t>(s) * l.channels);
    }
  }

  // 2. Trunk: h = L0(feat), then h = Li(ReLU(h)).
  MatMap<T> feat(features, rows, l.feat);
  T* previous = nullptr;
  for (int layer = 0; layer < l.layers; ++layer) {
    T* dst = cache ? cache->trunk[layer].data() + begin * l.width : scratch.trunk[layer].data();
    MatMap<T> h(dst, rows, l.width);
    if (layer == 0) {
      LinearInto(field.trunk[0], feat, h, lazy);
    } else {
      MatMap<T> in(previous, rows, l.width);
      LinearInto(field.trunk[layer], in.cwiseMax(T(0)), h, lazy);
    }
    previous = dst;
  }
  MatMap<T> h(previous, rows, l.width);

  // 3. Heads: out = L2(ReLU(L1(ReLU(h)))), added to the canonical values.
  for (int head = 0; head < kNumDeformHeads; ++head) {
    if (!l.heads[head]) continue;
    T* hidden_ptr = cache ? cache->head_hidden[head].data() + begin * l.width : scratch.hidden[head].data();
    MatMap<T> hidden(hidden_ptr, rows, l.width);
    LinearInto(field.heads[head][0], h.cwiseMax(T(0)), hidden, lazy);
    const int outputs = field.config.head_outputs(head);
    MatMap<T> out(scratch.out.data(), rows, outputs);
    LinearInto(field.heads[head][1], hidden.cwiseMax(T(0)), out, lazy);
    MatMap<T> target(deform_internal::HeadTarget(*deformed, head) + begin * outputs, rows, outputs);
    target += out;
  }
}

}  // namespace

// The time windows of time-local Gaussians (docs/conventions.md §3, "Time-local
// Gaussians"): a constant taken off the deformed logit, so DeformBackward passes the
// opacity gradient through unchanged.
namespace {
template <typename T>
void ApplyTimeWindows(const BasicGaussians<T>& canonical, double time, BasicGaussians<T>* deformed) {
  if (!canonical.has_time_windows()) return;
  for (size_t i = 0; i < canonical.size(); ++i) {
    deformed->opacity_logits[i] -=
        TimeWindowPenalty(canonical.time_windows[2 * i], canonical.time_windows[2 * i + 1], time);
  }
}
}  // namespace

template <typename T>
Status DeformForward(const BasicDeformationField<T>& field, const BasicGaussians<T>& canonical, double time,
                     std::type_identity_t<BasicGaussians<T>>* deformed,
                     std::type_identity_t<BasicDeformCache<T>>* cache) {
  ATEX_RETURN_IF_ERROR(deform_internal::CheckDeformInputs(field, canonical));
  if (deformed == nullptr || deformed == &canonical) {
    return MakeError(StatusCode::kInvalidArgument, "DeformForward: `deformed` must be a distinct, non-null output");
  }
  const Layout l = deform_internal::MakeLayout(field, canonical.size());
  *deformed = canonical;  // residuals are added below; disabled heads leave values as they are
  deformed->time_windows.clear();  // applied to the opacity logits below: a deformed set has none

  if (cache != nullptr) {
    cache->count = l.n;
    cache->time = time;
    cache->samples.assign(l.n * l.samples_per_gaussian(), T(0));
    cache->features.assign(l.n * l.feat, T(0));
    cache->trunk.assign(l.layers, std::vector<T>(l.n * l.width));
    for (int h = 0; h < kNumDeformHeads; ++h) {
      if (l.heads[h]) {
        cache->head_hidden[h].assign(l.n * l.width, T(0));
      } else {
        cache->head_hidden[h].clear();
      }
    }
  }
  if (l.n == 0) return Status::Ok();

  int max_outputs = 1;
  for (int h = 0; h < kNumDeformHeads; ++h) {
    if (l.heads[h]) max_outputs = std::max(max_outputs, field.config.head_outputs(h));
  }
  const auto views = deform_internal::ScaleViews(field);
  const CoordinateMap<T> map(field.config, time);
  const long long blocks = static_cast<long long>(deform_internal::BlockCount(l.n));

#pragma omp parallel if (blocks > 1)
  {
    BlockStorage<T> scratch(l, max_outputs, cache == nullptr);
#pragma omp for schedule(dynamic, 1)
    for (long long b = 0; b < blocks; ++b) {
      const size_t begin = static_cast<size_t>(b) * kBlock;
      const size_t end = std::min(l.n, begin + kBlock);
      ForwardBlock(field, l, views, map, canonical, begin, end, /*lazy=*/blocks == 1, scratch, cache, deformed);
    }
  }
  ApplyTimeWindows(canonical, time, deformed);
  return Status::Ok();
}

template Status DeformForward<float>(const BasicDeformationField<float>&, const BasicGaussians<float>&, double,
                                     BasicGaussians<float>*, BasicDeformCache<float>*);
template Status DeformForward<double>(const BasicDeformationField<double>&, const BasicGaussians<double>&, double,
                                      BasicGaussians<double>*, BasicDeformCache<double>*);

}  // namespace atex
