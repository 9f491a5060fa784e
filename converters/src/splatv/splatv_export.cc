// Asset -> .splatv: sample the deformation, fit closed-form motion per Gaussian,
// pack, and measure the error of what was stored (three passes over the samples so
// that memory stays O(N), not O(N x samples x parameters)).
#include <algorithm>
#include <cmath>
#include <limits>

#include "atex/converters/splatv.h"
#include "atex/deform.h"
#include "atex/file_io.h"
#include "atex/metrics.h"
#include "atex/render.h"
#include "splatv/half.h"
#include "splatv/motion_fit.h"
#include "splatv/splatv_format.h"

namespace atex {
namespace {

constexpr double kShC0 = 0.28209479177387814;
constexpr float kHalfMax = 65504.0f;

float ClampHalf(double v) { return float(std::clamp(v, -double(kHalfMax), double(kHalfMax))); }
float RoundHalf(double v) { return splatv::HalfToFloat(splatv::FloatToHalf(ClampHalf(v))); }
double Sigmoid(double x) { return 1.0 / (1.0 + std::exp(-x)); }

struct Bounds {
  std::array<double, 3> lo, hi;
  double diagonal() const {
    double s = 0;
    for (int k = 0; k < 3; ++k) s += (hi[k] - lo[k]) * (hi[k] - lo[k]);
    return std::sqrt(s);
  }
};

Bounds PositionBounds(const Gaussians& g) {
  Bounds b;
  b.lo.fill(std::numeric_limits<double>::infinity());
  b.hi.fill(-std::numeric_limits<double>::infinity());
  for (size_t i = 0; i < g.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      b.lo[k] = std::min(b.lo[k], double(g.positions[i * 3 + k]));
      b.hi[k] = std::max(b.hi[k], double(g.positions[i * 3 + k]));
    }
  }
  return b;
}

// A camera that frames the bounds, looking horizontally with `up` up (OpenCV axes).
SplatvCamera DefaultCamera(const Bounds& b, UpAxis up) {
  std::array<double, 3> down{0, 1, 0}, forward{0, 0, 1};  // kNegY unless changed below
  switch (up) {
    case UpAxis::kNegY: down = {0, 1, 0}, forward = {0, 0, 1}; break;
    case UpAxis::kPosY: down = {0, -1, 0}, forward = {0, 0, -1}; break;
    case UpAxis::kPosZ: down = {0, 0, -1}, forward = {0, 1, 0}; break;
    case UpAxis::kNegZ: down = {0, 0, 1}, forward = {0, -1, 0}; break;
    case UpAxis::kPosX: down = {-1, 0, 0}, forward = {0, 0, 1}; break;
    case UpAxis::kNegX: down = {1, 0, 0}, forward = {0, 0, -1}; break;
  }
  const std::array<double, 3> right = {down[1] * forward[2] - down[2] * forward[1],
                                       down[2] * forward[0] - down[0] * forward[2],
                                       down[0] * forward[1] - down[1] * forward[0]};
  SplatvCamera c;
  const double distance = 1.5 * std::max(b.diagonal(), 1e-6);
  for (int k = 0; k < 3; ++k) {
    c.position[size_t(k)] = 0.5 * (b.lo[k] + b.hi[k]) - distance * forward[size_t(k)];
    // Camera-to-world rows: row k = (right_k, down_k, forward_k).
    c.rotation[size_t(k * 3 + 0)] = right[size_t(k)];
    c.rotation[size_t(k * 3 + 1)] = down[size_t(k)];
    c.rotation[size_t(k * 3 + 2)] = forward[size_t(k)];
  }
  return c;
}

nlohmann::json CameraJson(const SplatvCamera& c, size_t id) {
  const auto& r = c.rotation;
  return {{"id", id},
          {"img_name", c.name},
          {"width", c.width},
          {"height", c.height},
          {"position", c.position},
          {"rotation", {{r[0], r[1], r[2]}, {r[3], r[4], r[5]}, {r[6], r[7], r[8]}}},
          {"fx", c.fx},
          {"fy", c.fy}};
}

// Per-Gaussian fit state between passes.
struct FitState {
  std::vector<float> alpha;        // [N][S] deformed opacity (pass 1)
  std::vector<double> log_scale;   // [N][3] sum over samples (pass 1)
  std::vector<double> dc;          // [N][3] sum over samples (pass 1)
  std::vector<splatv::TemporalOpacity> opacity;  // [N]
  std::vector<double> position_rhs;  // [N][3 axes][4] sum of phi * x (pass 2)
  std::vector<double> position_sum;  // [N][3] sum of x (pass 2)
  std::vector<double> rotation_rhs;  // [N][4 components][2] sum of (1, dt) * q (pass 2)
  std::vector<float> previous_q;     // [N][4] last sign-aligned unit quaternion (pass 2)
};

atex::Camera ToCamera(const SplatvCamera& c) {
  atex::Camera camera;
  camera.width = c.width, camera.height = c.height;
  camera.fx = c.fx, camera.fy = c.fy, camera.cx = c.width / 2.0, camera.cy = c.height / 2.0;  // the viewer's model
  const auto& r = c.rotation;  // camera-to-world rows: world-to-camera is [R^T | -R^T c]
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) camera.world_to_camera[size_t(i * 4 + j)] = r[size_t(j * 3 + i)];
    camera.world_to_camera[size_t(i * 4 + 3)] =
        -(r[size_t(i)] * c.position[0] + r[size_t(3 + i)] * c.position[1] + r[size_t(6 + i)] * c.position[2]);
  }
  return camera;
}

// The Gaussians the viewer draws at time u, in our parameters (DC colour only).
Gaussians BakedGaussians(const SplatvFile& file, size_t n, double u) {
  Gaussians g;
  g.sh_degree = 0;
  g.Resize(n);
  for (size_t i = 0; i < n; ++i) {
    const SplatvSample s = EvaluateSplatv(file, i, u);
    for (int k = 0; k < 3; ++k) {
      g.positions[i * 3 + size_t(k)] = s.position[size_t(k)];
      g.log_scales[i * 3 + size_t(k)] = float(std::log(std::max(double(s.scale[size_t(k)]), 1e-30)));
      g.sh[i * 3 + size_t(k)] = float((s.rgba[size_t(k)] / 255.0 - 0.5) / kShC0);
    }
    for (int k = 0; k < 4; ++k) g.rotations[i * 4 + size_t(k)] = s.rotation[size_t(k)];
    const double o = std::clamp(double(s.opacity), 1e-9, 1 - 1e-7);
    g.opacity_logits[i] = float(std::log(o / (1 - o)));
  }
  return g;
}

Gaussians DcOnly(const Gaussians& g) {
  Gaussians out = g;
  out.sh_degree = 0;
  out.sh.resize(g.size() * 3);
  const size_t k = size_t(g.sh_coeffs());
  for (size_t i = 0; i < g.size(); ++i) {
    for (int c = 0; c < 3; ++c) out.sh[i * 3 + size_t(c)] = g.sh[i * k * 3 + size_t(c)];
  }
  return out;
}

StatusOr<Image> Render(const atex::Camera& camera, const Gaussians& g, const TexturePool* textures,
                       const std::array<float, 3>& background) {
  RenderSettings settings;
  settings.background = background;
  ATEX_ASSIGN_OR_RETURN(RenderOutput out, RenderForward(camera, g, textures, settings));
  Image image = RenderedImage(out);
  for (float& v : image.pixels) v = std::clamp(v, 0.0f, 1.0f);
  return image;
}

}  // namespace

nlohmann::json SplatvFitReport::ToJson() const {
  return {{"gaussians", gaussians},
          {"samples", samples},
          {"scene_extent", scene_extent},
          {"position_rms", position_rms},
          {"position_rms_relative", position_rms_relative},
          {"position_max_relative", position_max_relative},
          {"rotation_rms_deg", rotation_rms_deg},
          {"rotation_max_deg", rotation_max_deg},
          {"opacity_rms", opacity_rms},
          {"opacity_max", opacity_max},
          {"log_scale_rms", log_scale_rms},
          {"motion_rms_relative", motion_rms_relative},
          {"psnr_full_db", psnr_full_db},
          {"psnr_motion_db", psnr_motion_db},
          {"psnr_frames", psnr_frames}};
}

StatusOr<SplatvResult> EncodeSplatv(const Asset& asset, const SplatvOptions& options) {
  ATEX_RETURN_IF_ERROR(ValidateAsset(asset));
  const Gaussians& canonical = asset.gaussians;
  const size_t n = canonical.size();
  if (n == 0) return MakeError(StatusCode::kInvalidArgument, "splatv export: the asset has no Gaussians");
  if (options.samples < 4 || options.samples > 100000) {
    return MakeError(StatusCode::kInvalidArgument, "splatv export: samples = ", options.samples, " (need 4 .. 100000)");
  }
  const bool moving = asset.deformation.has_value();
  const size_t samples = moving ? size_t(options.samples) : 1;
  std::vector<double> u(samples);  // viewer time of each sample
  for (size_t j = 0; j < samples; ++j) u[j] = samples == 1 ? 0.5 : double(j) / double(samples - 1);
  const double t0 = asset.metadata.time_min, t1 = asset.metadata.time_max;
  const size_t k_count = size_t(canonical.sh_coeffs());

  // The deformed Gaussians at sample j.
  Gaussians deformed;
  auto sample = [&](size_t j) -> StatusOr<const Gaussians*> {
    if (!moving) return &canonical;
    const double t = t0 + u[j] * (t1 - t0);
    if (options.deform) {
      ATEX_RETURN_IF_ERROR(options.deform(asset, t, &deformed));
    } else {
      ATEX_RETURN_IF_ERROR(DeformForward(*asset.deformation, canonical, t, &deformed, nullptr));
    }
    if (deformed.size() != n || deformed.sh_coeffs() != canonical.sh_coeffs()) {
      return MakeError(StatusCode::kInternal, "deformation changed the Gaussian count or SH degree");
    }
    return &deformed;
  };
  size_t step = 0;
  const size_t total_steps = 3 * samples;
  auto progress = [&]() -> Status {
    ++step;
    if (options.progress && !options.progress(double(step) / double(total_steps))) {
      return MakeError(StatusCode::kCancelled, "splatv export cancelled");
    }
    return Status::Ok();
  };

  // Pass 1: opacity over time, mean log-scale and mean DC colour.
  FitState s;
  s.alpha.resize(n * samples);
  s.log_scale.assign(n * 3, 0.0);
  s.dc.assign(n * 3, 0.0);
  for (size_t j = 0; j < samples; ++j) {
    ATEX_ASSIGN_OR_RETURN(const Gaussians* g, sample(j));
    for (size_t i = 0; i < n; ++i) {
      s.alpha[i * samples + j] = float(Sigmoid(g->opacity_logits[i]));
      for (int k = 0; k < 3; ++k) {
        s.log_scale[i * 3 + k] += g->log_scales[i * 3 + k];
        s.dc[i * 3 + k] += g->sh[i * k_count * 3 + k];
      }
    }
    ATEX_RETURN_IF_ERROR(progress());
  }
  s.opacity.resize(n);
  for (size_t i = 0; i < n; ++i) {
    s.opacity[i] = splatv::FitTemporalOpacity(u, &s.alpha[i * samples], samples);
    // Store what the file will hold, so that the motion is fitted around the stored centre.
    s.opacity[i].center = RoundHalf(s.opacity[i].center);
    s.opacity[i].width = RoundHalf(s.opacity[i].width);
  }

  // Pass 2: least-squares right-hand sides of the cubic position and linear rotation.
  s.position_rhs.assign(n * 12, 0.0);
  s.position_sum.assign(n * 3, 0.0);
  s.rotation_rhs.assign(n * 8, 0.0);
  s.previous_q.assign(n * 4, 0.0f);
  for (size_t j = 0; j < samples; ++j) {
    ATEX_ASSIGN_OR_RETURN(const Gaussians* g, sample(j));
    for (size_t i = 0; i < n; ++i) {
      const double dt = u[j] - s.opacity[i].center;
      const double phi[4] = {1, dt, dt * dt, dt * dt * dt};
      for (int k = 0; k < 3; ++k) {
        const double x = g->positions[i * 3 + k];
        s.position_sum[i * 3 + k] += x;
        for (int p = 0; p < 4; ++p) s.position_rhs[i * 12 + size_t(k * 4 + p)] += phi[p] * x;
      }
      const float* q = &g->rotations[i * 4];
      const double norm =
          std::sqrt(double(q[0]) * q[0] + double(q[1]) * q[1] + double(q[2]) * q[2] + double(q[3]) * q[3]);
      float unit[4] = {1, 0, 0, 0};
      if (norm > 0) {
        for (int k = 0; k < 4; ++k) unit[k] = float(q[k] / norm);
      }
      float* prev = &s.previous_q[i * 4];
      const double dot =
          double(unit[0]) * prev[0] + double(unit[1]) * prev[1] + double(unit[2]) * prev[2] + double(unit[3]) * prev[3];
      if (j > 0 && dot < 0) {
        for (float& c : unit) c = -c;  // q and -q are the same rotation: keep the path continuous
      }
      for (int k = 0; k < 4; ++k) {
        prev[k] = unit[k];
        s.rotation_rhs[i * 8 + size_t(k * 2 + 0)] += unit[k];
        s.rotation_rhs[i * 8 + size_t(k * 2 + 1)] += dt * unit[k];
      }
    }
    ATEX_RETURN_IF_ERROR(progress());
  }

  // Solve and pack.
  const size_t rows = (n + splatv::kGaussiansPerRow - 1) / splatv::kGaussiansPerRow;
  std::vector<uint32_t> words(rows * splatv::kGaussiansPerRow * 16, 0);
  for (size_t i = 0; i < n; ++i) {
    splatv::PackedGaussian p{};
    const splatv::TemporalOpacity& op = s.opacity[i];
    const std::array<double, 16> gram = splatv::CubicGram(u, op.center);
    for (int k = 0; k < 3; ++k) {
      double coef[4] = {s.position_sum[i * 3 + k] / double(samples), 0, 0, 0};
      if (samples >= 4 && !splatv::SolveCubic(gram, &s.position_rhs[i * 12 + size_t(k * 4)], coef)) {
        coef[0] = s.position_sum[i * 3 + k] / double(samples), coef[1] = coef[2] = coef[3] = 0;
      }
      // Round the motion to half first, then choose the f32 rest position that minimises the
      // squared error given the rounded motion (the mean residual).
      double motion_sum = 0;
      for (int d = 1; d <= 3; ++d) {
        const float m = RoundHalf(coef[d]);
        p.motion[(d - 1) * 3 + k] = m;
        for (size_t j = 0; j < samples; ++j) motion_sum += double(m) * std::pow(u[j] - op.center, d);
      }
      p.position[k] = float((s.position_sum[i * 3 + k] - motion_sum) / double(samples));
    }
    const std::array<double, 4> line = splatv::LineGram(u, op.center);
    for (int k = 0; k < 4; ++k) {
      double coef[2] = {s.rotation_rhs[i * 8 + size_t(k * 2)] / double(samples), 0};
      if (samples >= 2 && !splatv::SolveLine(line, &s.rotation_rhs[i * 8 + size_t(k * 2)], coef)) coef[1] = 0;
      p.rotation[k] = ClampHalf(coef[0]);
      p.omega[k] = ClampHalf(coef[1]);
    }
    for (int k = 0; k < 3; ++k) {
      p.scale[k] = ClampHalf(std::exp(s.log_scale[i * 3 + k] / double(samples)));
      const double colour = std::clamp(0.5 + kShC0 * s.dc[i * 3 + k] / double(samples), 0.0, 1.0);
      p.rgba[k] = uint8_t(std::lround(colour * 255));
    }
    p.rgba[3] = uint8_t(std::lround(std::clamp(op.peak, 0.0, 1.0) * 255));
    p.trbf_center = float(op.center);
    p.trbf_scale = float(op.width);
    splatv::PackGaussian(p, &words[i * 16]);
  }
  // Padding entries: never drawn (temporal opacity exp(-(u - 65504)^2) = 0 < 0.02).
  for (size_t i = n; i < rows * splatv::kGaussiansPerRow; ++i) words[i * 16 + 15] = splatv::PackHalf2(65504.0f, 1.0f);

  // The file.
  const Bounds bounds = PositionBounds(canonical);
  std::vector<SplatvCamera> cameras = options.cameras;
  if (cameras.empty()) {
    UpAxis up = UpAxis::kNegY;
    if (options.up) {
      up = *options.up;
    } else {
      auto from_metadata = UpAxisOf(asset.metadata);
      if (from_metadata.ok()) up = *from_metadata;
    }
    cameras.push_back(DefaultCamera(bounds, up));
  }
  nlohmann::json camera_list = nlohmann::json::array();
  for (size_t c = 0; c < cameras.size(); ++c) camera_list.push_back(CameraJson(cameras[c], c));

  // Pass 3: error of the stored values, evaluated as the viewer does.
  SplatvFitReport report;
  report.gaussians = n;
  report.samples = int(samples);
  report.scene_extent = std::max(bounds.diagonal(), 1e-12);
  SplatvFile file;
  file.count = n;
  file.words.assign(words.begin(), words.begin() + long(n * 16));
  double position_sq = 0, rotation_sq = 0, opacity_sq = 0, scale_sq = 0, motion_sq = 0;
  for (size_t j = 0; j < samples; ++j) {
    ATEX_ASSIGN_OR_RETURN(const Gaussians* g, sample(j));
    for (size_t i = 0; i < n; ++i) {
      const SplatvSample e = EvaluateSplatv(file, i, u[j]);
      double d2 = 0;
      for (int k = 0; k < 3; ++k) {
        const double d = double(e.position[size_t(k)]) - g->positions[i * 3 + k];
        d2 += d * d;
        const double ds = std::log(std::max(double(e.scale[size_t(k)]), 1e-30)) - g->log_scales[i * 3 + k];
        scale_sq += ds * ds;
      }
      position_sq += d2;
      for (int k = 0; k < 3; ++k) {
        const double m = g->positions[i * 3 + k] - s.position_sum[i * 3 + k] / double(samples);
        motion_sq += m * m;
      }
      report.position_max_relative = std::max(report.position_max_relative, std::sqrt(d2) / report.scene_extent);
      const float* q = &g->rotations[i * 4];
      const double norm =
          std::sqrt(double(q[0]) * q[0] + double(q[1]) * q[1] + double(q[2]) * q[2] + double(q[3]) * q[3]);
      double dot = 0;
      for (int k = 0; k < 4; ++k)
        dot += double(e.rotation[size_t(k)]) * (norm > 0 ? q[k] / norm : (k == 0 ? 1.0 : 0.0));
      const double angle = 2.0 * std::acos(std::min(1.0, std::abs(dot))) * 180.0 / M_PI;
      rotation_sq += angle * angle;
      report.rotation_max_deg = std::max(report.rotation_max_deg, angle);
      const double da = double(e.opacity) - Sigmoid(g->opacity_logits[i]);
      opacity_sq += da * da;
      report.opacity_max = std::max(report.opacity_max, std::abs(da));
    }
    ATEX_RETURN_IF_ERROR(progress());
  }
  const double count = double(n) * double(samples);
  report.position_rms = std::sqrt(position_sq / count);
  report.position_rms_relative = report.position_rms / report.scene_extent;
  report.rotation_rms_deg = std::sqrt(rotation_sq / count);
  report.opacity_rms = std::sqrt(opacity_sq / count);
  report.log_scale_rms = std::sqrt(scale_sq / (3 * count));
  report.motion_rms_relative = std::sqrt(motion_sq / count) / report.scene_extent;

  // Optional: the picture cost, with libatex's reference renderer.
  if (options.psnr_times > 0) {
    const atex::Camera camera = ToCamera(cameras[0]);
    double full = 0, motion = 0;
    const int frames = options.psnr_times;
    for (int f = 0; f < frames; ++f) {
      const double uf = frames == 1 ? 0.5 : double(f) / double(frames - 1);
      const double t = t0 + uf * (t1 - t0);
      Gaussians truth;
      if (!moving) {
        truth = canonical;
      } else if (options.deform) {
        ATEX_RETURN_IF_ERROR(options.deform(asset, t, &truth));
      } else {
        ATEX_RETURN_IF_ERROR(DeformForward(*asset.deformation, canonical, t, &truth, nullptr));
      }
      const auto& bg = asset.metadata.background;
      ATEX_ASSIGN_OR_RETURN(Image baked, Render(camera, BakedGaussians(file, n, uf), nullptr, bg));
      ATEX_ASSIGN_OR_RETURN(Image reference, Render(camera, truth, asset.textures ? &*asset.textures : nullptr, bg));
      ATEX_ASSIGN_OR_RETURN(Image reference_dc, Render(camera, DcOnly(truth), nullptr, bg));
      ATEX_ASSIGN_OR_RETURN(double p_full, Psnr(baked, reference));
      ATEX_ASSIGN_OR_RETURN(double p_motion, Psnr(baked, reference_dc));
      full += std::min(p_full, 99.0);
      motion += std::min(p_motion, 99.0);
    }
    report.psnr_full_db = full / frames;
    report.psnr_motion_db = motion / frames;
    report.psnr_frames = frames;
  }

  nlohmann::json chunk = {{"type", "splat"},
                          {"size", words.size() * 4},
                          {"texwidth", splatv::kTextureWidth},
                          {"texheight", rows},
                          {"cameras", camera_list},
                          {"atex", {{"version", 1},
                                    {"time_min", t0},
                                    {"time_max", t1},
                                    {"gaussians", n},
                                    {"fit", report.ToJson()}}}};
  SplatvResult result;
  result.bytes = splatv::AssembleFile(nlohmann::json::array({chunk}), words);
  result.report = report;
  return result;
}

Status WriteSplatvFile(const std::string& path, const Asset& asset, const SplatvOptions& options,
                       SplatvFitReport* report) {
  ATEX_ASSIGN_OR_RETURN(SplatvResult result, EncodeSplatv(asset, options));
  if (report != nullptr) *report = result.report;
  return WriteFileAtomic(path, result.bytes);
}

}  // namespace atex
