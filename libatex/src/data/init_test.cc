// Initialisation: nearest-neighbour scales against brute force, a synthetic
// sphere seen by a ring of cameras (analytic masks), determinism, the random
// cube, and the real Panoptic data.
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "atex/init.h"
#include "core/test_support.h"

namespace atex {
namespace {

constexpr double kC0 = 0.28209479177387814;

TEST(NearestNeighborLogScales, MatchesBruteForce) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<float> p(3 * 700);
  for (float& v : p) v = u(rng);
  // Clustered points too: the k-d tree must not depend on uniform density.
  for (int i = 0; i < 100; ++i) {
    for (int a = 0; a < 3; ++a) p[i * 3 + a] = 0.001f * u(rng) + 0.5f;
  }
  const std::vector<float> scales = NearestNeighborLogScales(p, 3);
  const size_t n = p.size() / 3;
  for (size_t i = 0; i < n; ++i) {
    std::vector<double> d2;
    for (size_t j = 0; j < n; ++j) {
      if (j == i) continue;
      double s = 0;
      for (int a = 0; a < 3; ++a) s += std::pow(double(p[i * 3 + a]) - p[j * 3 + a], 2);
      d2.push_back(s);
    }
    std::partial_sort(d2.begin(), d2.begin() + 3, d2.end());
    const double mean = std::max((d2[0] + d2[1] + d2[2]) / 3, 1e-7);
    ASSERT_NEAR(scales[i], 0.5 * std::log(mean), 1e-5) << i;
  }
}

TEST(NearestNeighborLogScales, GridSpacingAndEdgeCases) {
  std::vector<float> grid;
  for (int z = 0; z < 5; ++z) {
    for (int y = 0; y < 5; ++y) {
      for (int x = 0; x < 5; ++x) {
        grid.insert(grid.end(), {x * 0.1f, y * 0.1f, z * 0.1f});
      }
    }
  }
  const std::vector<float> s = NearestNeighborLogScales(grid, 3);
  EXPECT_NEAR(s[62], std::log(0.1), 1e-5);  // interior point: 6 neighbours at 0.1
  EXPECT_TRUE(NearestNeighborLogScales({}, 3).empty());
  EXPECT_NEAR(NearestNeighborLogScales({1, 2, 3}, 3)[0], 0.5 * std::log(1e-7), 1e-6);
  const std::vector<float> two = NearestNeighborLogScales({0, 0, 0, 0, 0, 2}, 3);
  EXPECT_NEAR(two[0], std::log(2.0), 1e-6);
  const std::vector<float> same = NearestNeighborLogScales({1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1}, 3);
  EXPECT_NEAR(same[0], 0.5 * std::log(1e-7), 1e-6);  // duplicates: the clamp
}

// 16 cameras on two rings around a red sphere (radius 0.5 at the origin) in
// front of a blue background, with exact masks.
constexpr double kRadius = 0.5;

StatusOr<std::unique_ptr<Dataset>> SphereScene(int size = 64, bool with_masks = true) {
  std::vector<InMemoryFrame> frames;
  for (int i = 0; i < 16; ++i) {
    const double azimuth = 2 * M_PI * (i % 8) / 8 + (i >= 8 ? 0.3 : 0.0);
    const double elevation = i >= 8 ? 0.6 : -0.2;
    const double o[3] = {3 * std::cos(elevation) * std::cos(azimuth), 3 * std::cos(elevation) * std::sin(azimuth),
                         3 * std::sin(elevation)};
    // Look at the origin: z = −o/|o|, x = z × up (normalised), y = z × x.
    double z[3] = {-o[0] / 3, -o[1] / 3, -o[2] / 3};
    double x[3] = {z[1] * 1 - z[2] * 0, z[2] * 0 - z[0] * 1, 0};  // z × (0, 0, 1)
    const double xn = std::sqrt(x[0] * x[0] + x[1] * x[1]);
    x[0] /= xn;
    x[1] /= xn;
    const double y[3] = {z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0]};
    InMemoryFrame f;
    Camera& cam = f.view.camera;
    cam.width = cam.height = size;
    cam.fx = cam.fy = size * 1.2;
    cam.cx = cam.cy = size / 2.0;
    const double* rows[3] = {x, y, z};
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) cam.world_to_camera[r * 4 + c] = rows[r][c];
      cam.world_to_camera[r * 4 + 3] = -(rows[r][0] * o[0] + rows[r][1] * o[1] + rows[r][2] * o[2]);
    }
    f.view.camera_id = i;
    f.view.timestep = 0;
    f.image = Image(size, size, 3);
    f.mask = Image(size, size, 1);
    for (int py = 0; py < size; ++py) {
      for (int px = 0; px < size; ++px) {
        // Ray through the pixel centre: d = Rᵀ((u − cx)/fx, (v − cy)/fy, 1); hit test with the sphere.
        const double cxy[3] = {(px + 0.5 - cam.cx) / cam.fx, (py + 0.5 - cam.cy) / cam.fy, 1};
        double d[3];
        for (int a = 0; a < 3; ++a) d[a] = x[a] * cxy[0] + y[a] * cxy[1] + z[a] * cxy[2];
        const double dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        const double od = o[0] * d[0] + o[1] * d[1] + o[2] * d[2];
        const double disc = od * od - dd * (9.0 - kRadius * kRadius);
        const bool hit = disc >= 0;
        f.mask.at(px, py, 0) = hit ? 1.0f : 0.0f;
        f.image.at(px, py, 0) = hit ? 0.9f : 0.1f;
        f.image.at(px, py, 1) = 0.1f;
        f.image.at(px, py, 2) = hit ? 0.1f : 0.9f;
      }
    }
    if (!with_masks) f.mask = Image();
    frames.push_back(std::move(f));
  }
  return MakeInMemoryDataset("sphere", std::move(frames));
}

std::array<float, 3> Colour(const Gaussians& g, size_t i) {
  const int k = g.sh_coeffs();
  return {float(g.sh[i * k * 3 + 0] * kC0 + 0.5), float(g.sh[i * k * 3 + 1] * kC0 + 0.5),
          float(g.sh[i * k * 3 + 2] * kC0 + 0.5)};
}

TEST(Init, VisualHullOfASphere) {
  auto scene = SphereScene();
  ASSERT_TRUE(scene.ok()) << scene.status().ToString();
  InitOptions options;
  options.method = InitMethod::kVisualHull;
  options.hull_points = 4000;
  options.hull_resolution = 64;
  InitReport report;
  auto g = InitializeGaussians(**scene, options, &report);
  ASSERT_TRUE(g.ok()) << g.status().ToString();
  ASSERT_EQ(g->size(), 4000u);
  EXPECT_EQ(report.hull_points, 4000u);
  EXPECT_NEAR(report.scene_center[0], 0.0, 1e-6);
  EXPECT_NEAR(report.camera_distance, 3.0, 1e-6);
  size_t inside = 0;
  std::array<float, 3> lo{9, 9, 9}, hi{-9, -9, -9};
  for (size_t i = 0; i < g->size(); ++i) {
    const float* p = &g->positions[i * 3];
    const double r = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    inside += r < kRadius * 1.15;  // the hull of 16 views is a little larger than the sphere
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], p[a]);
      hi[a] = std::max(hi[a], p[a]);
    }
    const auto c = Colour(*g, i);
    ASSERT_GT(c[0], 0.8f) << i;  // points on/in the sphere take its red
    ASSERT_LT(c[2], 0.2f) << i;
    EXPECT_EQ(g->rotations[i * 4], 1.0f);
    EXPECT_NEAR(g->opacity_logits[i], std::log(0.1 / 0.9), 1e-6);
    EXPECT_EQ(g->log_scales[i * 3], g->log_scales[i * 3 + 2]);
  }
  EXPECT_GT(inside, g->size() * 98 / 100);
  for (int a = 0; a < 3; ++a) {  // the points fill the sphere, not a part of it
    EXPECT_LT(lo[a], -0.4f);
    EXPECT_GT(hi[a], 0.4f);
  }
  EXPECT_EQ(g->sh_degree, 3);
  EXPECT_EQ(g->sh[1 * 3], 0.0f);  // higher SH coefficients are zero
}

TEST(Init, HullPlusVolumeIsDeterministicPerSeed) {
  auto scene = SphereScene(48);
  ASSERT_TRUE(scene.ok());
  InitOptions options;
  options.hull_points = 1500;
  options.volume_points = 800;
  options.hull_resolution = 40;
  InitReport report;
  auto a = InitializeGaussians(**scene, options, &report);
  ASSERT_TRUE(a.ok()) << a.status().ToString();
  EXPECT_EQ(report.method, InitMethod::kHullAndViewVolume);  // auto: multi-view with masks
  EXPECT_EQ(a->size(), 2300u);
  // Volume points are background: outside the sphere, blue.
  for (size_t i = 1500; i < a->size(); ++i) {
    const float* p = &a->positions[i * 3];
    ASSERT_GT(std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]), kRadius * 0.95) << i;
    ASSERT_GT(Colour(*a, i)[2], 0.8f) << i;
  }
  auto b = InitializeGaussians(**scene, options);
  ASSERT_TRUE(b.ok());
  EXPECT_EQ(a->positions, b->positions);
  EXPECT_EQ(a->sh, b->sh);
  options.seed = 7;
  auto c = InitializeGaussians(**scene, options);
  ASSERT_TRUE(c.ok());
  EXPECT_NE(a->positions, c->positions);
}

// Photo-consistency: without masks, a point whose cameras see both the red sphere
// and the blue background is rejected; red points then lie inside the sphere's
// visual hull, while without the test they also float along single lines of sight.
TEST(Init, ViewVolumePhotoConsistency) {
  auto scene = SphereScene(32, false);
  ASSERT_TRUE(scene.ok());
  auto farthest_red = [&](double spread, size_t* red_count) {
    InitOptions options;
    options.volume_points = 1500;
    options.volume_max_colour_spread = spread;
    InitReport report;
    auto g = InitializeGaussians(**scene, options, &report);
    EXPECT_TRUE(g.ok()) << g.status().ToString();
    EXPECT_EQ(report.volume_points, 1500u);
    EXPECT_GE(report.volume_candidates, report.volume_points);
    double farthest = 0;
    *red_count = 0;
    for (size_t i = 0; g.ok() && i < g->size(); ++i) {
      const std::array<float, 3> c = Colour(*g, i);
      if (c[0] < 0.5f) continue;  // not red: background or a mixture
      ++*red_count;
      const float* x = &g->positions[i * 3];
      farthest = std::max(farthest, std::sqrt(double(x[0]) * x[0] + double(x[1]) * x[1] + double(x[2]) * x[2]));
    }
    return farthest;
  };
  size_t red_filtered = 0, red_unfiltered = 0;
  EXPECT_LT(farthest_red(0.03, &red_filtered), kRadius * 1.3);
  EXPECT_GT(red_filtered, 10u);
  EXPECT_GT(farthest_red(0, &red_unfiltered), kRadius * 1.6);
  EXPECT_GT(red_unfiltered, 10u);
}

TEST(Init, ViewVolumeWithoutMasks) {
  auto scene = SphereScene(32, false);
  ASSERT_TRUE(scene.ok());
  InitOptions options;
  options.volume_points = 2000;
  InitReport report;
  auto g = InitializeGaussians(**scene, options, &report);
  ASSERT_TRUE(g.ok()) << g.status().ToString();
  EXPECT_EQ(report.method, InitMethod::kViewVolume);  // auto: multi-view, no masks
  ASSERT_EQ(g->size(), 2000u);
  // Every point is seen by at least min_views cameras; points on the sphere's
  // line of sight take reddish colours, the others blue.
  size_t red = 0;
  for (size_t i = 0; i < g->size(); ++i) {
    const float* x = &g->positions[i * 3];
    int seen = 0;
    for (const View& v : (*scene)->train_views()) {
      const auto& m = v.camera.world_to_camera;
      const double pz = m[8] * x[0] + m[9] * x[1] + m[10] * x[2] + m[11];
      const double u = v.camera.fx * (m[0] * x[0] + m[1] * x[1] + m[2] * x[2] + m[3]) / pz + v.camera.cx;
      const double w = v.camera.fy * (m[4] * x[0] + m[5] * x[1] + m[6] * x[2] + m[7]) / pz + v.camera.cy;
      seen += pz > 0 && u >= 0 && w >= 0 && u < 32 && w < 32;
    }
    ASSERT_GE(seen, 3) << i;
    red += Colour(*g, i)[0] > Colour(*g, i)[2];
  }
  EXPECT_GT(red, 0u);
  EXPECT_LT(red, g->size());
  InitOptions hull;
  hull.method = InitMethod::kVisualHull;
  EXPECT_EQ(InitializeGaussians(**scene, hull).status().code(), StatusCode::kNotFound);  // no masks
}

TEST(Init, RandomCubeForMonocularData) {
  ATEX_REQUIRE_DATA_FILE(npz, "dnerf_lego_tiny/tiny_dnerf_data.npz");
  auto lego = OpenDataset(npz.string());
  ASSERT_TRUE(lego.ok());
  InitOptions options;
  options.cube_points = 5000;
  options.sh_degree = 0;
  InitReport report;
  auto g = InitializeGaussians(**lego, options, &report);
  ASSERT_TRUE(g.ok()) << g.status().ToString();
  EXPECT_EQ(report.method, InitMethod::kRandomCube);
  ASSERT_EQ(g->size(), 5000u);
  double mean = 0;
  for (float v : g->positions) {
    ASSERT_LE(std::abs(v), 1.3f);
    mean += v;
  }
  EXPECT_NEAR(mean / g->positions.size(), 0.0, 0.05);
  for (float s : g->log_scales) ASSERT_TRUE(std::isfinite(s));
  EXPECT_EQ(g->sh.size(), 5000u * 3);
}

TEST(Init, RejectsBadOptionsAndParsesMethodNames) {
  auto scene = SphereScene(32);
  ASSERT_TRUE(scene.ok());
  InitOptions bad;
  bad.sh_degree = 4;
  EXPECT_EQ(InitializeGaussians(**scene, bad).status().code(), StatusCode::kInvalidArgument);
  bad = InitOptions();
  bad.initial_opacity = 1.0f;
  EXPECT_EQ(InitializeGaussians(**scene, bad).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(ParseInitMethod("hull+volume").value(), InitMethod::kHullAndViewVolume);
  EXPECT_FALSE(ParseInitMethod("sfm").ok());
}

TEST(Init, PanopticHullProjectsIntoTheMasks) {
  ATEX_REQUIRE_DATA_FILE(meta, "panoptic_basketball/train_meta.json");
  DatasetOptions dataset_options;
  dataset_options.max_timesteps = 1;
  auto dataset = OpenDataset(meta.parent_path().string(), dataset_options);
  ASSERT_TRUE(dataset.ok()) << dataset.status().ToString();
  InitOptions options;
  options.hull_points = 4000;
  options.volume_points = 1000;
  options.hull_resolution = 80;
  InitReport report;
  auto g = InitializeGaussians(**dataset, options, &report);
  ASSERT_TRUE(g.ok()) << g.status().ToString();
  EXPECT_EQ(report.method, InitMethod::kHullAndViewVolume);
  EXPECT_EQ(report.cameras, 27);
  ASSERT_EQ(report.hull_points, 4000u);
  EXPECT_GT(report.volume_points, 500u);
  // Two players and a ball: a few metres apart, but a small occupied volume.
  double longest = 0;
  for (int a = 0; a < 3; ++a) {
    const double extent = report.hull_box_max[a] - report.hull_box_min[a];
    EXPECT_LT(extent, 2 * report.camera_distance);
    longest = std::max(longest, extent);
  }
  const double voxel = longest / options.hull_resolution;
  const double occupied = report.hull_voxels * voxel * voxel * voxel / std::pow(report.camera_distance, 3);
  EXPECT_GT(occupied, 0.002);
  EXPECT_LT(occupied, 0.05);

  // Independent check: project each hull point into every training camera with
  // this test's own projection and count the masks that contain it.
  std::vector<std::shared_ptr<const Image>> masks;
  for (const View& v : (*dataset)->train_views()) masks.push_back(*(*dataset)->LoadMask(v));
  size_t good = 0;
  for (size_t i = 0; i < report.hull_points; ++i) {
    const float* x = &g->positions[i * 3];
    int seen = 0, inside = 0;
    for (size_t c = 0; c < masks.size(); ++c) {
      const Camera& cam = (*dataset)->train_views()[c].camera;
      const auto& m = cam.world_to_camera;
      const double pz = m[8] * x[0] + m[9] * x[1] + m[10] * x[2] + m[11];
      const double u = cam.fx * (m[0] * x[0] + m[1] * x[1] + m[2] * x[2] + m[3]) / pz + cam.cx;
      const double v = cam.fy * (m[4] * x[0] + m[5] * x[1] + m[6] * x[2] + m[7]) / pz + cam.cy;
      if (pz <= 0 || u < 0 || v < 0 || u >= cam.width || v >= cam.height) continue;
      ++seen;
      inside += masks[c]->at(int(u), int(v), 0) > 0.5f;
    }
    good += seen >= 10 && inside >= 0.8 * seen;
  }
  EXPECT_GT(good, report.hull_points * 95 / 100);
  // Colours come from the images: not all the same.
  double min_r = 1, max_r = 0;
  for (size_t i = 0; i < g->size(); ++i) {
    min_r = std::min<double>(min_r, g->sh[i * 16 * 3] * kC0 + 0.5);
    max_r = std::max<double>(max_r, g->sh[i * 16 * 3] * kC0 + 0.5);
  }
  EXPECT_GT(max_r - min_r, 0.2);
}

}  // namespace
}  // namespace atex
