// The plane regularisers of 4DGaussians' fine stage (see deform.h for the
// exact definition). Each plane is [C][res_b][res_a]; smoothness is taken
// along b (rows), which is time for the three time planes.
#include <cmath>
#include <limits>

#include "atex/deform.h"
#include "atex/detail/hexplane.h"

namespace atex {
namespace {

// mean over [C][res_b - 2][res_a] of (second difference along b)^2, with the
// second difference formed as 4DGaussians does: (P[b+2] - P[b+1]) - (P[b+1] - P[b]).
// Adds weight * d(mean)/dP to grad (may be null). Returns the mean.
template <typename T>
double SecondDifferenceMean(const std::vector<T>& plane, int channels, int res_b, int res_a, double weight,
                            std::vector<T>* grad) {
  if (res_b < 3 || plane.empty()) return 0.0;
  const size_t count = static_cast<size_t>(channels) * (res_b - 2) * res_a;
  const double inv_count = 1.0 / static_cast<double>(count);
  double sum = 0.0;
  for (int c = 0; c < channels; ++c) {
    const size_t base = static_cast<size_t>(c) * res_b * res_a;
    for (int b = 0; b + 2 < res_b; ++b) {
      for (int a = 0; a < res_a; ++a) {
        const size_t i0 = base + static_cast<size_t>(b) * res_a + a;
        const size_t i1 = i0 + res_a;
        const size_t i2 = i1 + res_a;
        const T d2 = (plane[i2] - plane[i1]) - (plane[i1] - plane[i0]);
        sum += static_cast<double>(d2) * static_cast<double>(d2);
        if (grad) {
          const T g = static_cast<T>(2.0 * weight * inv_count * static_cast<double>(d2));
          (*grad)[i0] += g;
          (*grad)[i1] -= T(2) * g;
          (*grad)[i2] += g;
        }
      }
    }
  }
  return sum * inv_count;
}

// mean |1 - P|; adds weight * d/dP (sign(P - 1) / count, 0 at P == 1) to grad.
template <typename T>
double OneL1Mean(const std::vector<T>& plane, double weight, std::vector<T>* grad) {
  if (plane.empty()) return 0.0;
  const double inv_count = 1.0 / static_cast<double>(plane.size());
  const T step = static_cast<T>(weight * inv_count);
  double sum = 0.0;
  for (size_t i = 0; i < plane.size(); ++i) {
    const T d = T(1) - plane[i];
    sum += std::fabs(static_cast<double>(d));
    if (grad) {
      if (d > T(0)) {
        (*grad)[i] -= step;
      } else if (d < T(0)) {
        (*grad)[i] += step;
      }
    }
  }
  return sum * inv_count;
}

}  // namespace

template <typename T>
T DeformRegularizer(const BasicDeformationField<T>& field, const RegularizerWeights& weights,
                    std::type_identity_t<BasicDeformationField<T>>* grad) {
  if (!CheckDeformationField(field).ok() || (grad != nullptr && grad->planes.size() != field.planes.size())) {
    return std::numeric_limits<T>::quiet_NaN();
  }
  if (grad != nullptr) {
    for (size_t s = 0; s < field.planes.size(); ++s) {
      for (int p = 0; p < kNumHexPlanes; ++p) {
        if (grad->planes[s][p].size() != field.planes[s][p].size()) return std::numeric_limits<T>::quiet_NaN();
      }
    }
  }
  const HexPlaneConfig& grid = field.config.grid;
  double plane_term = 0.0, time_term = 0.0, l1_term = 0.0;
  for (size_t s = 0; s < field.planes.size(); ++s) {
    for (int p = 0; p < kNumHexPlanes; ++p) {
      const int res_a = grid.resolution(static_cast<int>(s), kHexPlaneAxes[p][0]);
      const int res_b = grid.resolution(static_cast<int>(s), kHexPlaneAxes[p][1]);
      std::vector<T>* g = grad ? &grad->planes[s][p] : nullptr;
      if (detail::IsTimePlane(p)) {
        time_term += SecondDifferenceMean(field.planes[s][p], grid.channels, res_b, res_a, weights.time_smoothness, g);
        l1_term += OneL1Mean(field.planes[s][p], weights.time_l1, g);
      } else {
        plane_term += SecondDifferenceMean(field.planes[s][p], grid.channels, res_b, res_a, weights.plane_tv, g);
      }
    }
  }
  return static_cast<T>(weights.plane_tv * plane_term + weights.time_smoothness * time_term +
                        weights.time_l1 * l1_term);
}

template float DeformRegularizer<float>(const BasicDeformationField<float>&, const RegularizerWeights&,
                                        BasicDeformationField<float>*);
template double DeformRegularizer<double>(const BasicDeformationField<double>&, const RegularizerWeights&,
                                          BasicDeformationField<double>*);

}  // namespace atex
