// Multi-view stereo, steps 1-4 of atex/mvs.h: images at the MVS resolution, neighbour
// selection, the plane sweep with windowed ZNCC and the winner-take-all depth maps.
// Fusion and subsampling are in mvs_fusion.cc.
#include "atex/mvs.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "data/mvs_internal.h"

namespace atex {
namespace {

using mvs::Frame;

constexpr double kPi = 3.14159265358979323846;
constexpr float kInvalidScore = -1.0f;

Status ValidateMvsOptions(const MvsOptions& o) {
  const bool ok = o.max_image_side >= 16 && o.near_depth > 0 && o.far_depth > o.near_depth &&
                  std::isfinite(o.far_depth) &&
                  (o.depth_planes == 0 || (o.depth_planes >= 8 && o.depth_planes <= 4096)) && o.plane_step_px > 0 &&
                  o.max_depth_planes >= 16 && o.max_depth_planes <= 4096 && o.neighbors >= 1 && o.neighbors <= 16 &&
                  o.best_neighbors >= 1 && o.best_neighbors <= o.neighbors && o.min_angle_deg >= 0 &&
                  o.preferred_angle_deg > o.min_angle_deg && o.max_angle_deg > o.preferred_angle_deg &&
                  o.max_angle_deg < 180 && o.window_radius >= 1 && o.window_radius <= 5 && o.min_zncc >= -1 &&
                  o.min_zncc <= 1 && o.min_texture >= 0 && o.max_cost_ratio > 0 && o.max_cost_ratio <= 1 &&
                  o.min_consistent_views >= 1 && o.max_reprojection_px > 0 && o.max_relative_depth > 0;
  if (ok) return Status::Ok();
  return MakeError(StatusCode::kInvalidArgument,
                   "mvs: options out of range (max_image_side >= 16, 0 < near_depth < far_depth, depth_planes "
                   "0 or 8..4096, plane_step_px > 0, max_depth_planes 16..4096, neighbors 1..16, best_neighbors "
                   "1..neighbors, 0 <= min_angle < preferred_angle < "
                   "max_angle < 180, window_radius 1..5, min_zncc in [-1, 1], min_texture >= 0, max_cost_ratio "
                   "(0, 1], min_consistent_views >= 1, max_reprojection_px > 0, max_relative_depth > 0)");
}

StatusOr<Frame> MakeFrame(const MvsView& view, int max_side, size_t index) {
  if (!view.image || view.image->width != view.camera.width || view.image->height != view.camera.height ||
      view.image->channels != 3) {
    return MakeError(StatusCode::kInvalidArgument, "mvs: view ", index,
                     " has no RGB image of its camera's size (", view.camera.width, "x", view.camera.height, ")");
  }
  const int factor = DownscaleFactorFor(view.camera, max_side);
  Frame f;
  f.camera = DownscaledCamera(view.camera, factor);
  ATEX_ASSIGN_OR_RETURN(Image small, DownscaleImage(*view.image, factor));
  f.width = small.width;
  f.height = small.height;
  f.rgb = std::move(small.pixels);
  f.grey.resize(f.pixels());
  for (size_t p = 0; p < f.pixels(); ++p) {
    f.grey[p] = 0.299f * f.rgb[3 * p] + 0.587f * f.rgb[3 * p + 1] + 0.114f * f.rgb[3 * p + 2];
  }
  f.center = f.camera.Center();
  return f;
}

std::array<double, 3> Axis(const Camera& cam) {  // optical axis (camera z) in world coordinates
  const auto& m = cam.world_to_camera;
  return {m[8], m[9], m[10]};
}

double Dot(const std::array<double, 3>& a, const std::array<double, 3>& b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

// Depth along camera r's axis of its closest approach to camera s's axis; < 0 when none.
double ClosestApproachDepth(const Frame& r, const Frame& s) {
  const auto a = Axis(r.camera), b = Axis(s.camera);
  const std::array<double, 3> w{r.center[0] - s.center[0], r.center[1] - s.center[1], r.center[2] - s.center[2]};
  const double ab = Dot(a, b), denom = 1 - ab * ab;
  if (denom < 1e-6) return -1;
  return (ab * Dot(b, w) - Dot(a, w)) / denom;
}

// Depth of the reference's anchor point (step 2 of atex/mvs.h).
double AnchorDepth(const std::vector<Frame>& frames, int r, const MvsOptions& o) {
  const Frame& ref = frames[r];
  std::vector<double> depths;
  for (size_t s = 0; s < frames.size(); ++s) {
    if (int(s) == r) continue;
    const double d = ClosestApproachDepth(ref, frames[s]);
    if (d > 0) depths.push_back(d);
  }
  double anchor_depth = std::sqrt(o.near_depth * o.far_depth);
  if (!depths.empty()) {
    std::nth_element(depths.begin(), depths.begin() + depths.size() / 2, depths.end());
    anchor_depth = std::clamp(depths[depths.size() / 2], o.near_depth, o.far_depth);
  }
  return anchor_depth;
}

std::vector<int> ChooseNeighbours(const std::vector<Frame>& frames, int r, const MvsOptions& o) {
  const Frame& ref = frames[r];
  const double anchor_depth = AnchorDepth(frames, r, o);
  double anchor[3];
  mvs::BackProject(ref.camera, ref.camera.cx, ref.camera.cy, anchor_depth, anchor);
  const auto ref_axis = Axis(ref.camera);
  std::vector<std::pair<double, int>> scored;
  for (size_t s = 0; s < frames.size(); ++s) {
    if (int(s) == r) continue;
    const Frame& f = frames[s];
    double u, v;
    if (!ProjectToImage(f.camera, anchor, 1e-6, &u, &v)) continue;
    if (Dot(ref_axis, Axis(f.camera)) < std::cos(80.0 * kPi / 180)) continue;
    std::array<double, 3> a{}, b{};
    for (int k = 0; k < 3; ++k) {
      a[k] = ref.center[k] - anchor[k];
      b[k] = f.center[k] - anchor[k];
    }
    const double cosine = Dot(a, b) / std::sqrt(Dot(a, a) * Dot(b, b));
    const double angle = std::acos(std::clamp(cosine, -1.0, 1.0)) * 180 / kPi;
    if (angle < o.min_angle_deg || angle > o.max_angle_deg) continue;
    const double sigma = angle < o.preferred_angle_deg ? 0.5 * o.preferred_angle_deg : o.preferred_angle_deg;
    const double x = (angle - o.preferred_angle_deg) / sigma;
    scored.push_back({-std::exp(-0.5 * x * x), int(s)});
  }
  std::sort(scored.begin(), scored.end());
  std::vector<int> out;
  for (size_t i = 0; i < scored.size() && int(i) < o.neighbors; ++i) out.push_back(scored[i].second);
  return out;
}

// Sums over the (2r+1)² window of four images at once (separable; 0 where the window leaves the image).
void BoxSums4(const float* const in[4], float* const out[4], float* const tmp[4], int w, int h, int r) {
  for (int y = 0; y < h; ++y) {
    const size_t row = size_t(y) * w;
    for (int c = 0; c < 4; ++c) {
      const float* src = in[c] + row;
      float* dst = tmp[c] + row;
      std::fill(dst, dst + w, 0.0f);
      for (int x = r; x < w - r; ++x) {
        float s = 0;
        for (int dx = -r; dx <= r; ++dx) s += src[x + dx];
        dst[x] = s;
      }
    }
  }
  for (int c = 0; c < 4; ++c) {
    std::fill(out[c], out[c] + size_t(w) * h, 0.0f);
    for (int y = r; y < h - r; ++y) {
      float* dst = out[c] + size_t(y) * w;
      for (int dy = -r; dy <= r; ++dy) {
        const float* src = tmp[c] + size_t(y + dy) * w;
        for (int x = 0; x < w; ++x) dst[x] += src[x];
      }
    }
  }
}

// Planes for reference r: the fixed count, or as many as keep the anchor's image in every
// neighbour within plane_step_px between planes (its motion per unit inverse depth,
// measured by a central difference at the anchor, times the inverse-depth range).
int PlaneCount(const std::vector<Frame>& frames, int r, const std::vector<int>& nbrs, const MvsOptions& o) {
  if (o.depth_planes > 0) return o.depth_planes;
  const Frame& ref = frames[r];
  const double inv_anchor = 1.0 / AnchorDepth(frames, r, o);
  const double eps = 1e-3 * (1.0 / o.near_depth - 1.0 / o.far_depth);
  double a[3], b[3], fastest = 0;
  mvs::BackProject(ref.camera, ref.camera.cx, ref.camera.cy, 1.0 / (inv_anchor + eps), a);
  mvs::BackProject(ref.camera, ref.camera.cx, ref.camera.cy, 1.0 / std::max(inv_anchor - eps, 1e-12), b);
  for (int j : nbrs) {
    double ca[3], cb[3];
    mvs::ToCamera(frames[j].camera, a, ca);
    mvs::ToCamera(frames[j].camera, b, cb);
    if (!(ca[2] > 0 && cb[2] > 0)) continue;
    const double du = frames[j].camera.fx * (ca[0] / ca[2] - cb[0] / cb[2]);
    const double dv = frames[j].camera.fy * (ca[1] / ca[2] - cb[1] / cb[2]);
    fastest = std::max(fastest, std::hypot(du, dv) / (2 * eps));
  }
  const double planes = fastest * (1.0 / o.near_depth - 1.0 / o.far_depth) / o.plane_step_px;
  return static_cast<int>(std::clamp(std::ceil(planes) + 1, 16.0, double(o.max_depth_planes)));
}

// Per-thread buffers of the sweep.
struct SweepScratch {
  std::vector<float> warped, valid, product, squared;
  std::vector<float> sum_j, sum_valid, sum_ij, sum_jj, tmp[4];
  std::vector<float> scores;  // [neighbours][P]
  explicit SweepScratch(size_t p, int neighbours)
      : warped(p), valid(p), product(p), squared(p), sum_j(p), sum_valid(p), sum_ij(p), sum_jj(p),
        scores(p * neighbours) {
    for (auto& t : tmp) t.resize(p);
  }
};

// Mean and standard deviation of reference r's grey values over each pixel's window.
struct WindowStats {
  std::vector<float> mean, std;  // [P] each
};
WindowStats ReferenceWindowStats(const Frame& ref, int rad) {
  const int w = ref.width, h = ref.height;
  const size_t P = ref.pixels();
  const float window = float((2 * rad + 1) * (2 * rad + 1));
  WindowStats stats{std::vector<float>(P), std::vector<float>(P)};
  std::vector<float> sq(P), s1(P), s2(P), t0(P), t1(P), t2(P), t3(P), z(P, 0.0f), z2(P);
  for (size_t p = 0; p < P; ++p) sq[p] = ref.grey[p] * ref.grey[p];
  const float* in[4] = {ref.grey.data(), sq.data(), z.data(), z.data()};
  float* out[4] = {s1.data(), s2.data(), z2.data(), z2.data()};
  float* tmp[4] = {t0.data(), t1.data(), t2.data(), t3.data()};
  BoxSums4(in, out, tmp, w, h, rad);
  for (size_t p = 0; p < P; ++p) {
    stats.mean[p] = s1[p] / window;
    stats.std[p] = std::sqrt(std::max(0.0f, s2[p] / window - stats.mean[p] * stats.mean[p]));
  }
  return stats;
}

// Homographies of the plane sweep: neighbour pixel q = d·a[p] + b (homogeneous), with
// a = K_n R_rel ray_r(p) and b = K_n t_rel, for each neighbour j of reference `ref`.
struct SweepHomographies {
  std::vector<std::vector<float>> a;     // [K][P][3]
  std::vector<std::array<double, 3>> b;  // [K]
};
SweepHomographies NeighbourHomographies(const std::vector<Frame>& frames, const Frame& ref,
                                        const std::vector<int>& nbrs) {
  const int w = ref.width, h = ref.height;
  const size_t P = ref.pixels();
  const int K = static_cast<int>(nbrs.size());
  SweepHomographies hg{std::vector<std::vector<float>>(K, std::vector<float>(3 * P)),
                       std::vector<std::array<double, 3>>(K)};
  const auto& mr = ref.camera.world_to_camera;
  for (int j = 0; j < K; ++j) {
    const Camera& cn = frames[nbrs[j]].camera;
    const auto& mn = cn.world_to_camera;
    double rel[3][3], trel[3];
    for (int i = 0; i < 3; ++i) {
      for (int k = 0; k < 3; ++k) {
        rel[i][k] = 0;
        for (int m = 0; m < 3; ++m) rel[i][k] += mn[4 * i + m] * mr[4 * k + m];  // R_n · R_rᵀ
      }
    }
    for (int i = 0; i < 3; ++i) {
      trel[i] = mn[4 * i + 3];
      for (int k = 0; k < 3; ++k) trel[i] -= rel[i][k] * mr[4 * k + 3];
    }
    hg.b[j] = {cn.fx * trel[0] + cn.cx * trel[2], cn.fy * trel[1] + cn.cy * trel[2], trel[2]};
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const double ray[3] = {(x + 0.5 - ref.camera.cx) / ref.camera.fx, (y + 0.5 - ref.camera.cy) / ref.camera.fy, 1};
        double c[3];
        for (int i = 0; i < 3; ++i) c[i] = rel[i][0] * ray[0] + rel[i][1] * ray[1] + rel[i][2] * ray[2];
        float* dst = &hg.a[j][3 * (size_t(y) * w + x)];
        dst[0] = float(cn.fx * c[0] + cn.cx * c[2]);
        dst[1] = float(cn.fy * c[1] + cn.cy * c[2]);
        dst[2] = float(c[2]);
      }
    }
  }
  return hg;
}

// The ZNCC of reference `ref` against neighbour `nb` warped onto the plane at depth d, per
// pixel, into score [P] (kInvalidScore where the window is not fully seen or is flat).
void ScoreNeighbourAtDepth(const Frame& ref, const Frame& nb, const WindowStats& stats, const float* aj,
                           const std::array<double, 3>& bj, float d, int rad, SweepScratch& s, float* score) {
  const int w = ref.width, h = ref.height;
  const size_t P = ref.pixels();
  const float window = float((2 * rad + 1) * (2 * rad + 1));
  const float b0 = float(bj[0]), b1 = float(bj[1]), b2 = float(bj[2]);
  for (size_t p = 0; p < P; ++p) {
    const float qz = d * aj[3 * p + 2] + b2;
    float value = 0, ok = 0;
    if (qz > 1e-6f) {
      const float gx = (d * aj[3 * p] + b0) / qz - 0.5f, gy = (d * aj[3 * p + 1] + b1) / qz - 0.5f;
      if (gx >= 0 && gy >= 0 && gx <= float(nb.width - 1) && gy <= float(nb.height - 1)) {
        const int x0 = std::min(int(gx), nb.width - 2 < 0 ? 0 : nb.width - 2);
        const int y0 = std::min(int(gy), nb.height - 2 < 0 ? 0 : nb.height - 2);
        const float fx = gx - x0, fy = gy - y0;
        const float* g = &nb.grey[size_t(y0) * nb.width + x0];
        value = (1 - fy) * ((1 - fx) * g[0] + fx * g[1]) + fy * ((1 - fx) * g[nb.width] + fx * g[nb.width + 1]);
        ok = 1;
      }
    }
    s.warped[p] = value;
    s.valid[p] = ok;
    s.product[p] = value * ref.grey[p];
    s.squared[p] = value * value;
  }
  const float* in[4] = {s.warped.data(), s.valid.data(), s.product.data(), s.squared.data()};
  float* out[4] = {s.sum_j.data(), s.sum_valid.data(), s.sum_ij.data(), s.sum_jj.data()};
  float* tmp[4] = {s.tmp[0].data(), s.tmp[1].data(), s.tmp[2].data(), s.tmp[3].data()};
  BoxSums4(in, out, tmp, w, h, rad);
  for (size_t p = 0; p < P; ++p) {
    score[p] = kInvalidScore;
    if (s.sum_valid[p] < window - 0.5f || stats.std[p] <= 0) continue;
    const float mj = s.sum_j[p] / window;
    const float var_j = s.sum_jj[p] / window - mj * mj;
    if (!(var_j > 1e-8f)) continue;
    const float cov = s.sum_ij[p] / window - stats.mean[p] * mj;
    score[p] = std::clamp(cov / (stats.std[p] * std::sqrt(var_j)), -1.0f, 1.0f);
  }
}

// Step 3 and 4 for reference r: its depth map [H][W] (0 = none).
std::vector<float> SweepReference(const std::vector<Frame>& frames, int r, const std::vector<int>& nbrs,
                                  const MvsOptions& o, int D) {
  const Frame& ref = frames[r];
  const size_t P = ref.pixels();
  const int K = static_cast<int>(nbrs.size());
  std::vector<float> depth(P, 0.0f);
  if (K < o.best_neighbors) return depth;

  const WindowStats stats = ReferenceWindowStats(ref, o.window_radius);
  const SweepHomographies hg = NeighbourHomographies(frames, ref, nbrs);
  const double inv_near = 1.0 / o.near_depth, inv_far = 1.0 / o.far_depth;
  auto plane_depth = [&](double k) { return 1.0 / (inv_near + (inv_far - inv_near) * k / (D - 1)); };

  // The cost volume [D][P]: per plane, the mean of the best neighbours' ZNCC.
  std::vector<float> volume(size_t(D) * P);
#pragma omp parallel
  {
    SweepScratch s(P, K);
    std::vector<float> top(K);
#pragma omp for schedule(dynamic, 1)
    for (int k = 0; k < D; ++k) {
      const float d = float(plane_depth(k));
      for (int j = 0; j < K; ++j) {
        ScoreNeighbourAtDepth(ref, frames[nbrs[j]], stats, hg.a[j].data(), hg.b[j], d, o.window_radius, s,
                              &s.scores[size_t(j) * P]);
      }
      float* plane = &volume[size_t(k) * P];
      for (size_t p = 0; p < P; ++p) {
        for (int j = 0; j < K; ++j) top[j] = s.scores[size_t(j) * P + p];
        std::partial_sort(top.begin(), top.begin() + o.best_neighbors, top.end(), std::greater<float>());
        float sum = 0;
        for (int j = 0; j < o.best_neighbors; ++j) sum += top[j];
        plane[p] = sum / float(o.best_neighbors);
      }
    }
  }

  // Winner takes all with the step-4 tests.
#pragma omp parallel for schedule(static)
  for (long long pl = 0; pl < static_cast<long long>(P); ++pl) {
    const size_t p = static_cast<size_t>(pl);
    if (stats.std[p] < o.min_texture) continue;
    int best_k = -1;
    float best = -2;
    for (int k = 0; k < D; ++k) {
      const float v = volume[size_t(k) * P + p];
      if (v > best) best = v, best_k = k;
    }
    if (best_k <= 0 || best_k >= D - 1 || best < o.min_zncc) continue;
    float second = -1;
    for (int k = 0; k < D; ++k) {
      if (std::abs(k - best_k) > 2) second = std::max(second, volume[size_t(k) * P + p]);
    }
    if ((1.0 - best) > o.max_cost_ratio * (1.0 - second)) continue;
    const double sm = volume[size_t(best_k - 1) * P + p], sp = volume[size_t(best_k + 1) * P + p];
    const double curvature = sm - 2.0 * best + sp;
    const double offset = curvature < 0 ? std::clamp(0.5 * (sm - sp) / curvature, -0.5, 0.5) : 0.0;
    depth[p] = float(plane_depth(best_k + offset));
  }
  return depth;
}

}  // namespace

int DownscaleFactorFor(const Camera& camera, int max_side) {
  const int longest = std::max(camera.width, camera.height);
  return std::max(1, (longest + std::max(max_side, 1) - 1) / std::max(max_side, 1));
}

Camera DownscaledCamera(const Camera& camera, int factor) {
  Camera c = camera;
  c.width = camera.width / factor;
  c.height = camera.height / factor;
  c.fx = camera.fx / factor;
  c.fy = camera.fy / factor;
  c.cx = camera.cx / factor;
  c.cy = camera.cy / factor;
  return c;
}

double PointCoverage(const std::vector<float>& positions, const Camera& camera, int max_side) {
  const Camera c = DownscaledCamera(camera, DownscaleFactorFor(camera, max_side));
  if (c.width <= 0 || c.height <= 0) return 0;
  std::vector<uint8_t> hit(size_t(c.width) * c.height, 0);
  for (size_t i = 0; i + 2 < positions.size(); i += 3) {
    const double x[3] = {positions[i], positions[i + 1], positions[i + 2]};
    double u, v;
    if (ProjectToImage(c, x, 1e-6, &u, &v)) hit[size_t(v) * c.width + size_t(u)] = 1;
  }
  return double(std::count(hit.begin(), hit.end(), 1)) / double(hit.size());
}

StatusOr<PointCloud> MultiViewStereo(const std::vector<MvsView>& views, const MvsOptions& options, MvsReport* report,
                                     const MvsProgress& progress) {
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  ATEX_RETURN_IF_ERROR(ValidateMvsOptions(options));
  if (views.size() < 2) {
    return MakeError(StatusCode::kInvalidArgument, "mvs: needs at least 2 views, got ", views.size());
  }
  MvsReport local;
  MvsReport& rep = report ? *report : local;
  rep = MvsReport();
  std::vector<Frame> frames;
  for (size_t i = 0; i < views.size(); ++i) {
    ATEX_ASSIGN_OR_RETURN(Frame f, MakeFrame(views[i], options.max_image_side, i));
    frames.push_back(std::move(f));
  }
  const int n = static_cast<int>(frames.size());
  rep.cameras = n;
  rep.width = frames[0].width;
  rep.height = frames[0].height;
  rep.downscale = DownscaleFactorFor(views[0].camera, options.max_image_side);
  std::vector<std::vector<float>> depths(n);
  rep.depth_fraction.assign(n, 0.0);
  for (int r = 0; r < n; ++r) {
    rep.neighbours.push_back(ChooseNeighbours(frames, r, options));
    rep.depth_planes.push_back(PlaneCount(frames, r, rep.neighbours.back(), options));
    depths[r] = SweepReference(frames, r, rep.neighbours.back(), options, rep.depth_planes.back());
    const size_t kept = frames[r].pixels() - std::count(depths[r].begin(), depths[r].end(), 0.0f);
    rep.depth_fraction[r] = double(kept) / double(frames[r].pixels());
    if (progress && !progress(r + 1, n)) return MakeError(StatusCode::kCancelled, "mvs: cancelled");
  }
  const auto swept = Clock::now();
  rep.seconds_depth = std::chrono::duration<double>(swept - start).count();
  PointCloud fused = mvs::FuseDepthMaps(frames, depths, options, &rep);
  if (options.keep_depth_maps) rep.depth_maps = depths;
  rep.fused_points = fused.size();
  if (fused.size() == 0) {
    return MakeError(StatusCode::kNotFound, "mvs: no point survived fusion (", n,
                     " cameras; too little texture or overlap, or a depth range that misses the scene)");
  }
  PointCloud out = options.target_points > 0 ? mvs::VoxelSubsample(fused, options.target_points, &rep.voxel_size)
                                             : std::move(fused);
  rep.output_points = out.size();
  rep.seconds_fusion = std::chrono::duration<double>(Clock::now() - swept).count();
  rep.seconds_total = std::chrono::duration<double>(Clock::now() - start).count();
  return out;
}

}  // namespace atex
