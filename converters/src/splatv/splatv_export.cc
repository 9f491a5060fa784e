// Asset -> .splatv: sample the deformation, fit closed-form motion per Gaussian,
// pack, and measure the error of what was stored (three passes over the samples so
// that memory stays O(N), not O(N x samples x parameters)).
#include <algorithm>
#include <cmath>

#include "atex/converters/splatv.h"
#include "atex/deform.h"
#include "atex/file_io.h"
#include "atex/metrics.h"
#include "atex/render.h"
#include "splatv/half.h"
#include "splatv/motion_fit.h"
#include "splatv/splatv_camera.h"
#include "splatv/splatv_format.h"

namespace atex {
namespace {

constexpr double kShC0 = 0.28209479177387814;
constexpr float kHalfMax = 65504.0f;

float ClampHalf(double v) { return float(std::clamp(v, -double(kHalfMax), double(kHalfMax))); }
float RoundHalf(double v) { return splatv::HalfToFloat(splatv::FloatToHalf(ClampHalf(v))); }
double Sigmoid(double x) { return 1.0 / (1.0 + std::exp(-x)); }

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

// The deformation at scene time t: options.deform when given, else libatex's DeformForward.
Status DeformAt(const Asset& asset, const SplatvOptions& options, double t, Gaussians* out) {
  if (options.deform) return options.deform(asset, t, out);
  return DeformForward(*asset.deformation, asset.gaussians, t, out, nullptr);
}

// The sample times and the Gaussians deformed to each. The three passes over the samples deform
// again rather than keep N x samples values, so that memory stays O(N); the progress counts the
// samples of all three passes.
class DeformationSamples {
 public:
  DeformationSamples(const Asset& asset, const SplatvOptions& options)
      : asset_(asset),
        options_(options),
        moving_(asset.deformation.has_value()) {
    const size_t samples = moving_ ? size_t(options.samples) : 1;
    u_.resize(samples);
    for (size_t j = 0; j < samples; ++j) u_[j] = samples == 1 ? 0.5 : double(j) / double(samples - 1);
    total_steps_ = 3 * samples;
  }

  const std::vector<double>& u() const { return u_; }  // the viewer time of each sample
  size_t count() const { return u_.size(); }

  // The Gaussians at sample j (valid until the next call).
  StatusOr<const Gaussians*> At(size_t j) {
    const Gaussians& canonical = asset_.gaussians;
    if (!moving_) return &canonical;
    const double t0 = asset_.metadata.time_min, t1 = asset_.metadata.time_max;
    const double t = t0 + u_[j] * (t1 - t0);
    ATEX_RETURN_IF_ERROR(DeformAt(asset_, options_, t, &deformed_));
    if (deformed_.size() != canonical.size() || deformed_.sh_coeffs() != canonical.sh_coeffs()) {
      return MakeError(StatusCode::kInternal, "deformation changed the Gaussian count or SH degree");
    }
    return &deformed_;
  }

  // One sample of one pass is done; kCancelled when the progress callback says stop.
  Status Step() {
    ++step_;
    if (options_.progress && !options_.progress(double(step_) / double(total_steps_))) {
      return MakeError(StatusCode::kCancelled, "splatv export cancelled");
    }
    return Status::Ok();
  }

 private:
  const Asset& asset_;
  const SplatvOptions& options_;
  bool moving_;
  std::vector<double> u_;
  Gaussians deformed_;
  size_t step_ = 0, total_steps_ = 0;
};

// Pass 1: opacity over time, mean log-scale and mean DC colour, then each Gaussian's temporal
// opacity.
Status FitOpacityScaleColour(DeformationSamples& samples, size_t n, size_t k_count, FitState* s) {
  const size_t count = samples.count();
  s->alpha.resize(n * count);
  s->log_scale.assign(n * 3, 0.0);
  s->dc.assign(n * 3, 0.0);
  for (size_t j = 0; j < count; ++j) {
    ATEX_ASSIGN_OR_RETURN(const Gaussians* g, samples.At(j));
    for (size_t i = 0; i < n; ++i) {
      s->alpha[i * count + j] = float(Sigmoid(g->opacity_logits[i]));
      for (int k = 0; k < 3; ++k) {
        s->log_scale[i * 3 + k] += g->log_scales[i * 3 + k];
        s->dc[i * 3 + k] += g->sh[i * k_count * 3 + k];
      }
    }
    ATEX_RETURN_IF_ERROR(samples.Step());
  }
  s->opacity.resize(n);
  for (size_t i = 0; i < n; ++i) {
    s->opacity[i] = splatv::FitTemporalOpacity(samples.u(), &s->alpha[i * count], count);
    // Store what the file will hold, so that the motion is fitted around the stored centre.
    s->opacity[i].center = RoundHalf(s->opacity[i].center);
    s->opacity[i].width = RoundHalf(s->opacity[i].width);
  }
  return Status::Ok();
}

// Pass 2: least-squares right-hand sides of the cubic position and linear rotation, around each
// Gaussian's temporal centre (pass 1).
Status AccumulateMotion(DeformationSamples& samples, size_t n, FitState* s) {
  s->position_rhs.assign(n * 12, 0.0);
  s->position_sum.assign(n * 3, 0.0);
  s->rotation_rhs.assign(n * 8, 0.0);
  s->previous_q.assign(n * 4, 0.0f);
  for (size_t j = 0; j < samples.count(); ++j) {
    ATEX_ASSIGN_OR_RETURN(const Gaussians* g, samples.At(j));
    for (size_t i = 0; i < n; ++i) {
      const double dt = samples.u()[j] - s->opacity[i].center;
      const double phi[4] = {1, dt, dt * dt, dt * dt * dt};
      for (int k = 0; k < 3; ++k) {
        const double x = g->positions[i * 3 + k];
        s->position_sum[i * 3 + k] += x;
        for (int p = 0; p < 4; ++p) s->position_rhs[i * 12 + size_t(k * 4 + p)] += phi[p] * x;
      }
      const float* q = &g->rotations[i * 4];
      const double norm =
          std::sqrt(double(q[0]) * q[0] + double(q[1]) * q[1] + double(q[2]) * q[2] + double(q[3]) * q[3]);
      float unit[4] = {1, 0, 0, 0};
      if (norm > 0) {
        for (int k = 0; k < 4; ++k) unit[k] = float(q[k] / norm);
      }
      float* prev = &s->previous_q[i * 4];
      const double dot =
          double(unit[0]) * prev[0] + double(unit[1]) * prev[1] + double(unit[2]) * prev[2] + double(unit[3]) * prev[3];
      if (j > 0 && dot < 0) {
        for (float& c : unit) c = -c;  // q and -q are the same rotation: keep the path continuous
      }
      for (int k = 0; k < 4; ++k) {
        prev[k] = unit[k];
        s->rotation_rhs[i * 8 + size_t(k * 2 + 0)] += unit[k];
        s->rotation_rhs[i * 8 + size_t(k * 2 + 1)] += dt * unit[k];
      }
    }
    ATEX_RETURN_IF_ERROR(samples.Step());
  }
  return Status::Ok();
}

// Gaussian i as stored: its motion solved from the sums of passes 1 and 2, with half-precision
// rounding where the file has half precision.
splatv::PackedGaussian SolveGaussian(const std::vector<double>& u, const FitState& s, size_t i) {
  const size_t samples = u.size();
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
  return p;
}

// The texture words of all n Gaussians, whole rows of kGaussiansPerRow.
std::vector<uint32_t> PackTexture(const std::vector<double>& u, const FitState& s, size_t n) {
  const size_t rows = (n + splatv::kGaussiansPerRow - 1) / splatv::kGaussiansPerRow;
  std::vector<uint32_t> words(rows * splatv::kGaussiansPerRow * 16, 0);
  for (size_t i = 0; i < n; ++i) splatv::PackGaussian(SolveGaussian(u, s, i), &words[i * 16]);
  // Padding entries: never drawn (temporal opacity exp(-(u - 65504)^2) = 0 < 0.02).
  for (size_t i = n; i < rows * splatv::kGaussiansPerRow; ++i) words[i * 16 + 15] = splatv::PackHalf2(65504.0f, 1.0f);
  return words;
}

// Pass 3: the error of the stored values, evaluated as the viewer does, relative to
// report->scene_extent (set by the caller).
Status MeasureStoredError(DeformationSamples& samples, const SplatvFile& file, const FitState& s,
                          SplatvFitReport* report) {
  const size_t n = file.count;
  const std::vector<double>& u = samples.u();
  double position_sq = 0, rotation_sq = 0, opacity_sq = 0, scale_sq = 0, motion_sq = 0;
  for (size_t j = 0; j < samples.count(); ++j) {
    ATEX_ASSIGN_OR_RETURN(const Gaussians* g, samples.At(j));
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
        const double m = g->positions[i * 3 + k] - s.position_sum[i * 3 + k] / double(samples.count());
        motion_sq += m * m;
      }
      report->position_max_relative = std::max(report->position_max_relative, std::sqrt(d2) / report->scene_extent);
      const float* q = &g->rotations[i * 4];
      const double norm =
          std::sqrt(double(q[0]) * q[0] + double(q[1]) * q[1] + double(q[2]) * q[2] + double(q[3]) * q[3]);
      double dot = 0;
      for (int k = 0; k < 4; ++k)
        dot += double(e.rotation[size_t(k)]) * (norm > 0 ? q[k] / norm : (k == 0 ? 1.0 : 0.0));
      const double angle = 2.0 * std::acos(std::min(1.0, std::abs(dot))) * 180.0 / M_PI;
      rotation_sq += angle * angle;
      report->rotation_max_deg = std::max(report->rotation_max_deg, angle);
      const double da = double(e.opacity) - Sigmoid(g->opacity_logits[i]);
      opacity_sq += da * da;
      report->opacity_max = std::max(report->opacity_max, std::abs(da));
    }
    ATEX_RETURN_IF_ERROR(samples.Step());
  }
  const double count = double(n) * double(samples.count());
  report->position_rms = std::sqrt(position_sq / count);
  report->position_rms_relative = report->position_rms / report->scene_extent;
  report->rotation_rms_deg = std::sqrt(rotation_sq / count);
  report->opacity_rms = std::sqrt(opacity_sq / count);
  report->log_scale_rms = std::sqrt(scale_sq / (3 * count));
  report->motion_rms_relative = std::sqrt(motion_sq / count) / report->scene_extent;
  return Status::Ok();
}

// The picture cost of the bake: PSNR of the stored file against the asset at options.psnr_times
// times, rendered from `view` by libatex's reference renderer.
Status MeasurePictureCost(const Asset& asset, const SplatvOptions& options, const SplatvCamera& view,
                          const SplatvFile& file, SplatvFitReport* report) {
  const atex::Camera camera = splatv::ToCamera(view);
  const double t0 = asset.metadata.time_min, t1 = asset.metadata.time_max;
  double full = 0, motion = 0;
  const int frames = options.psnr_times;
  for (int f = 0; f < frames; ++f) {
    const double uf = frames == 1 ? 0.5 : double(f) / double(frames - 1);
    const double t = t0 + uf * (t1 - t0);
    Gaussians truth;
    if (!asset.deformation.has_value()) {
      truth = asset.gaussians;
    } else {
      ATEX_RETURN_IF_ERROR(DeformAt(asset, options, t, &truth));
    }
    const auto& bg = asset.metadata.background;
    ATEX_ASSIGN_OR_RETURN(Image baked, Render(camera, BakedGaussians(file, file.count, uf), nullptr, bg));
    ATEX_ASSIGN_OR_RETURN(Image reference, Render(camera, truth, asset.textures ? &*asset.textures : nullptr, bg));
    ATEX_ASSIGN_OR_RETURN(Image reference_dc, Render(camera, DcOnly(truth), nullptr, bg));
    ATEX_ASSIGN_OR_RETURN(double p_full, Psnr(baked, reference));
    ATEX_ASSIGN_OR_RETURN(double p_motion, Psnr(baked, reference_dc));
    full += std::min(p_full, 99.0);
    motion += std::min(p_motion, 99.0);
  }
  report->psnr_full_db = full / frames;
  report->psnr_motion_db = motion / frames;
  report->psnr_frames = frames;
  return Status::Ok();
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
  DeformationSamples samples(asset, options);
  FitState s;
  ATEX_RETURN_IF_ERROR(FitOpacityScaleColour(samples, n, size_t(canonical.sh_coeffs()), &s));
  ATEX_RETURN_IF_ERROR(AccumulateMotion(samples, n, &s));
  const std::vector<uint32_t> words = PackTexture(samples.u(), s, n);
  const size_t rows = words.size() / (size_t(splatv::kGaussiansPerRow) * 16);

  const splatv::Bounds bounds = splatv::PositionBounds(canonical);
  const std::vector<SplatvCamera> cameras = splatv::ChooseCameras(asset, options, bounds);
  nlohmann::json camera_list = nlohmann::json::array();
  for (size_t c = 0; c < cameras.size(); ++c) camera_list.push_back(splatv::CameraJson(cameras[c], c));

  SplatvFitReport report;
  report.gaussians = n;
  report.samples = int(samples.count());
  report.scene_extent = std::max(bounds.diagonal(), 1e-12);
  SplatvFile file;
  file.count = n;
  file.words.assign(words.begin(), words.begin() + long(n * 16));
  ATEX_RETURN_IF_ERROR(MeasureStoredError(samples, file, s, &report));
  // Optional: the picture cost, with libatex's reference renderer.
  if (options.psnr_times > 0) ATEX_RETURN_IF_ERROR(MeasurePictureCost(asset, options, cameras[0], file, &report));

  const double t0 = asset.metadata.time_min, t1 = asset.metadata.time_max;
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
