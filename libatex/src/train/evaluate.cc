// Test-view evaluation: whole-image metrics and the dynamic-region PSNR.
#include <algorithm>
#include <cmath>
#include <future>
#include <map>

#include "atex/train/trainer.h"
#include "render/parallel.h"

namespace atex::train {

namespace {

// The dynamic region of every camera of `views` that has two or more frames in the
// dataset (both splits). Cameras with one frame get no entry.
StatusOr<std::map<int, DynamicRegion>> CameraRegions(const Dataset& dataset, const std::vector<View>& views,
                                                     double threshold) {
  std::map<int, std::vector<const View*>> frames;
  for (const View& v : views) frames[v.camera_id];
  for (const auto* split : {&dataset.train_views(), &dataset.test_views()}) {
    for (const View& v : *split) {
      auto it = frames.find(v.camera_id);
      if (it != frames.end() && v.camera_id >= 0) it->second.push_back(&v);
    }
  }
  std::vector<std::pair<int, std::vector<const View*>>> work;
  for (auto& [camera, list] : frames) {
    if (list.size() >= 2) work.emplace_back(camera, std::move(list));
  }
  std::vector<StatusOr<DynamicRegion>> regions(work.size(), DynamicRegion{});
#pragma omp parallel for schedule(dynamic, 1)
  for (long long i = 0; i < static_cast<long long>(work.size()); ++i) {
    TemporalVariance variance;
    for (const View* v : work[i].second) {
      StatusOr<std::shared_ptr<const Image>> image = dataset.LoadImage(*v);
      if (!image.ok()) {
        regions[i] = image.status();
        break;
      }
      if (Status s = variance.Add(**image); !s.ok()) {
        regions[i] = MakeError(s.code(), "camera ", work[i].first, ": ", s.message());
        break;
      }
    }
    if (regions[i].ok()) regions[i] = variance.Region(threshold);
  }
  std::map<int, DynamicRegion> out;
  for (size_t i = 0; i < work.size(); ++i) {
    if (!regions[i].ok()) return regions[i].status();
    out.emplace(work[i].first, std::move(*regions[i]));
  }
  return out;
}

}  // namespace

StatusOr<EvalResult> Evaluate(const Dataset& dataset, Backend& backend, const std::vector<View>& views,
                              const RenderRequest& request, const EvalOptions& options) {
  EvalResult result;
  result.views.resize(views.size());
  std::map<int, DynamicRegion> regions;
  if (options.dynamic_region) {
    ATEX_ASSIGN_OR_RETURN(regions, CameraRegions(dataset, views, options.dynamic_threshold));
  }
  // Renders come from the backend one by one; the CPU metrics (SSIM dominates) of a chunk run in
  // parallel, on another thread while the next chunk renders.
  constexpr size_t kChunk = 32;
  struct Chunk {
    size_t begin = 0;
    std::vector<Image> rendered;
    std::vector<std::shared_ptr<const Image>> targets;
  };
  const auto score = [&](Chunk chunk) -> Status {
    const size_t count = chunk.rendered.size();
    std::vector<Status> errors(count);
    const int threads = options.metric_threads > 0 ? options.metric_threads : render_internal::MaxThreads();
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
    for (long long k = 0; k < static_cast<long long>(count); ++k) {
      Image& rendered = chunk.rendered[k];
      const Image& target = *chunk.targets[k];
      for (float& v : rendered.pixels) v = std::clamp(v, 0.0f, 1.0f);
      StatusOr<ImageMetrics> m = CompareImages(rendered, target);
      if (!m.ok()) {
        errors[k] = m.status();
        continue;
      }
      const View& view = views[chunk.begin + k];
      ViewMetrics& out = result.views[chunk.begin + k];
      out = {view.camera_id, view.timestep, *m};
      auto region = regions.find(view.camera_id);
      if (region != regions.end() && region->second.count > 0) {
        StatusOr<double> psnr = RegionPsnr(rendered, target, region->second);
        if (!psnr.ok()) {
          errors[k] = psnr.status();
          continue;
        }
        out.dynamic_psnr = *psnr;
        out.dynamic_fraction = region->second.fraction();
      }
    }
    for (const Status& e : errors) ATEX_RETURN_IF_ERROR(e);
    return Status::Ok();
  };
  // Declared after `result` and `regions`, which it uses: an early return waits for it first.
  std::future<Status> scoring;
  for (size_t begin = 0; begin < views.size(); begin += kChunk) {
    const size_t end = std::min(views.size(), begin + kChunk);
    Chunk chunk;
    chunk.begin = begin;
    chunk.rendered.resize(end - begin);
    chunk.targets.resize(end - begin);
    for (size_t i = begin; i < end; ++i) {
      ATEX_ASSIGN_OR_RETURN(chunk.rendered[i - begin], backend.Render(views[i].camera, request));
      ATEX_ASSIGN_OR_RETURN(chunk.targets[i - begin], dataset.LoadImage(views[i]));
    }
    if (scoring.valid()) ATEX_RETURN_IF_ERROR(scoring.get());
    scoring = std::async(std::launch::async, score, std::move(chunk));
  }
  if (scoring.valid()) ATEX_RETURN_IF_ERROR(scoring.get());
  const double n = static_cast<double>(std::max<size_t>(1, result.views.size()));
  double dynamic_sum = 0;
  for (const auto& v : result.views) {
    result.mean.psnr += v.metrics.psnr / n;
    result.mean.ssim += v.metrics.ssim / n;
    result.mean.dssim1 += v.metrics.dssim1 / n;
    result.mean.dssim2 += v.metrics.dssim2 / n;
    result.mean.l1 += v.metrics.l1 / n;
    result.mean.mse += v.metrics.mse / n;
    if (!std::isnan(v.dynamic_psnr)) {  // +infinity (a perfect region) counts, as in the PSNR mean
      dynamic_sum += v.dynamic_psnr;
      ++result.dynamic_views;
    }
  }
  if (result.dynamic_views > 0) result.dynamic_psnr = dynamic_sum / double(result.dynamic_views);
  return result;
}

}  // namespace atex::train
