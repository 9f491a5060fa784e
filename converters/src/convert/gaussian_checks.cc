#include "convert/gaussian_checks.h"

#include <cmath>
#include <vector>

namespace atex::converters {

namespace {

Status CheckSize(std::string_view what, const char* name, size_t actual, size_t expected) {
  if (actual == expected) return Status::Ok();
  return MakeError(StatusCode::kInvalidArgument, what, ": array '", name, "' has ", actual, " values, expected ",
                   expected);
}

Status CheckFinite(std::string_view what, const char* name, const std::vector<float>& values, size_t per_item) {
  for (size_t i = 0; i < values.size(); ++i) {
    if (!std::isfinite(values[i])) {
      return MakeError(StatusCode::kOutOfRange, what, ": ", name, " of Gaussian ", i / per_item, " (component ",
                       i % per_item, ") is not finite (", values[i], ")");
    }
  }
  return Status::Ok();
}

}  // namespace

Status CheckGaussianShapes(const Gaussians& g, std::string_view what) {
  if (g.sh_degree < 0 || g.sh_degree > kMaxShDegree) {
    return MakeError(StatusCode::kInvalidArgument, what, ": SH degree ", g.sh_degree, " outside 0..", kMaxShDegree);
  }
  const size_t n = g.size();
  ATEX_RETURN_IF_ERROR(CheckSize(what, "positions", g.positions.size(), n * 3));
  ATEX_RETURN_IF_ERROR(CheckSize(what, "rotations", g.rotations.size(), n * 4));
  ATEX_RETURN_IF_ERROR(CheckSize(what, "log_scales", g.log_scales.size(), n * 3));
  ATEX_RETURN_IF_ERROR(CheckSize(what, "sh", g.sh.size(), n * static_cast<size_t>(g.sh_coeffs()) * 3));
  return Status::Ok();
}

Status CheckGaussiansFinite(const Gaussians& g, std::string_view what) {
  ATEX_RETURN_IF_ERROR(CheckFinite(what, "position", g.positions, 3));
  ATEX_RETURN_IF_ERROR(CheckFinite(what, "rotation", g.rotations, 4));
  ATEX_RETURN_IF_ERROR(CheckFinite(what, "log_scale", g.log_scales, 3));
  ATEX_RETURN_IF_ERROR(CheckFinite(what, "opacity_logit", g.opacity_logits, 1));
  ATEX_RETURN_IF_ERROR(CheckFinite(what, "sh", g.sh, static_cast<size_t>(g.sh_coeffs()) * 3));
  return Status::Ok();
}

}  // namespace atex::converters
