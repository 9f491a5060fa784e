// Probe views, probe rendering and the importance order (fit.h).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>

#include "atex/deform.h"
#include "cpu_probes.h"
#include "atex/fit.h"
#include "atex/render.h"
#include "atex/train/schedule.h"
#include "atex/train/trainer.h"

namespace atex::fit {
namespace {

double Percentile(std::vector<float> values, double q) {
  if (values.empty()) return 0.0;
  const size_t k = std::min(values.size() - 1, static_cast<size_t>(q * (values.size() - 1)));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  return values[k];
}

// World-to-camera of a camera at `eye` looking at `target` (OpenCV axes: x right, y down, z forward).
std::array<double, 16> LookAt(const std::array<double, 3>& eye, const std::array<double, 3>& target) {
  std::array<double, 3> z{target[0] - eye[0], target[1] - eye[1], target[2] - eye[2]};
  const auto normalise = [](std::array<double, 3>& v) {
    const double l = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (double& c : v) c /= l;
  };
  normalise(z);
  // Any "up" not parallel to z; the proxy only needs views from many directions.
  std::array<double, 3> up = std::abs(z[1]) < 0.9 ? std::array<double, 3>{0, -1, 0} : std::array<double, 3>{0, 0, 1};
  std::array<double, 3> x{up[1] * z[2] - up[2] * z[1], up[2] * z[0] - up[0] * z[2], up[0] * z[1] - up[1] * z[0]};
  normalise(x);
  const std::array<double, 3> y{z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0]};
  std::array<double, 16> m{};
  for (int c = 0; c < 3; ++c) {
    m[c] = x[c];
    m[4 + c] = y[c];
    m[8 + c] = z[c];
  }
  m[3] = -(x[0] * eye[0] + x[1] * eye[1] + x[2] * eye[2]);
  m[7] = -(y[0] * eye[0] + y[1] * eye[1] + y[2] * eye[2]);
  m[11] = -(z[0] * eye[0] + z[1] * eye[1] + z[2] * eye[2]);
  m[15] = 1;
  return m;
}

// Stores a measured importance; the other statistics are unknown: zero, as training writes
// them for never-visible Gaussians.
void SetImportance(Asset* asset, std::vector<float> importance) {
  const size_t n = asset->gaussians.size();
  if (!asset->stats) asset->stats = GaussianStats{};
  GaussianStats& stats = *asset->stats;
  stats.importance = std::move(importance);
  for (std::vector<float>* v : {&stats.texture_demand, &stats.peak_scale_u, &stats.peak_scale_v}) {
    if (v->size() != n) v->assign(n, 0.0f);
  }
}

}  // namespace

std::vector<Probe> OrbitProbes(const Asset& asset, int count, int width, int height) {
  const Gaussians& g = asset.gaussians;
  const size_t n = g.size();
  std::array<double, 3> lo{}, hi{};
  for (int a = 0; a < 3; ++a) {
    std::vector<float> coord(n);
    for (size_t i = 0; i < n; ++i) coord[i] = g.positions[3 * i + a];
    lo[a] = Percentile(coord, 0.05);
    hi[a] = Percentile(std::move(coord), 0.95);
  }
  const std::array<double, 3> centre{(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2};
  const double half_diagonal =
      std::max(1e-3, 0.5 * std::sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                                     (hi[2] - lo[2]) * (hi[2] - lo[2])));
  const double distance = 2.5 * half_diagonal;
  const double focal = 0.5 * height / std::tan(0.5 * 50.0 * M_PI / 180.0);
  std::vector<Probe> probes;
  for (int k = 0; k < count; ++k) {
    // Fibonacci sphere: evenly spread directions, deterministic.
    const double y = count > 1 ? 1.0 - 2.0 * (k + 0.5) / count : 0.0;
    const double r = std::sqrt(std::max(0.0, 1.0 - y * y));
    const double phi = k * M_PI * (3.0 - std::sqrt(5.0));
    const std::array<double, 3> eye{centre[0] + distance * r * std::cos(phi), centre[1] + distance * y,
                                    centre[2] + distance * r * std::sin(phi)};
    Probe p;
    p.camera.width = width;
    p.camera.height = height;
    p.camera.fx = p.camera.fy = focal;
    p.camera.cx = 0.5 * width;
    p.camera.cy = 0.5 * height;
    p.camera.world_to_camera = LookAt(eye, centre);
    const double f = count > 1 ? static_cast<double>(k) / (count - 1) : 0.0;
    p.camera.time = asset.metadata.time_min + f * (asset.metadata.time_max - asset.metadata.time_min);
    p.camera.name = "orbit " + std::to_string(k);
    probes.push_back(p);
  }
  return probes;
}

Camera ScaleCamera(const Camera& camera, int max_side) {
  const int side = std::max(camera.width, camera.height);
  if (side <= max_side || max_side <= 0) return camera;
  const double s = static_cast<double>(max_side) / side;
  Camera c = camera;
  c.width = std::max(1, static_cast<int>(std::lround(camera.width * s)));
  c.height = std::max(1, static_cast<int>(std::lround(camera.height * s)));
  const double sx = static_cast<double>(c.width) / camera.width, sy = static_cast<double>(c.height) / camera.height;
  c.fx *= sx;
  c.cx *= sx;
  c.fy *= sy;
  c.cy *= sy;
  return c;
}

ProbeRenderer::ProbeRenderer(train::Backend* backend, std::vector<Probe> probes)
    : backend_(backend), probes_(std::move(probes)) {
  if (backend_ == nullptr || backend_->name() == "cpu") cpu_ = std::make_unique<internal::CpuProbeRenderer>();
}

ProbeRenderer::~ProbeRenderer() = default;

StatusOr<std::vector<Image>> ProbeRenderer::RenderCameras(const Asset& asset, const std::vector<Camera>& cameras) {
  if (cpu_) return cpu_->Render(asset, cameras, train::RenderRequestFor(asset));
  return RenderOnBackend(train::RenderStateFromAsset(asset), train::RenderRequestFor(asset), cameras);
}

StatusOr<std::vector<Image>> ProbeRenderer::RenderState(const train::ModelState& state,
                                                        const train::RenderRequest& request,
                                                        const train::StateKeys* keys) {
  if (cpu_) {
    return MakeError(StatusCode::kUnsupported,
                     "probe renders from a render state need a GPU backend; the CPU renderer renders assets");
  }
  std::vector<Camera> cameras;
  for (const Probe& p : probes_) cameras.push_back(p.camera);
  return RenderOnBackend(state, request, cameras, keys);
}

StatusOr<std::vector<Image>> ProbeRenderer::RenderOnBackend(const train::ModelState& state,
                                                            const train::RenderRequest& request,
                                                            const std::vector<Camera>& cameras,
                                                            const train::StateKeys* keys) {
  const auto load_start = std::chrono::steady_clock::now();
  ATEX_RETURN_IF_ERROR(keys != nullptr ? backend_->LoadKeyed(state, *keys) : backend_->Load(state));
  load_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - load_start).count();
  std::vector<Image> images;
  images.reserve(cameras.size());
  for (const Camera& camera : cameras) {
    ATEX_ASSIGN_OR_RETURN(Image image, backend_->Render(camera, request));
    images.push_back(std::move(image));
  }
  return images;
}

Status ProbeRenderer::EnsureImportance(Asset* asset) {
  if (!cpu_) return fit::EnsureImportance(asset, probes_);
  const size_t n = asset->gaussians.size();
  if (asset->stats && asset->stats->importance.size() == n) return Status::Ok();
  std::vector<Camera> cameras;
  for (const Probe& p : probes_) cameras.push_back(p.camera);
  ATEX_ASSIGN_OR_RETURN(std::vector<float> importance,
                        cpu_->Importance(*asset, cameras, train::RenderRequestFor(*asset)));
  SetImportance(asset, std::move(importance));
  return Status::Ok();
}

ProbeRenderer::CacheCounts ProbeRenderer::cache_counts() const {
  CacheCounts c;
  if (cpu_) {
    c.deformed = cpu_->deformed();
    c.deform_reused = cpu_->reused();
    c.tiles_drawn = cpu_->tiles_drawn();
    c.tiles_reused = cpu_->tiles_reused();
  }
  return c;
}

StatusOr<std::vector<Image>> ProbeRenderer::Render(const Asset& asset) {
  std::vector<Camera> cameras;
  for (const Probe& p : probes_) cameras.push_back(p.camera);
  return RenderCameras(asset, cameras);
}

StatusOr<double> MeanSquaredError(const std::vector<Image>& a, const std::vector<Image>& b) {
  if (a.size() != b.size()) {
    return MakeError(StatusCode::kInvalidArgument, "distortion: ", a.size(), " renders against ", b.size());
  }
  double total = 0;
  for (size_t k = 0; k < a.size(); ++k) {
    if (a[k].pixels.size() != b[k].pixels.size()) {
      return MakeError(StatusCode::kInvalidArgument, "distortion: render ", k, " sizes differ");
    }
    double sum = 0;
    for (size_t p = 0; p < a[k].pixels.size(); ++p) {
      const double d = std::clamp(a[k].pixels[p], 0.0f, 1.0f) - std::clamp(b[k].pixels[p], 0.0f, 1.0f);
      sum += d * d;
    }
    total += a[k].pixels.empty() ? 0.0 : sum / static_cast<double>(a[k].pixels.size());
  }
  return a.empty() ? 0.0 : total / static_cast<double>(a.size());
}

Status EnsureImportance(Asset* asset, const std::vector<Probe>& probes) {
  const size_t n = asset->gaussians.size();
  if (asset->stats && asset->stats->importance.size() == n) return Status::Ok();
  // Measured with the reference renderer: the accumulated blending weight over the probes.
  std::vector<float> importance(n, 0.0f);
  RenderSettings settings;
  settings.background = asset->metadata.background;
  settings.active_sh_degree = asset->gaussians.sh_degree;
  const TexturePool* textures = asset->textures ? &*asset->textures : nullptr;
  for (const Probe& probe : probes) {
    Gaussians deformed;
    const Gaussians* shown = &asset->gaussians;
    if (asset->deformation) {
      ATEX_RETURN_IF_ERROR(DeformForward(*asset->deformation, asset->gaussians, probe.camera.time, &deformed, nullptr));
      shown = &deformed;
    }
    ATEX_ASSIGN_OR_RETURN(RenderOutput out, RenderForward(probe.camera, *shown, textures, settings));
    for (size_t i = 0; i < n; ++i) importance[i] += out.importance[i];
  }
  SetImportance(asset, std::move(importance));
  return Status::Ok();
}

std::vector<uint32_t> ImportanceOrder(const Asset& asset, uint64_t seed) {
  const size_t n = asset.gaussians.size();
  const bool have = asset.stats && asset.stats->importance.size() == n;
  std::vector<uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  std::vector<uint64_t> tie(n);
  for (size_t i = 0; i < n; ++i) tie[i] = train::SplitMix64(seed ^ (0x9E3779B97F4A7C15ull * (i + 1))).Next();
  std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
    const float ia = have ? asset.stats->importance[a] : 0.0f, ib = have ? asset.stats->importance[b] : 0.0f;
    if (ia != ib) return ia < ib;
    return tie[a] < tie[b];
  });
  return order;
}

}  // namespace atex::fit
