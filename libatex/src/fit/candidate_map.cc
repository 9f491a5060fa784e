// CandidateMap helpers (incremental_probes.h): which Gaussians a candidate keeps and changes.
#include <cstring>

#include "incremental_probes.h"

namespace atex::fit::internal {
namespace {

template <typename T>
bool SameSpan(const std::vector<T>& a, size_t i, const std::vector<T>& b, size_t j, size_t width) {
  return std::memcmp(a.data() + i * width, b.data() + j * width, width * sizeof(T)) == 0;
}

}  // namespace

std::vector<uint32_t> BaseIndices(const std::vector<uint32_t>& base_kept, const std::vector<uint32_t>& kept) {
  std::vector<uint32_t> out(kept.size(), kNoBase);
  size_t b = 0;
  for (size_t j = 0; j < kept.size(); ++j) {
    while (b < base_kept.size() && base_kept[b] < kept[j]) ++b;
    if (b < base_kept.size() && base_kept[b] == kept[j]) out[j] = static_cast<uint32_t>(b);
  }
  return out;
}

std::vector<uint32_t> ChangedGaussians(const Asset& before, const Asset& after, const std::vector<uint32_t>& base_of) {
  const Gaussians &a = before.gaussians, &b = after.gaussians;
  const size_t n = b.size();
  std::vector<uint32_t> changed;
  const bool comparable = a.sh_degree == b.sh_degree && before.textures.has_value() == after.textures.has_value() &&
                          a.has_time_windows() == b.has_time_windows() && base_of.size() == n;
  const size_t sh = 3 * static_cast<size_t>(b.sh_coeffs());
  for (size_t j = 0; j < n; ++j) {
    const uint32_t i = comparable ? base_of[j] : kNoBase;
    bool same = i != kNoBase && i < a.size() && SameSpan(a.positions, i, b.positions, j, 3) &&
                SameSpan(a.rotations, i, b.rotations, j, 4) && SameSpan(a.log_scales, i, b.log_scales, j, 3) &&
                SameSpan(a.opacity_logits, i, b.opacity_logits, j, 1) && SameSpan(a.sh, i, b.sh, j, sh) &&
                (!b.has_time_windows() || SameSpan(a.time_windows, i, b.time_windows, j, 2));
    if (same && after.textures) {
      const TexturePool &ta = *before.textures, &tb = *after.textures;
      same = ta.heights[i] == tb.heights[j] && ta.widths[i] == tb.widths[j] && ta.axis_u[i] == tb.axis_u[j] &&
             ta.axis_v[i] == tb.axis_v[j] &&
             std::memcmp(ta.texels.data() + ta.offsets[i] * 4, tb.texels.data() + tb.offsets[j] * 4,
                         (tb.offsets[j + 1] - tb.offsets[j]) * 4 * sizeof(float)) == 0;
    }
    if (!same) changed.push_back(static_cast<uint32_t>(j));
  }
  return changed;
}

}  // namespace atex::fit::internal
