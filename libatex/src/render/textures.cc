// Texture pools: attachment (axes from the canonical scales) and resizing by
// corner-aligned bilinear resampling (conventions §5).
#include <algorithm>
#include <array>
#include <cmath>
#include <exception>
#include <new>

#include "atex/detail/texture.h"
#include "atex/render.h"

namespace atex {
namespace {

bool ValidSide(int side) { return side == 1 || side == 2 || side == 4; }

}  // namespace

template <typename T>
StatusOr<BasicTexturePool<T>> AttachTextures(const BasicGaussians<T>& canonical, TextureMode mode) {
  if (mode == TextureMode::kNone) {
    return MakeError(StatusCode::kInvalidArgument, "attach textures: mode 'none' attaches no texture pool");
  }
  if (mode != TextureMode::kUniform && mode != TextureMode::kAdaptive) {
    return MakeError(StatusCode::kInvalidArgument, "attach textures: unknown mode ", static_cast<int>(mode));
  }
  const size_t n = canonical.size();
  if (canonical.log_scales.size() != 3 * n) {
    return MakeError(StatusCode::kInvalidArgument, "attach textures: log_scales has ", canonical.log_scales.size(),
                     " values, expected ", 3 * n);
  }
  try {
    const uint8_t side = mode == TextureMode::kUniform ? 4 : 1;
    BasicTexturePool<T> pool;
    pool.heights.assign(n, side);
    pool.widths.assign(n, side);
    pool.axis_u.resize(n);
    pool.axis_v.resize(n);
    for (size_t i = 0; i < n; ++i) {
      const T* s = &canonical.log_scales[3 * i];
      for (int k = 0; k < 3; ++k) {
        if (!std::isfinite(s[k])) {
          return MakeError(StatusCode::kOutOfRange, "attach textures: log_scale of element ", i, " (component ", k,
                           ") is not finite");
        }
      }
      // Descending scale; the stable sort keeps the lower index first on ties.
      std::array<uint8_t, 3> axes{0, 1, 2};
      std::stable_sort(axes.begin(), axes.end(), [s](uint8_t a, uint8_t b) { return s[a] > s[b]; });
      pool.axis_u[i] = axes[0];
      pool.axis_v[i] = axes[1];
    }
    pool.RebuildOffsets();
    pool.texels.assign(pool.texel_count() * kTexelChannels, T(0));
    return pool;
  } catch (const std::bad_alloc&) {
    return MakeError(StatusCode::kLimitExceeded, "attach textures: out of memory for ", n, " Gaussians");
  }
}

template <typename T>
StatusOr<BasicTexturePool<T>> ResizeTextures(const BasicTexturePool<T>& pool, std::span<const uint8_t> new_heights,
                                             std::span<const uint8_t> new_widths,
                                             std::span<std::vector<T>* const> extra) {
  const size_t n = pool.size();
  ATEX_RETURN_IF_ERROR(ValidateTexturePool(pool, n));
  if (new_heights.size() != n || new_widths.size() != n) {
    return MakeError(StatusCode::kInvalidArgument, "resize textures: ", new_heights.size(), " heights and ",
                     new_widths.size(), " widths for ", n, " Gaussians");
  }
  for (size_t i = 0; i < n; ++i) {
    if (!ValidSide(new_heights[i]) || !ValidSide(new_widths[i])) {
      return MakeError(StatusCode::kOutOfRange, "resize textures: element ", i, " gets size ", int(new_heights[i]),
                       "x", int(new_widths[i]), " (each side must be 1, 2 or 4)");
    }
  }
  for (size_t k = 0; k < extra.size(); ++k) {
    if (extra[k] == nullptr || extra[k]->size() != pool.texels.size()) {
      return MakeError(StatusCode::kInvalidArgument, "resize textures: extra array ", k, " has ",
                       extra[k] == nullptr ? 0 : extra[k]->size(), " values, expected ", pool.texels.size());
    }
  }
  try {
    BasicTexturePool<T> out;
    out.heights.assign(new_heights.begin(), new_heights.end());
    out.widths.assign(new_widths.begin(), new_widths.end());
    out.axis_u = pool.axis_u;
    out.axis_v = pool.axis_v;
    out.RebuildOffsets();
    const auto resample = [&](const std::vector<T>& src, std::vector<T>* dst) {
      dst->assign(out.texel_count() * kTexelChannels, T(0));
      for (size_t i = 0; i < n; ++i) {
        detail::UpsampleTexture(src.data() + pool.offsets[i] * kTexelChannels, pool.heights[i], pool.widths[i],
                                dst->data() + out.offsets[i] * kTexelChannels, out.heights[i], out.widths[i],
                                kTexelChannels);
      }
    };
    resample(pool.texels, &out.texels);
    for (std::vector<T>* array : extra) {
      std::vector<T> resized;
      resample(*array, &resized);
      *array = std::move(resized);
    }
    return out;
  } catch (const std::bad_alloc&) {
    return MakeError(StatusCode::kLimitExceeded, "resize textures: out of memory for ", n, " Gaussians");
  }
}

#define ATEX_INSTANTIATE(T)                                                                                    \
  template StatusOr<BasicTexturePool<T>> AttachTextures(const BasicGaussians<T>&, TextureMode);              \
  template StatusOr<BasicTexturePool<T>> ResizeTextures(const BasicTexturePool<T>&, std::span<const uint8_t>, \
                                                        std::span<const uint8_t>, std::span<std::vector<T>* const>);
ATEX_INSTANTIATE(float)
ATEX_INSTANTIATE(double)
#undef ATEX_INSTANTIATE

}  // namespace atex
