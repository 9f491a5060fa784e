// Multi-view stereo on a synthetic scene with known geometry: a ring of cameras around
// a floor, two walls and a sphere, all with a solid value-noise texture, rendered by
// analytic ray casting. The fused points must lie on the true surfaces, cover the
// walls and the floor, carry the texture's colours, respect the target count and be
// deterministic; textureless images must give no points. Also the initialisation
// methods "mvs", "mvs+hull" and "file" through an in-memory dataset.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include <gtest/gtest.h>

#include "atex/init.h"
#include "atex/mvs.h"
#include "atex/point_cloud.h"
#include "core/test_support.h"

namespace atex {
namespace {

constexpr double kWall = 4.0;  // walls at x = −kWall and y = −kWall, floor z = 0 within |x|, |y| <= kWall
constexpr double kSphereRadius = 0.6;
constexpr double kSphere[3] = {0.3, 0.2, 0.6};

double Hash(int x, int y, int z) {
  uint32_t h = uint32_t(x) * 73856093u ^ uint32_t(y) * 19349663u ^ uint32_t(z) * 83492791u;
  h ^= h >> 13;
  h *= 0x5bd1e995u;
  h ^= h >> 15;
  return double(h & 0xFFFF) / 65535.0;
}

// Trilinear value noise on a lattice of spacing 1/frequency.
double Noise(const double p[3], double frequency, int seed) {
  double g[3];
  int i[3];
  for (int a = 0; a < 3; ++a) {
    const double s = p[a] * frequency;
    i[a] = int(std::floor(s));
    g[a] = s - i[a];
  }
  double v = 0;
  for (int c = 0; c < 8; ++c) {
    const int dx = c & 1, dy = (c >> 1) & 1, dz = c >> 2;
    const double w = (dx ? g[0] : 1 - g[0]) * (dy ? g[1] : 1 - g[1]) * (dz ? g[2] : 1 - g[2]);
    v += w * Hash(i[0] + dx + seed, i[1] + dy, i[2] + dz);
  }
  return v;
}

std::array<float, 3> Texture(const double p[3], bool textured) {
  if (!textured) return {0.5f, 0.5f, 0.5f};
  std::array<float, 3> c{};
  for (int a = 0; a < 3; ++a) c[a] = float(0.15 + 0.5 * Noise(p, 6, 17 * a) + 0.3 * Noise(p, 13, 5 + 17 * a));
  return c;
}

// Distance of x to the nearest true surface.
double SurfaceDistance(const float x[3]) {
  const double d_sphere =
      std::abs(std::hypot(x[0] - kSphere[0], x[1] - kSphere[1], x[2] - kSphere[2]) - kSphereRadius);
  return std::min({std::abs(double(x[2])), std::abs(x[0] + kWall), std::abs(x[1] + kWall), d_sphere});
}

// Nearest hit along o + t·d (t > 0); false when the ray leaves the scene.
bool CastRay(const double o[3], const double d[3], double hit[3]) {
  double best = 1e30;
  auto try_plane = [&](int axis, double value) {
    if (std::abs(d[axis]) < 1e-12) return;
    const double t = (value - o[axis]) / d[axis];
    if (t <= 1e-9 || t >= best) return;
    double p[3];
    for (int a = 0; a < 3; ++a) p[a] = o[a] + t * d[a];
    for (int a = 0; a < 3; ++a) {
      if (a != axis && (p[a] < -kWall - 1e-9 || p[a] > kWall)) return;
    }
    if (p[2] < -1e-9) return;
    best = t;
  };
  try_plane(2, 0.0);
  try_plane(0, -kWall);
  try_plane(1, -kWall);
  double oc[3];
  for (int a = 0; a < 3; ++a) oc[a] = o[a] - kSphere[a];
  const double dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  const double od = oc[0] * d[0] + oc[1] * d[1] + oc[2] * d[2];
  const double disc = od * od - dd * (oc[0] * oc[0] + oc[1] * oc[1] + oc[2] * oc[2] - kSphereRadius * kSphereRadius);
  if (disc >= 0) {
    const double t = (-od - std::sqrt(disc)) / dd;
    if (t > 1e-9 && t < best) best = t;
  }
  if (best >= 1e29) return false;
  for (int a = 0; a < 3; ++a) hit[a] = o[a] + best * d[a];
  return true;
}

// A camera at `eye` looking at `target`, world z up.
Camera LookAt(const double eye[3], const double target[3], int width, int height) {
  double f[3], r[3], dn[3];
  double n = 0;
  for (int a = 0; a < 3; ++a) {
    f[a] = target[a] - eye[a];
    n += f[a] * f[a];
  }
  for (double& v : f) v /= std::sqrt(n);
  r[0] = f[1], r[1] = -f[0], r[2] = 0;  // f × (0, 0, 1)
  n = std::hypot(r[0], r[1]);
  r[0] /= n, r[1] /= n;
  dn[0] = f[1] * r[2] - f[2] * r[1], dn[1] = f[2] * r[0] - f[0] * r[2], dn[2] = f[0] * r[1] - f[1] * r[0];
  Camera cam;
  cam.width = width;
  cam.height = height;
  cam.fx = cam.fy = 0.9 * width;
  cam.cx = width / 2.0;
  cam.cy = height / 2.0;
  const double* rows[3] = {r, dn, f};
  for (int i = 0; i < 3; ++i) {
    for (int k = 0; k < 3; ++k) cam.world_to_camera[4 * i + k] = rows[i][k];
    cam.world_to_camera[4 * i + 3] = -(rows[i][0] * eye[0] + rows[i][1] * eye[1] + rows[i][2] * eye[2]);
  }
  return cam;
}

struct Shot {
  Camera camera;
  Image image;
  Image mask;  // the sphere
  double surface_fraction = 0;  // of the pixels whose ray hits a surface
};

// `count` cameras on a ring of radius 2.5 at heights 1.2 / 1.8, looking at the sphere's top.
std::vector<Shot> RingScene(int count, int width, int height, bool textured = true) {
  std::vector<Shot> shots;
  for (int i = 0; i < count; ++i) {
    const double angle = 2 * M_PI * i / count;
    const double eye[3] = {2.5 * std::cos(angle), 2.5 * std::sin(angle), i % 2 ? 1.8 : 1.2};
    const double target[3] = {0, 0, 0.9};
    Shot s{LookAt(eye, target, width, height), Image(width, height, 3), Image(width, height, 1)};
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) {
        const double c[3] = {(x + 0.5 - s.camera.cx) / s.camera.fx, (y + 0.5 - s.camera.cy) / s.camera.fy, 1};
        const auto& m = s.camera.world_to_camera;
        double d[3], hit[3];
        for (int a = 0; a < 3; ++a) d[a] = m[a] * c[0] + m[4 + a] * c[1] + m[8 + a] * c[2];
        std::array<float, 3> colour{0, 0, 0};
        if (CastRay(eye, d, hit)) {
          s.surface_fraction += 1.0 / (width * height);
          colour = Texture(hit, textured);
          const double r = std::hypot(hit[0] - kSphere[0], hit[1] - kSphere[1], hit[2] - kSphere[2]);
          s.mask.at(x, y, 0) = r < kSphereRadius + 1e-6 ? 1.0f : 0.0f;
        }
        for (int a = 0; a < 3; ++a) s.image.at(x, y, a) = colour[a];
      }
    }
    shots.push_back(std::move(s));
  }
  return shots;
}

std::vector<MvsView> Views(const std::vector<Shot>& shots) {
  std::vector<MvsView> views;
  for (const Shot& s : shots) views.push_back({s.camera, std::make_shared<Image>(s.image)});
  return views;
}

MvsOptions TestOptions() {
  MvsOptions o;
  o.max_image_side = 160;
  o.near_depth = 1.0;
  o.far_depth = 12;
  o.neighbors = 4;
  o.best_neighbors = 2;
  return o;
}

const std::vector<Shot>& Scene() {
  static const std::vector<Shot> scene = RingScene(12, 160, 120);
  return scene;
}

// The stereo of Scene() with TestOptions() and its depth maps, computed once.
struct StereoResult {
  StatusOr<PointCloud> cloud = PointCloud();
  MvsReport report;
};
const StereoResult& SceneStereo() {
  static const StereoResult result = [] {
    StereoResult r;
    MvsOptions o = TestOptions();
    o.keep_depth_maps = true;
    r.cloud = MultiViewStereo(Views(Scene()), o, &r.report);
    return r;
  }();
  return result;
}

double Quantile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, size_t(q * v.size()))];
}

TEST(MultiViewStereo, RecoversTheSurfacesOfASyntheticScene) {
  const MvsReport& report = SceneStereo().report;
  const auto& cloud = SceneStereo().cloud;
  ASSERT_TRUE(cloud.ok()) << cloud.status().ToString();
  ASSERT_EQ(report.cameras, 12);
  EXPECT_EQ(report.width, 160);
  EXPECT_EQ(report.downscale, 1);
  ASSERT_GT(cloud->size(), 20000u);
  ASSERT_EQ(cloud->colours.size(), cloud->positions.size());
  std::vector<double> errors, colour_errors;
  size_t floor = 0, walls = 0, sphere = 0;
  for (size_t i = 0; i < cloud->size(); ++i) {
    const float* x = &cloud->positions[3 * i];
    errors.push_back(SurfaceDistance(x));
    const double p[3] = {x[0], x[1], x[2]};
    const auto truth = Texture(p, true);
    for (int a = 0; a < 3; ++a) colour_errors.push_back(std::abs(truth[a] - cloud->colours[3 * i + a]));
    if (std::abs(x[2]) < 0.05) ++floor;
    else if (std::abs(x[0] + kWall) < 0.1 || std::abs(x[1] + kWall) < 0.1) ++walls;
    else if (std::abs(std::hypot(x[0] - kSphere[0], x[1] - kSphere[1], x[2] - kSphere[2]) - kSphereRadius) < 0.05)
      ++sphere;
  }
  // Depth accuracy: a plane step at 3 units is ~2 % of the depth; after the parabola
  // and fusion the points sit within a small fraction of it.
  EXPECT_LT(Quantile(errors, 0.5), 0.01);   // 0.3 % of the median depth
  EXPECT_LT(Quantile(errors, 0.9), 0.04);
  std::printf("surface error median %.4f, 90th %.4f; floor %zu walls %zu sphere %zu of %zu\n", Quantile(errors, 0.5),
              Quantile(errors, 0.9), floor, walls, sphere, cloud->size());
  EXPECT_LT(Quantile(colour_errors, 0.5), 0.05);
  // Every kind of surface is there, floor and walls included.
  EXPECT_GT(floor, cloud->size() / 20);
  EXPECT_GT(walls, cloud->size() / 20);
  EXPECT_GT(sphere, 200u);
  EXPECT_LT(report.median_reprojection_px, 0.5);
  for (int c = 0; c < 12; ++c) {
    // Of the pixels that see a surface (the rest is the empty background): most get a
    // depth, most of those are confirmed by fusion, and the cloud seeds most of them.
    const Shot& shot = Scene()[c];
    const double coverage = PointCoverage(cloud->positions, shot.camera, 160);
    std::printf("camera %d: surface %.3f depth %.3f fused %.3f coverage %.3f\n", c, shot.surface_fraction,
                report.depth_fraction[c], report.fused_fraction[c], coverage);
    EXPECT_GT(report.depth_fraction[c], 0.6 * shot.surface_fraction) << c;
    EXPECT_GT(report.fused_fraction[c], 0.15 * shot.surface_fraction) << c;
    EXPECT_GT(coverage, 0.3 * shot.surface_fraction) << c;
    EXPECT_EQ(report.neighbours[c].size(), 4u) << c;
  }
}

// Depth of pixel (x, y)'s ray to the first surface, camera z; 0 when it leaves the scene.
double TrueDepth(const Camera& cam, int x, int y) {
  const double c[3] = {(x + 0.5 - cam.cx) / cam.fx, (y + 0.5 - cam.cy) / cam.fy, 1};
  const auto& m = cam.world_to_camera;
  const auto o = cam.Center();
  double d[3], hit[3];
  for (int a = 0; a < 3; ++a) d[a] = m[a] * c[0] + m[4 + a] * c[1] + m[8 + a] * c[2];
  if (!CastRay(o.data(), d, hit)) return 0;
  return m[8] * hit[0] + m[9] * hit[1] + m[10] * hit[2] + m[11];
}

TEST(MultiViewStereo, DepthMapsMatchTheTrueDepths) {
  const MvsReport& report = SceneStereo().report;
  ASSERT_TRUE(SceneStereo().cloud.ok()) << SceneStereo().cloud.status().ToString();
  ASSERT_EQ(report.depth_maps.size(), 12u);
  for (int c = 0; c < 12; ++c) {
    const Camera& cam = Scene()[c].camera;
    std::vector<double> relative;
    for (int y = 0; y < cam.height; ++y) {
      for (int x = 0; x < cam.width; ++x) {
        const float d = report.depth_maps[c][size_t(y) * cam.width + x];
        if (d > 0) relative.push_back(std::abs(d / TrueDepth(cam, x, y) - 1));
      }
    }
    ASSERT_FALSE(relative.empty());
    size_t within = std::count_if(relative.begin(), relative.end(), [](double r) { return r < 0.01; });
    std::printf("camera %d: planes %d depth %.3f, median relative error %.4f, within 1%% %.3f\n", c,
                report.depth_planes[c], report.depth_fraction[c], Quantile(relative, 0.5),
                double(within) / relative.size());
    // Fronto-parallel windows on slanted and curved surfaces: most depths within 1-2 %.
    EXPECT_LT(Quantile(relative, 0.5), 0.02) << c;
    EXPECT_GT(double(within) / relative.size(), 0.35) << c;
    // The plane count follows the 1-pixel rule: the ring's neighbours at 30° need about 200.
    EXPECT_GT(report.depth_planes[c], 100) << c;
    EXPECT_LT(report.depth_planes[c], 512) << c;
  }
}

TEST(MultiViewStereo, SubsamplesToTheTargetAndIsDeterministic) {
  MvsOptions o = TestOptions();
  o.max_image_side = 80;
  o.target_points = 2000;
  MvsReport report;
  auto a = MultiViewStereo(Views(Scene()), o, &report);
  ASSERT_TRUE(a.ok()) << a.status().ToString();
  EXPECT_LE(a->size(), 2000u);
  EXPECT_GT(a->size(), 1200u);  // the bisection gets close to the target
  EXPECT_GT(report.voxel_size, 0);
  EXPECT_GT(report.fused_points, a->size());
  EXPECT_EQ(report.output_points, a->size());
  std::vector<double> errors;
  for (size_t i = 0; i < a->size(); ++i) errors.push_back(SurfaceDistance(&a->positions[3 * i]));
  EXPECT_LT(Quantile(errors, 0.5), 0.5 * report.voxel_size);  // voxel means stay on the surfaces
  auto b = MultiViewStereo(Views(Scene()), o);
  ASSERT_TRUE(b.ok());
  EXPECT_EQ(a->positions, b->positions);
  EXPECT_EQ(a->colours, b->colours);
}

TEST(MultiViewStereo, NeedsTextureAndValidInputs) {
  static const std::vector<Shot> flat = RingScene(6, 80, 60, /*textured=*/false);
  MvsOptions o = TestOptions();
  auto none = MultiViewStereo(Views(flat), o);
  EXPECT_EQ(none.status().code(), StatusCode::kNotFound) << none.status().ToString();

  std::vector<MvsView> one = {Views(flat)[0]};
  EXPECT_EQ(MultiViewStereo(one, o).status().code(), StatusCode::kInvalidArgument);
  MvsOptions bad = o;
  bad.far_depth = bad.near_depth;
  EXPECT_EQ(MultiViewStereo(Views(flat), bad).status().code(), StatusCode::kInvalidArgument);
  bad = o;
  bad.best_neighbors = bad.neighbors + 1;
  EXPECT_EQ(MultiViewStereo(Views(flat), bad).status().code(), StatusCode::kInvalidArgument);
  std::vector<MvsView> wrong = Views(flat);
  wrong[1].camera.width = 81;
  EXPECT_EQ(MultiViewStereo(wrong, o).status().code(), StatusCode::kInvalidArgument);
}

TEST(MultiViewStereo, DownscalesToTheMaximumSide) {
  EXPECT_EQ(DownscaleFactorFor(Scene()[0].camera, 160), 1);
  EXPECT_EQ(DownscaleFactorFor(Scene()[0].camera, 80), 2);
  EXPECT_EQ(DownscaleFactorFor(Scene()[0].camera, 79), 3);
  const Camera half = DownscaledCamera(Scene()[0].camera, 2);
  EXPECT_EQ(half.width, 80);
  EXPECT_DOUBLE_EQ(half.fx, Scene()[0].camera.fx / 2);
  MvsOptions o = TestOptions();
  o.max_image_side = 80;
  MvsReport report;
  auto cloud = MultiViewStereo(Views(Scene()), o, &report);
  ASSERT_TRUE(cloud.ok()) << cloud.status().ToString();
  EXPECT_EQ(report.width, 80);
  EXPECT_EQ(report.downscale, 2);
  std::vector<double> errors;
  for (size_t i = 0; i < cloud->size(); ++i) errors.push_back(SurfaceDistance(&cloud->positions[3 * i]));
  EXPECT_LT(Quantile(errors, 0.5), 0.02);
}

TEST(PointCoverage, CountsPixelsHitOnce) {
  const Camera& cam = Scene()[0].camera;
  std::vector<float> points;
  // One point per pixel of the top-left 10×10 block at depth 2, and one behind the camera.
  for (int y = 0; y < 10; ++y) {
    for (int x = 0; x < 10; ++x) {
      const double pc[3] = {(x + 0.5 - cam.cx) / cam.fx * 2, (y + 0.5 - cam.cy) / cam.fy * 2, 2};
      const auto& m = cam.world_to_camera;
      for (int a = 0; a < 3; ++a) {
        points.push_back(float(m[a] * (pc[0] - m[3]) + m[4 + a] * (pc[1] - m[7]) + m[8 + a] * (pc[2] - m[11])));
      }
    }
  }
  const auto c = cam.Center();
  points.insert(points.end(), {float(2 * c[0]), float(2 * c[1]), float(2 * c[2])});  // behind it
  EXPECT_NEAR(PointCoverage(points, cam, 160), 100.0 / (160 * 120), 1e-12);
  EXPECT_NEAR(PointCoverage(points, cam, 80), 25.0 / (80 * 60), 1e-12);  // 2×2 blocks
}

// The initialisation methods through a dataset.
StatusOr<std::unique_ptr<Dataset>> SceneDataset() {
  std::vector<InMemoryFrame> frames;
  for (size_t i = 0; i < Scene().size(); ++i) {
    InMemoryFrame f;
    f.view.camera = Scene()[i].camera;
    f.view.camera_id = int(i);
    f.view.timestep = 0;
    f.image = Scene()[i].image;
    f.mask = Scene()[i].mask;
    frames.push_back(std::move(f));
  }
  return MakeInMemoryDataset("ring", std::move(frames));
}

TEST(InitFromStereo, MvsAndMvsWithHull) {
  auto dataset = SceneDataset();
  ASSERT_TRUE(dataset.ok()) << dataset.status().ToString();
  InitOptions o;
  o.method = InitMethod::kMvs;
  o.mvs = TestOptions();
  o.mvs.max_image_side = 80;
  o.mvs_points = 3000;
  o.mvs_near = 0.2;
  o.mvs_far = 4;
  InitReport report;
  auto g = InitializeGaussians(**dataset, o, &report);
  ASSERT_TRUE(g.ok()) << g.status().ToString();
  EXPECT_EQ(report.method, InitMethod::kMvs);
  EXPECT_EQ(report.mvs_points, g->size());
  EXPECT_LE(g->size(), 3000u);
  EXPECT_GT(g->size(), 1500u);
  EXPECT_EQ(report.hull_points, 0u);
  EXPECT_EQ(report.mvs.cameras, 12);
  std::vector<double> errors;
  for (size_t i = 0; i < g->size(); ++i) errors.push_back(SurfaceDistance(&g->positions[3 * i]));
  EXPECT_LT(Quantile(errors, 0.5), 0.05);
  for (float s : g->log_scales) ASSERT_TRUE(std::isfinite(s));

  o.method = InitMethod::kMvsAndHull;
  o.hull_points = 500;
  o.hull_resolution = 32;
  auto both = InitializeGaussians(**dataset, o, &report);
  ASSERT_TRUE(both.ok()) << both.status().ToString();
  EXPECT_EQ(report.hull_points, 500u);
  EXPECT_EQ(both->size(), 500u + report.mvs_points);
  for (size_t i = 0; i < 500; ++i) {  // hull points come first, inside the sphere's hull
    const float* x = &both->positions[3 * i];
    EXPECT_LT(std::hypot(x[0] - kSphere[0], x[1] - kSphere[1], x[2] - kSphere[2]), kSphereRadius * 1.6) << i;
  }
}

TEST(InitFromFile, ReadsAPlyAndColoursPointsWithoutColours) {
  auto dataset = SceneDataset();
  ASSERT_TRUE(dataset.ok()) << dataset.status().ToString();
  const testing::TempDir temp;
  const std::filesystem::path& dir = temp.path();
  // Points on the floor, with and without colours.
  PointCloud cloud;
  for (int i = 0; i < 400; ++i) {
    cloud.positions.insert(cloud.positions.end(), {float(-2 + 0.01 * i), float(1 - 0.005 * i), 0.0f});
    cloud.colours.insert(cloud.colours.end(), {0.25f, 0.5f, 1.0f});
  }
  ASSERT_TRUE(WritePlyPoints((dir / "coloured.ply").string(), cloud).ok());
  PointCloud bare = cloud;
  bare.colours.clear();
  ASSERT_TRUE(WritePlyPoints((dir / "bare.ply").string(), bare).ok());

  InitOptions o;
  o.method = InitMethod::kFile;
  o.point_cloud_path = (dir / "coloured.ply").string();
  o.file_points = 100;
  InitReport report;
  auto g = InitializeGaussians(**dataset, o, &report);
  ASSERT_TRUE(g.ok()) << g.status().ToString();
  ASSERT_EQ(g->size(), 100u);
  EXPECT_EQ(report.file_points, 100u);
  EXPECT_FLOAT_EQ(g->positions[3 * 1], cloud.positions[3 * 4]);  // evenly spaced: point floor(1·400/100)
  const int k = g->sh_coeffs();
  EXPECT_NEAR(g->sh[0] * 0.28209479177387814 + 0.5, 64 / 255.0, 1e-6);  // the PLY's uchar colours
  EXPECT_NEAR(g->sh[2] * 0.28209479177387814 + 0.5, 1.0, 1e-6);

  o.point_cloud_path = (dir / "bare.ply").string();
  o.file_points = 0;
  auto b = InitializeGaussians(**dataset, o, &report);
  ASSERT_TRUE(b.ok()) << b.status().ToString();
  ASSERT_EQ(b->size(), 400u);
  for (size_t i = 0; i < b->size(); i += 37) {  // colours from the images: the floor's texture
    const double p[3] = {b->positions[3 * i], b->positions[3 * i + 1], b->positions[3 * i + 2]};
    const auto truth = Texture(p, true);
    EXPECT_NEAR(b->sh[i * k * 3] * 0.28209479177387814 + 0.5, truth[0], 0.12) << i;
  }
  o.point_cloud_path = (dir / "missing.ply").string();
  EXPECT_EQ(InitializeGaussians(**dataset, o).status().code(), StatusCode::kNotFound);
  o.point_cloud_path.clear();
  EXPECT_EQ(InitializeGaussians(**dataset, o).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(*ParseInitMethod("mvs+hull"), InitMethod::kMvsAndHull);
  EXPECT_EQ(*ParseInitMethod("file"), InitMethod::kFile);
  EXPECT_STREQ(InitMethodName(InitMethod::kMvs), "mvs");
}

// Real data: the stereo on Panoptic's first timestep covers the training views.
TEST(MultiViewStereo, PanopticFirstTimestep) {
  ATEX_REQUIRE_DATA_FILE(meta, "panoptic_basketball/train_meta.json");
  const std::filesystem::path root = meta.parent_path();
  DatasetOptions dopt;
  dopt.max_timesteps = 1;
  auto dataset = OpenDataset(root.string(), dopt);
  ASSERT_TRUE(dataset.ok()) << dataset.status().ToString();
  InitOptions o;
  o.method = InitMethod::kMvs;
  o.mvs.max_image_side = 160;  // quick: a quarter of the default's pixels
  o.mvs.depth_planes = 128;
  o.mvs_points = 20000;
  InitReport report;
  auto g = InitializeGaussians(**dataset, o, &report);
  ASSERT_TRUE(g.ok()) << g.status().ToString();
  EXPECT_GT(g->size(), 15000u);
  EXPECT_LT(report.mvs.median_reprojection_px, 0.5);
  double mean_coverage = 0;
  for (const View* v : FirstTimestepViews((*dataset)->train_views())) {
    mean_coverage += PointCoverage(g->positions, v->camera, 160);
  }
  mean_coverage /= report.mvs.cameras;
  EXPECT_GT(mean_coverage, 0.3);  // the walls and the floor, not only the people
}

}  // namespace
}  // namespace atex
