// k-nearest-neighbour distances through an implicit k-d tree: the points are
// permuted so that every range [lo, hi) has its median (on the axis cycling with
// depth) at mid = (lo + hi)/2, smaller coordinates left of it, larger right.
#include <algorithm>
#include <cmath>
#include <numeric>

#include "atex/init.h"

namespace atex {
namespace {

constexpr int kLeafSize = 8;
constexpr double kMinSquaredDistance = 1e-7;  // 3DGS's clamp_min on distCUDA2
constexpr int kMaxK = 16;

class KdTree {
 public:
  explicit KdTree(const std::vector<float>& positions) : p_(positions), order_(positions.size() / 3) {
    std::iota(order_.begin(), order_.end(), 0u);
    Build(0, order_.size(), 0);
  }

  // The k smallest squared distances from point `self` to other points, ascending. [k]
  void Query(uint32_t self, int k, double* best) const {
    std::fill(best, best + k, INFINITY);
    const float* q = &p_[size_t(self) * 3];
    Search(0, order_.size(), 0, q, self, k, best);
  }

 private:
  double Coord(uint32_t i, int axis) const { return p_[size_t(i) * 3 + axis]; }

  void Build(size_t lo, size_t hi, int depth) {
    if (hi - lo <= kLeafSize) return;
    const int axis = depth % 3;
    const size_t mid = lo + (hi - lo) / 2;
    std::nth_element(order_.begin() + lo, order_.begin() + mid, order_.begin() + hi,
                     [&](uint32_t a, uint32_t b) { return Coord(a, axis) < Coord(b, axis); });
    Build(lo, mid, depth + 1);
    Build(mid + 1, hi, depth + 1);
  }

  static void Offer(double d2, int k, double* best) {
    if (d2 >= best[k - 1]) return;
    int i = k - 1;
    while (i > 0 && best[i - 1] > d2) {
      best[i] = best[i - 1];
      --i;
    }
    best[i] = d2;
  }

  double Distance2(uint32_t i, const float* q) const {
    const double dx = Coord(i, 0) - q[0], dy = Coord(i, 1) - q[1], dz = Coord(i, 2) - q[2];
    return dx * dx + dy * dy + dz * dz;
  }

  void Search(size_t lo, size_t hi, int depth, const float* q, uint32_t self, int k, double* best) const {
    if (hi - lo <= kLeafSize) {
      for (size_t j = lo; j < hi; ++j) {
        if (order_[j] != self) Offer(Distance2(order_[j], q), k, best);
      }
      return;
    }
    const int axis = depth % 3;
    const size_t mid = lo + (hi - lo) / 2;
    const uint32_t m = order_[mid];
    if (m != self) Offer(Distance2(m, q), k, best);
    const double diff = double(q[axis]) - Coord(m, axis);
    const bool left_first = diff < 0;
    if (left_first) {
      Search(lo, mid, depth + 1, q, self, k, best);
      if (diff * diff < best[k - 1]) Search(mid + 1, hi, depth + 1, q, self, k, best);
    } else {
      Search(mid + 1, hi, depth + 1, q, self, k, best);
      if (diff * diff < best[k - 1]) Search(lo, mid, depth + 1, q, self, k, best);
    }
  }

  const std::vector<float>& p_;  // [N][3]
  std::vector<uint32_t> order_;  // [N] permutation of point indices
};

}  // namespace

std::vector<float> NearestNeighborLogScales(const std::vector<float>& positions, int k) {
  const size_t n = positions.size() / 3;
  std::vector<float> out(n);
  if (n == 0) return out;
  k = std::clamp(k, 1, kMaxK);
  const int available = static_cast<int>(std::min<size_t>(k, n - 1));
  if (available == 0) {
    out[0] = static_cast<float>(0.5 * std::log(kMinSquaredDistance));
    return out;
  }
  const KdTree tree(positions);
#pragma omp parallel for schedule(static)
  for (long long i = 0; i < static_cast<long long>(n); ++i) {
    double best[kMaxK];
    tree.Query(static_cast<uint32_t>(i), available, best);
    double mean = 0;
    for (int j = 0; j < available; ++j) mean += best[j];
    mean = std::max(mean / available, kMinSquaredDistance);
    out[i] = static_cast<float>(0.5 * std::log(mean));
  }
  return out;
}

}  // namespace atex
