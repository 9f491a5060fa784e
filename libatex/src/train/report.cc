// JSON forms of training and evaluation results.
#include <cmath>
#include <map>

#include "atex/container.h"
#include "atex/train/trainer.h"

namespace atex::train {

static nlohmann::json MetricsToJson(const ImageMetrics& m) {
  return {{"psnr", m.psnr}, {"ssim", m.ssim}, {"dssim1", m.dssim1}, {"dssim2", m.dssim2}, {"l1", m.l1}};
}

// A finite number, or null (no dynamic region there).
static nlohmann::json NumberOrNull(double x) { return std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr); }

nlohmann::json EvalToJson(const EvalResult& eval) {
  nlohmann::json views = nlohmann::json::array();
  // Per camera: the dynamic-region PSNR's mean over the views that have one, and the region's share.
  std::map<int, std::pair<double, int>> dynamic_per_camera;
  std::map<int, double> dynamic_fraction;
  for (const auto& v : eval.views) {
    nlohmann::json j = MetricsToJson(v.metrics);
    j["camera"] = v.camera_id;
    j["timestep"] = v.timestep;
    j["dynamic_psnr"] = NumberOrNull(v.dynamic_psnr);
    if (!std::isnan(v.dynamic_psnr)) {
      auto& [sum, n] = dynamic_per_camera[v.camera_id];
      sum += v.dynamic_psnr;
      ++n;
      dynamic_fraction[v.camera_id] = v.dynamic_fraction;
    }
    views.push_back(std::move(j));
  }
  // Per camera: mean over its timesteps (the benchmark tables report cameras).
  std::map<int, std::pair<ImageMetrics, int>> per_camera;
  for (const auto& v : eval.views) {
    auto& [sum, n] = per_camera[v.camera_id];
    sum.psnr += v.metrics.psnr;
    sum.ssim += v.metrics.ssim;
    sum.dssim1 += v.metrics.dssim1;
    sum.dssim2 += v.metrics.dssim2;
    sum.l1 += v.metrics.l1;
    ++n;
  }
  nlohmann::json cameras = nlohmann::json::array();
  for (auto& [camera, entry] : per_camera) {
    ImageMetrics m = entry.first;
    const double n = entry.second;
    m.psnr /= n, m.ssim /= n, m.dssim1 /= n, m.dssim2 /= n, m.l1 /= n;
    nlohmann::json j = MetricsToJson(m);
    j["camera"] = camera;
    j["views"] = entry.second;
    auto dynamic = dynamic_per_camera.find(camera);
    j["dynamic_psnr"] = dynamic == dynamic_per_camera.end()
                            ? nlohmann::json(nullptr)
                            : nlohmann::json(dynamic->second.first / dynamic->second.second);
    j["dynamic_fraction"] = dynamic == dynamic_per_camera.end() ? 0.0 : dynamic_fraction[camera];
    cameras.push_back(std::move(j));
  }
  nlohmann::json mean = MetricsToJson(eval.mean);
  mean["dynamic_psnr"] = NumberOrNull(eval.dynamic_psnr);
  mean["dynamic_views"] = eval.dynamic_views;
  return {{"mean", mean}, {"cameras", cameras}, {"views", views}};
}

nlohmann::json SummaryToJson(const TrainSummary& s) {
  nlohmann::json growth = nlohmann::json::array();
  for (const auto& g : s.growths) {
    growth.push_back({{"candidates", g.candidates},
                      {"grown", g.grown},
                      {"grown_u_only", g.grown_u_only},
                      {"grown_v_only", g.grown_v_only},
                      {"grown_both", g.grown_both},
                      {"rejected_budget", g.rejected_budget},
                      {"texels_before", g.texels_before},
                      {"texels_after", g.texels_after},
                      {"texel_budget", g.texel_budget}});
  }
  nlohmann::json j = {
      {"gaussians", s.asset.gaussians.size()},
      {"seconds", {{"coarse", s.coarse_seconds}, {"fine", s.fine_seconds}, {"textures", s.textures_seconds}}},
      {"steps", {{"coarse", s.coarse_steps}, {"fine", s.fine_steps}, {"textures", s.texture_steps}}},
      {"densifications", s.densifications.size()},
      {"growth", growth},
      {"events", s.events},
      {"warnings", s.warnings},
      {"stopped_by_time_limit", s.stopped_by_time_limit},
      {"peak_memory_bytes", s.peak_memory_bytes},
  };
  if (!s.test.views.empty()) j["test"] = EvalToJson(s.test);
  if (s.asset.textures) {
    const TextureHistogram h = ComputeTextureHistogram(*s.asset.textures);
    nlohmann::json counts = nlohmann::json::object();
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 3; ++b) counts[std::to_string(1 << a) + "x" + std::to_string(1 << b)] = h.counts[a][b];
    }
    j["textures"] = {{"histogram_hxw", counts}, {"texels", h.texels}, {"uniform_texels", h.uniform_texels()}};
  }
  return j;
}

}  // namespace atex::train
