// Public entry points of the reference rasteriser: validation, the three stages,
// and the exception boundary (no exception leaves the library).
#include <algorithm>
#include <cmath>
#include <exception>
#include <new>

#include "atex/render.h"
#include "render/render_internal.h"

namespace atex {
namespace {

using render_internal::RasterGradients;

template <typename T>
Status ValidateInputs(const Camera& camera, const BasicGaussians<T>& gaussians, const BasicTexturePool<T>* textures,
                      const RenderSettings& settings) {
  ATEX_RETURN_IF_ERROR(render_internal::ValidateCamera(camera));
  ATEX_RETURN_IF_ERROR(render_internal::ValidateSettings(settings));
  ATEX_RETURN_IF_ERROR(render_internal::ValidateGaussians(gaussians));
  if (textures != nullptr) ATEX_RETURN_IF_ERROR(ValidateTexturePool(*textures, gaussians.size()));
  return Status::Ok();
}

// The forward result must be one RenderForward produced for these inputs: sizes and
// every index that the backward follows are checked, so a damaged one fails cleanly.
template <typename T>
Status ValidateForward(const detail::CameraModel<T>& cam, size_t n, bool textured, int sh_degree,
                       const BasicRenderOutput<T>& fwd) {
  const auto& st = fwd.state;
  const size_t pixels = size_t(cam.width) * size_t(cam.height);
  const size_t tiles = size_t(cam.tiles_x) * size_t(cam.tiles_y);
  const auto fail = [](const char* what) {
    return MakeError(StatusCode::kInvalidArgument, "render backward: the forward result does not match the inputs (",
                     what, ")");
  };
  if (fwd.width != cam.width || fwd.height != cam.height) return fail("image size");
  if (fwd.radius.size() != n || fwd.mean2d.size() != 2 * n || fwd.depth.size() != n) return fail("Gaussian count");
  if (st.textured != textured || st.sh_degree != sh_degree) return fail("textures or SH degree");
  if (st.tiles_x != cam.tiles_x || st.tiles_y != cam.tiles_y) return fail("tile grid");
  if (st.conic.size() != 3 * n || st.opacity.size() != n || st.color.size() != 3 * n ||
      st.frames.size() != (textured ? n : 0)) {
    return fail("per-Gaussian state");
  }
  if (st.final_transmittance.size() != pixels || st.contributor_end.size() != pixels) return fail("per-pixel state");
  const size_t entries = st.tile_gaussians.size();
  if (st.tile_ranges.size() != tiles + 1 || st.tile_ranges[0] != 0 || st.tile_ranges[tiles] != entries ||
      st.gaussian_entry_ranges.size() != n + 1 || st.gaussian_entry_ranges[0] != 0 ||
      st.gaussian_entry_ranges[n] != entries || st.gaussian_entries.size() != entries) {
    return fail("tile lists");
  }
  for (size_t t = 0; t < tiles; ++t) {
    if (st.tile_ranges[t + 1] < st.tile_ranges[t]) return fail("tile ranges");
  }
  for (size_t i = 0; i < n; ++i) {
    if (st.gaussian_entry_ranges[i + 1] < st.gaussian_entry_ranges[i]) return fail("Gaussian entry ranges");
  }
  for (size_t e = 0; e < entries; ++e) {
    if (st.tile_gaussians[e] < 0 || size_t(st.tile_gaussians[e]) >= n || fwd.radius[st.tile_gaussians[e]] <= 0) {
      return fail("tile entry");
    }
    if (st.gaussian_entries[e] >= entries) return fail("Gaussian entry");
  }
  for (int y = 0; y < cam.height; ++y) {
    for (int x = 0; x < cam.width; ++x) {
      const size_t t = size_t(y / detail::kTileSize) * cam.tiles_x + x / detail::kTileSize;
      const int32_t end = st.contributor_end[size_t(y) * cam.width + x];
      if (end < 0 || uint64_t(end) > st.tile_ranges[t + 1] - st.tile_ranges[t]) return fail("contributor count");
      const T tr = st.final_transmittance[size_t(y) * cam.width + x];
      if (!(tr >= T(0) && tr <= T(1))) return fail("final transmittance");
    }
  }
  return Status::Ok();
}

Status OutOfMemory(const char* where) {
  return MakeError(StatusCode::kLimitExceeded, where, ": out of memory");
}

}  // namespace

template <typename T>
StatusOr<BasicRenderOutput<T>> RenderForward(const Camera& camera, const BasicGaussians<T>& gaussians,
                                             const BasicTexturePool<std::type_identity_t<T>>* textures,
                                             const RenderSettings& settings) {
  try {
    ATEX_RETURN_IF_ERROR(ValidateInputs(camera, gaussians, textures, settings));
    const auto cam = detail::MakeCameraModel<T>(camera, settings.near_plane);
    const int sh_degree = std::min(settings.active_sh_degree, gaussians.sh_degree);
    BasicRenderOutput<T> out;
    ATEX_RETURN_IF_ERROR(render_internal::BuildRenderState(cam, gaussians, textures, sh_degree, &out));
    render_internal::RasterizeForward(cam, textures, settings, &out);
    return out;
  } catch (const std::bad_alloc&) {
    return OutOfMemory("render forward");
  } catch (const std::exception& e) {
    return MakeError(StatusCode::kInternal, "render forward: ", e.what());
  }
}

template <typename T>
Status RenderBackward(const Camera& camera, const BasicGaussians<T>& gaussians,
                      const BasicTexturePool<std::type_identity_t<T>>* textures, const RenderSettings& settings,
                      const BasicRenderOutput<T>& forward, const std::type_identity_t<T>* grad_color,
                      const std::type_identity_t<T>* grad_alpha, BasicRenderGradients<T>* out) {
  try {
    if (out == nullptr) return MakeError(StatusCode::kInvalidArgument, "render backward: no output");
    if (grad_color == nullptr) return MakeError(StatusCode::kInvalidArgument, "render backward: grad_color is null");
    ATEX_RETURN_IF_ERROR(ValidateInputs(camera, gaussians, textures, settings));
    const auto cam = detail::MakeCameraModel<T>(camera, settings.near_plane);
    const int sh_degree = std::min(settings.active_sh_degree, gaussians.sh_degree);
    ATEX_RETURN_IF_ERROR(ValidateForward(cam, gaussians.size(), textures != nullptr, sh_degree, forward));
    const size_t pixels = size_t(camera.width) * size_t(camera.height);
    for (size_t k = 0; k < pixels * 3; ++k) {
      if (!std::isfinite(grad_color[k])) {
        return MakeError(StatusCode::kOutOfRange, "render backward: grad_color of pixel ", k / 3, " channel ", k % 3,
                         " is not finite");
      }
    }
    if (grad_alpha != nullptr) {
      for (size_t k = 0; k < pixels; ++k) {
        if (!std::isfinite(grad_alpha[k])) {
          return MakeError(StatusCode::kOutOfRange, "render backward: grad_alpha of pixel ", k, " is not finite");
        }
      }
    }
    const size_t n = gaussians.size();
    out->gaussians = BasicGaussians<T>();
    out->gaussians.sh_degree = gaussians.sh_degree;
    out->gaussians.Resize(n);
    out->mean2d.assign(2 * n, T(0));
    RasterGradients<T> raster;
    ATEX_RETURN_IF_ERROR(
        render_internal::RasterizeBackward(cam, textures, settings, forward, grad_color, grad_alpha, &raster));
    render_internal::ProjectionBackward(cam, gaussians, textures, forward, raster, out);
    out->texels = std::move(raster.texels);
    return Status::Ok();
  } catch (const std::bad_alloc&) {
    return OutOfMemory("render backward");
  } catch (const std::exception& e) {
    return MakeError(StatusCode::kInternal, "render backward: ", e.what());
  }
}

Image RenderedImage(const RenderOutput& output) {
  Image image;
  image.width = output.width;
  image.height = output.height;
  image.channels = 3;
  image.pixels = output.color;
  return image;
}

std::string_view TextureModeName(TextureMode mode) {
  switch (mode) {
    case TextureMode::kUniform: return "uniform";
    case TextureMode::kAdaptive: return "adaptive";
    default: return "none";
  }
}

StatusOr<TextureMode> ParseTextureMode(std::string_view name) {
  if (name == "none") return TextureMode::kNone;
  if (name == "uniform") return TextureMode::kUniform;
  if (name == "adaptive") return TextureMode::kAdaptive;
  return MakeError(StatusCode::kInvalidArgument, "unknown texture mode '", name,
                   "' (expected none, uniform or adaptive)");
}

#define ATEX_INSTANTIATE(T)                                                                                     \
  template StatusOr<BasicRenderOutput<T>> RenderForward(const Camera&, const BasicGaussians<T>&,               \
                                                        const BasicTexturePool<T>*, const RenderSettings&);     \
  template Status RenderBackward(const Camera&, const BasicGaussians<T>&, const BasicTexturePool<T>*,           \
                                 const RenderSettings&, const BasicRenderOutput<T>&, const T*, const T*,        \
                                 BasicRenderGradients<T>*);
ATEX_INSTANTIATE(float)
ATEX_INSTANTIATE(double)
#undef ATEX_INSTANTIATE

}  // namespace atex
