// Stress suite at CPU scale (issue 9): degenerate content and numerical stress through
// the CPU reference renderer, the container and the CPU training backend.
//
// Every case records one outcome in a table:
//   ok          finished, output finite and as expected
//   error       the library refused with a Status that names the problem
//   nan         a NaN/Inf reached an output that was reported as OK      -> test FAILS
//   collapse    training finished with no Gaussians left
//   low-psnr    finished and finite, but the picture is wrong or poor (precision, capacity)
// A case FAILS on a crash (the executable dies), an uncaught NaN in an output, or an error
// Status without a message; every other outcome is a finding for the table. The table is
// written to $ATEX_BINARY_DIR/tests/stress/stress_table.{json,md} after the last test.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <numbers>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "atex/container.h"
#include "atex/dataset.h"
#include "atex/deform.h"
#include "atex/metrics.h"
#include "atex/render.h"
#include "atex/train/backend.h"
#include "atex/train/trainer.h"
#include "core/test_support.h"

namespace atex {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// ---------------------------------------------------------------------------
// The outcome table.

struct CaseRow {
  std::string name, group, outcome, message;
  double seconds = 0;
};

class StressTable {
 public:
  static StressTable& Get() {
    static StressTable table;
    return table;
  }
  void Add(CaseRow row) { rows_.push_back(std::move(row)); }

  void Write() const {
    const char* bin = std::getenv("ATEX_BINARY_DIR");
    const fs::path dir = fs::path(bin ? bin : ".") / "tests" / "stress";
    std::error_code ec;
    fs::create_directories(dir, ec);
    nlohmann::json cases = nlohmann::json::array();
    std::map<std::string, int> counts;
    for (const CaseRow& r : rows_) {
      cases.push_back({{"case", r.name}, {"group", r.group}, {"outcome", r.outcome}, {"message", r.message},
                       {"seconds", std::round(r.seconds * 1000) / 1000}});
      ++counts[r.outcome];
    }
    std::ofstream json(dir / "stress_table.json");
    json << nlohmann::json{{"cases", cases}, {"counts", counts}}.dump(2) << "\n";
    std::ofstream md(dir / "stress_table.md");
    md << "| case | group | outcome | seconds | message |\n|---|---|---|---:|---|\n";
    for (const CaseRow& r : rows_) {
      std::string message = r.message;
      std::replace(message.begin(), message.end(), '|', '/');
      std::replace(message.begin(), message.end(), '\n', ' ');
      char seconds[32];
      std::snprintf(seconds, sizeof seconds, "%.2f", r.seconds);
      md << "| " << r.name << " | " << r.group << " | " << r.outcome << " | " << seconds << " | " << message << " |\n";
    }
    md << "\n";
    for (const auto& [outcome, n] : counts) md << "- " << outcome << ": " << n << "\n";
    std::printf("[stress] table written to %s (%zu cases)\n", (dir / "stress_table.md").c_str(), rows_.size());
  }

 private:
  std::vector<CaseRow> rows_;
};

class TableWriter : public ::testing::Environment {
 public:
  void TearDown() override { StressTable::Get().Write(); }
};
[[maybe_unused]] ::testing::Environment* const kTableWriter = ::testing::AddGlobalTestEnvironment(new TableWriter);

// Records one case; fails the test for an error without a message or an uncaught NaN.
class Case {
 public:
  Case(std::string name, std::string group) : start_(Clock::now()) {
    row_.name = std::move(name);
    row_.group = std::move(group);
  }
  ~Case() {
    if (row_.outcome.empty()) Set("error", "case ended without an outcome (an assertion failed first)");
    row_.seconds = std::chrono::duration<double>(Clock::now() - start_).count();
    std::printf("[stress] %-40s %-9s %s\n", row_.name.c_str(), row_.outcome.c_str(), row_.message.c_str());
    StressTable::Get().Add(row_);
  }
  void Set(const std::string& outcome, const std::string& message) {
    row_.outcome = outcome;
    row_.message = message;
    if (outcome == "nan") ADD_FAILURE() << row_.name << ": uncaught NaN/Inf in an output: " << message;
  }
  void Ok(const std::string& message = "") { Set("ok", message); }
  // An error Status is a legitimate outcome only when it says what went wrong.
  void Error(const Status& status) {
    EXPECT_FALSE(status.message().empty()) << row_.name << ": error without a message (" << status.ToString() << ")";
    Set("error", status.ToString());
  }

 private:
  CaseRow row_;
  Clock::time_point start_;
};

std::string Fmt(const char* format, double a, double b = 0, double c = 0) {
  char buffer[256];
  std::snprintf(buffer, sizeof buffer, format, a, b, c);
  return buffer;
}

bool AllFinite(const std::vector<float>& v) {
  return std::all_of(v.begin(), v.end(), [](float x) { return std::isfinite(x); });
}

// ---------------------------------------------------------------------------
// Scenes and cameras.

// OpenCV world-to-camera looking from `eye` at `target` (world up = +y).
Camera LookAt(std::array<double, 3> eye, std::array<double, 3> target, int width, int height, double focal) {
  auto sub = [](auto a, auto b) { return std::array<double, 3>{a[0] - b[0], a[1] - b[1], a[2] - b[2]}; };
  auto cross = [](auto a, auto b) {
    return std::array<double, 3>{a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
  };
  auto normalize = [](std::array<double, 3> a) {
    const double n = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    return std::array<double, 3>{a[0] / n, a[1] / n, a[2] / n};
  };
  const auto f = normalize(sub(target, eye));
  const auto r = normalize(cross(f, std::array<double, 3>{0, 1, 0}));
  const auto d = cross(f, r);
  Camera c;
  c.width = width;
  c.height = height;
  c.fx = c.fy = focal;
  c.cx = 0.5 * width;
  c.cy = 0.5 * height;
  const std::array<std::array<double, 3>, 3> rows{r, d, f};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) c.world_to_camera[i * 4 + j] = rows[i][j];
    c.world_to_camera[i * 4 + 3] = -(rows[i][0] * eye[0] + rows[i][1] * eye[1] + rows[i][2] * eye[2]);
  }
  return c;
}

Camera BaseCamera() {
  Camera c;
  c.width = 64;
  c.height = 48;
  c.fx = c.fy = 60;
  c.cx = 32;
  c.cy = 24;
  return c;  // identity pose: at the origin looking along +z
}

// N Gaussians in front of the base camera (z in [3, 6]), SH degree 1.
Gaussians BaseGaussians(int n = 64, uint32_t seed = 9) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  Gaussians g;
  g.sh_degree = 1;
  g.Resize(n);
  for (int i = 0; i < n; ++i) {
    g.positions[3 * i] = 1.2f * u(rng);
    g.positions[3 * i + 1] = 0.9f * u(rng);
    g.positions[3 * i + 2] = 4.5f + 1.5f * u(rng);
    for (int k = 0; k < 4; ++k) g.rotations[4 * i + k] = u(rng) + (k == 0 ? 1.5f : 0.0f);
    for (int k = 0; k < 3; ++k) g.log_scales[3 * i + k] = std::log(0.15f) + 0.4f * u(rng);
    g.opacity_logits[i] = 1.0f + u(rng);
    for (size_t k = 0; k < size_t(g.sh_coeffs()) * 3; ++k) g.sh[i * g.sh_coeffs() * 3 + k] = (k < 3 ? 1.0f : 0.3f) * u(rng);
  }
  return g;
}

// Adaptive-looking textures: sides cycling through {1, 2, 4}, random texels.
TexturePool MixedTextures(const Gaussians& g, float range = 1.5f, uint32_t seed = 11) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-range, range);
  TexturePool pool;
  const uint8_t sides[] = {1, 2, 4};
  for (size_t i = 0; i < g.size(); ++i) {
    pool.heights.push_back(sides[i % 3]);
    pool.widths.push_back(sides[(i / 3) % 3]);
    pool.axis_u.push_back(static_cast<uint8_t>(i % 3));
    pool.axis_v.push_back(static_cast<uint8_t>((i + 1) % 3));
  }
  pool.RebuildOffsets();
  pool.texels.resize(pool.texel_count() * 4);
  for (float& t : pool.texels) t = u(rng);
  return pool;
}

StatusOr<RenderOutput> Render(const Camera& camera, const Gaussians& g, const TexturePool* textures = nullptr,
                              RenderSettings settings = {}) {
  settings.active_sh_degree = g.sh_degree;
  return RenderForward<float>(camera, g, textures, settings);
}

double Psnr(const std::vector<float>& a, const std::vector<float>& b) {
  double sse = 0;
  for (size_t k = 0; k < a.size(); ++k) sse += (double(a[k]) - b[k]) * (double(a[k]) - b[k]);
  const double mse = sse / std::max<size_t>(1, a.size());
  return mse > 0 ? -10.0 * std::log10(mse) : 99.0;
}

double MaxAbsFromBackground(const std::vector<float>& color, const std::array<float, 3>& background) {
  double worst = 0;
  for (size_t k = 0; k < color.size(); ++k) worst = std::max(worst, std::abs(double(color[k]) - background[k % 3]));
  return worst;
}

// Renders, classifies and returns the output when it is usable (ok and finite).
std::optional<RenderOutput> RenderCase(Case& c, const Camera& camera, const Gaussians& g,
                                       const TexturePool* textures = nullptr, RenderSettings settings = {}) {
  auto out = Render(camera, g, textures, settings);
  if (!out.ok()) {
    c.Error(out.status());
    return std::nullopt;
  }
  if (!AllFinite(out->color) || !AllFinite(out->alpha)) {
    c.Set("nan", "render reported OK but its colour/alpha holds NaN/Inf");
    return std::nullopt;
  }
  return std::move(*out);
}

// ---------------------------------------------------------------------------
// Degenerate content through the reference renderer.

TEST(StressRender, NearZeroScales) {
  for (float scale : {1e-6f, 1e-12f, 1e-30f}) {
    Case c(Fmt("render/near-zero-scale-%g", scale), "degenerate content");
    Gaussians g = BaseGaussians();
    for (float& s : g.log_scales) s = std::log(scale);
    auto out = RenderCase(c, BaseCamera(), g);
    if (!out) continue;
    int visible = 0;
    for (int r : out->radius) visible += r > 0;
    // The 0.3 px low-pass keeps sub-pixel Gaussians as small dots (3DGS's dilation).
    c.Ok(StrCat(visible, " of ", g.size(), " visible; alpha max ",
                *std::max_element(out->alpha.begin(), out->alpha.end())));
  }
  {
    Case c("render/log-scale=-inf (zero scale)", "degenerate content");
    Gaussians g = BaseGaussians();
    g.log_scales[5] = -INFINITY;
    if (auto out = RenderCase(c, BaseCamera(), g)) c.Ok("accepted a zero scale");
  }
}

TEST(StressRender, HugeScales) {
  for (float scale : {1e3f, 1e8f, 1e15f, 1e19f, 1e30f}) {
    Case c(Fmt("render/huge-scale-%g", scale), "degenerate content");
    Gaussians g = BaseGaussians(16);
    for (float& s : g.log_scales) s = std::log(scale);
    auto out = RenderCase(c, BaseCamera(), g);
    if (!out) continue;
    int visible = 0;
    for (int r : out->radius) visible += r > 0;
    c.Ok(visible > 0 ? StrCat(visible, " of ", g.size(), " visible (the camera is inside them)")
                     : StrCat("all ", g.size(), " culled: their 2D covariance overflows float32 (not finite: "
                              "invisible by conventions §4.3), silently"));
  }
}

TEST(StressRender, BehindTheCameraAndAtTheNearPlane) {
  RenderSettings settings;
  settings.background = {0.2f, 0.4f, 0.6f};
  {
    Case c("render/all-behind-camera", "degenerate content");
    Gaussians g = BaseGaussians();
    for (size_t i = 0; i < g.size(); ++i) g.positions[3 * i + 2] = -g.positions[3 * i + 2];
    if (auto out = RenderCase(c, BaseCamera(), g, nullptr, settings)) {
      const double dev = MaxAbsFromBackground(out->color, settings.background);
      dev == 0 ? c.Ok("image is exactly the background")
               : c.Set("low-psnr", StrCat("Gaussians behind the camera changed pixels by up to ", dev));
    }
  }
  {
    Case c("render/straddling-near-plane", "degenerate content");
    Gaussians g = BaseGaussians();
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(-1, 1);
    for (size_t i = 0; i < g.size(); ++i) {
      g.positions[3 * i + 2] = settings.near_plane + 0.005f * u(rng);  // around the near plane
      for (int k = 0; k < 3; ++k) g.log_scales[3 * i + k] = std::log(0.5f);
    }
    if (auto out = RenderCase(c, BaseCamera(), g, nullptr, settings)) {
      int visible = 0;
      for (int r : out->radius) visible += r > 0;
      c.Ok(StrCat(visible, " of ", g.size(), " within 5 mm of the near plane rasterised"));
    }
  }
}

TEST(StressRender, AllTransparentAndEmpty) {
  RenderSettings settings;
  settings.background = {0.25f, 0.5f, 0.75f};
  for (float logit : {-30.0f, -100.0f, -1e30f}) {
    Case c(Fmt("render/all-transparent-logit-%g", logit), "degenerate content");
    Gaussians g = BaseGaussians();
    for (float& o : g.opacity_logits) o = logit;
    if (auto out = RenderCase(c, BaseCamera(), g, nullptr, settings)) {
      const double dev = MaxAbsFromBackground(out->color, settings.background);
      dev < 1e-6 ? c.Ok(StrCat("background within ", dev))
                 : c.Set("low-psnr", StrCat("transparent Gaussians changed pixels by ", dev));
    }
  }
  {
    Case c("render/fully-opaque-logit-1e30", "degenerate content");
    Gaussians g = BaseGaussians();
    for (float& o : g.opacity_logits) o = 1e30f;
    if (auto out = RenderCase(c, BaseCamera(), g, nullptr, settings)) c.Ok("opacity saturates at the 0.99 clamp");
  }
  {
    Case c("render/empty-model", "degenerate content");
    Gaussians g;
    g.sh_degree = 1;
    if (auto out = RenderCase(c, BaseCamera(), g, nullptr, settings)) {
      const double dev = MaxAbsFromBackground(out->color, settings.background);
      dev == 0 ? c.Ok("background") : c.Set("low-psnr", StrCat("empty model drew pixels: ", dev));
    }
  }
  {
    Case c("render/1x1-image", "degenerate content");
    Camera cam = BaseCamera();
    cam.width = cam.height = 1;
    cam.cx = cam.cy = 0.5;
    if (auto out = RenderCase(c, cam, BaseGaussians())) c.Ok();
  }
  {
    Case c("render/10000-coincident-gaussians", "degenerate content");
    Gaussians g = BaseGaussians(10000);
    for (size_t i = 0; i < g.size(); ++i) {
      g.positions[3 * i] = 0.1f;
      g.positions[3 * i + 1] = -0.1f;
      g.positions[3 * i + 2] = 4.0f;
    }
    if (auto out = RenderCase(c, BaseCamera(), g)) c.Ok("equal depths, index order");
  }
}

TEST(StressRender, ExtremeAnisotropy) {
  const std::vector<std::pair<std::string, std::array<float, 3>>> shapes = {
      {"disc 1e-6:1:1", {1e-6f, 1.0f, 1.0f}},
      {"needle 1e-6:1e-6:1", {1e-6f, 1e-6f, 1.0f}},
      {"disc 1e-12:1:1", {1e-12f, 1.0f, 1.0f}}};
  for (const auto& [label, scales] : shapes) {
    for (bool textured : {false, true}) {
      Case c(StrCat("render/anisotropy ", label, textured ? " textured" : ""), "degenerate content");
      Gaussians g = BaseGaussians();
      for (size_t i = 0; i < g.size(); ++i) {
        for (int k = 0; k < 3; ++k) g.log_scales[3 * i + k] = std::log(0.3f * scales[k]);
      }
      // Half of them seen exactly edge-on (identity rotation: the thin axis is camera x).
      for (size_t i = 0; i < g.size(); i += 2) {
        g.rotations[4 * i] = 1;
        g.rotations[4 * i + 1] = g.rotations[4 * i + 2] = g.rotations[4 * i + 3] = 0;
      }
      const TexturePool pool = MixedTextures(g);
      auto out = RenderCase(c, BaseCamera(), g, textured ? &pool : nullptr);
      if (!out) continue;
      // The backward pass too: gradients must stay finite.
      RenderSettings settings;
      settings.active_sh_degree = g.sh_degree;
      std::vector<float> grad_color(out->color.size(), 1.0f);
      RenderGradients grads;
      const Status s = RenderBackward<float>(BaseCamera(), g, textured ? &pool : nullptr, settings, *out,
                                             grad_color.data(), nullptr, &grads);
      if (!s.ok()) {
        c.Error(s);
      } else if (!AllFinite(grads.gaussians.positions) || !AllFinite(grads.gaussians.log_scales) ||
                 !AllFinite(grads.gaussians.rotations) || !AllFinite(grads.texels)) {
        c.Set("nan", "backward pass reported OK with NaN/Inf gradients");
      } else {
        c.Ok("forward and backward finite");
      }
    }
  }
}

TEST(StressRender, InvalidNumbersAreRefusedWithAMessage) {
  struct Bad {
    std::string name;
    std::function<void(Gaussians*)> poison;
  };
  const std::vector<Bad> cases = {
      {"render/nan-position", [](Gaussians* g) { g->positions[7] = NAN; }},
      {"render/inf-position", [](Gaussians* g) { g->positions[7] = INFINITY; }},
      {"render/zero-quaternion", [](Gaussians* g) { std::fill_n(g->rotations.begin() + 8, 4, 0.0f); }},
      {"render/nan-opacity", [](Gaussians* g) { g->opacity_logits[3] = NAN; }},
      {"render/nan-sh", [](Gaussians* g) { g->sh[5] = NAN; }},
      {"render/denormal-quaternion", [](Gaussians* g) { std::fill_n(g->rotations.begin() + 8, 4, 1e-42f); }},
  };
  for (const Bad& bad : cases) {
    Case c(bad.name, "numerical stress");
    Gaussians g = BaseGaussians();
    bad.poison(&g);
    if (auto out = RenderCase(c, BaseCamera(), g)) c.Ok("accepted and rendered finite");
  }
  {
    Case c("render/nan-texel", "numerical stress");
    Gaussians g = BaseGaussians();
    TexturePool pool = MixedTextures(g);
    pool.texels[10] = NAN;
    if (auto out = RenderCase(c, BaseCamera(), g, &pool)) c.Ok("accepted and rendered finite");
  }
}

// ---------------------------------------------------------------------------
// Scale and position of the whole scene (float32 precision).

// The base scene moved by x -> s * x + offset, its camera with it: the image must not change.
void TransformedSceneCase(const std::string& name, double s, double offset, double near_scale) {
  Case c(name, "numerical stress");
  const Camera base_cam = BaseCamera();
  const Gaussians base = BaseGaussians();
  auto reference = Render(base_cam, base);
  ASSERT_TRUE(reference.ok()) << reference.status().ToString();
  Gaussians g = base;
  for (size_t i = 0; i < g.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      g.positions[3 * i + k] = static_cast<float>(s * base.positions[3 * i + k] + offset);
      g.log_scales[3 * i + k] = static_cast<float>(base.log_scales[3 * i + k] + std::log(s));
    }
  }
  Camera cam = base_cam;
  // Camera centre C' = s C + o with the same rotation: t' = -R C' = s t - R o.
  for (int i = 0; i < 3; ++i) {
    double r_o = 0;
    for (int j = 0; j < 3; ++j) r_o += cam.world_to_camera[i * 4 + j] * offset;
    cam.world_to_camera[i * 4 + 3] = s * cam.world_to_camera[i * 4 + 3] - r_o;
  }
  RenderSettings settings;
  settings.near_plane = static_cast<float>(0.01 * near_scale);
  auto out = RenderCase(c, cam, g, nullptr, settings);
  if (!out) return;
  const double psnr = Psnr(out->color, reference->color);
  if (psnr >= 40) {
    c.Ok(Fmt("PSNR %.1f dB against the untransformed scene", psnr));
  } else {
    c.Set("low-psnr", Fmt("PSNR %.1f dB against the untransformed scene (float32 positions: spacing %.3g world "
                          "units at this offset)",
                          psnr, std::nextafter(static_cast<float>(std::abs(offset) + 6 * s), INFINITY) -
                                    static_cast<float>(std::abs(offset) + 6 * s)));
  }
}

TEST(StressScale, LargeAndSmallSceneScale) {
  TransformedSceneCase("scale/scene-x1e4", 1e4, 0, 1);
  TransformedSceneCase("scale/scene-x1e-3 (near plane x1e-3)", 1e-3, 0, 1e-3);
}

TEST(StressScale, FarFromOrigin) {
  for (double offset : {1e3, 1e4, 1e5, 1e6, 1e7}) TransformedSceneCase(Fmt("scale/offset-%g", offset), 1, offset, 1);
  TransformedSceneCase("scale/x1e4-and-offset-1e5", 1e4, 1e5, 1);
}

// ---------------------------------------------------------------------------
// float16 texels through the container.

Asset TexturedAsset(float texel_range) {
  Asset asset;
  asset.gaussians = BaseGaussians();
  asset.textures = MixedTextures(asset.gaussians, texel_range);
  asset.metadata.texture_mode = "adaptive";
  return asset;
}

void Float16Case(const std::string& name, float texel_range, bool everything_half) {
  Case c(name, "numerical stress");
  const Asset asset = TexturedAsset(texel_range);
  WriteOptions options;
  options.texels = ScalarEncoding::kFloat16;
  if (everything_half) {
    options.positions = options.rotations = options.log_scales = options.opacities = options.sh_dc =
        options.sh_rest = ScalarEncoding::kFloat16;
  }
  auto bytes = EncodeAsset(asset, options);
  if (!bytes.ok()) return c.Error(bytes.status());
  auto decoded = DecodeAsset(bytes->data(), bytes->size());
  if (!decoded.ok()) return c.Error(decoded.status());
  if (!decoded->textures) return c.Set("error", "textures lost in the round trip");
  if (!AllFinite(decoded->textures->texels)) return c.Set("nan", "decoded texels hold NaN/Inf");
  auto reference = Render(BaseCamera(), asset.gaussians, &*asset.textures);
  ASSERT_TRUE(reference.ok());
  auto out = RenderCase(c, BaseCamera(), decoded->gaussians, &*decoded->textures);
  if (!out) return;
  const double psnr = Psnr(out->color, reference->color);
  const std::string what = Fmt("%.0f bytes; PSNR %.1f dB against the float32 render", bytes->size(), psnr);
  psnr >= 40 ? c.Ok(what) : c.Set("low-psnr", what);
}

TEST(StressContainer, Float16Texels) {
  Float16Case("container/f16-texels round trip + render", 1.5f, false);
  Float16Case("container/f16-everything round trip + render", 1.5f, true);
  // Beyond float16's range (65504): the texel saturates tanh anyway, but the encoding must not make Inf.
  Float16Case("container/f16-texels beyond 65504", 1e5f, false);
}

// ---------------------------------------------------------------------------
// Deformation far outside the trained time range.

TEST(StressDeform, TimeFarOutsideTheRange) {
  for (double time : {1e3, 1e9}) {
    Case c(Fmt("deform/time-%g", time), "numerical stress");
    DeformationConfig dc;
    dc.grid.channels = 4;
    dc.grid.base_resolution = {8, 8, 8, 8};
    dc.mlp_width = 16;
    dc.sh_coeffs = 4;
    auto field = InitDeformationField(dc, 5);
    ASSERT_TRUE(field.ok()) << field.status().ToString();
    Gaussians deformed;
    const Status s = DeformForward(*field, BaseGaussians(), time, &deformed, nullptr);
    if (!s.ok()) {
      c.Error(s);
      continue;
    }
    if (!AllFinite(deformed.positions) || !AllFinite(deformed.log_scales) || !AllFinite(deformed.rotations)) {
      c.Set("nan", "deformed parameters hold NaN/Inf");
      continue;
    }
    if (auto out = RenderCase(c, BaseCamera(), deformed)) c.Ok("deformed parameters and render finite");
  }
}

// ---------------------------------------------------------------------------
// Training on the CPU backend: synthetic multi-view videos at tiny resolution.

// A ground-truth scene: a few coloured blobs orbiting the origin (period = the sequence).
Gaussians MovingScene(double time, double scene_scale) {
  Gaussians g;
  g.sh_degree = 0;
  const int n = 12;
  g.Resize(n);
  for (int i = 0; i < n; ++i) {
    const double phase = 2 * std::numbers::pi * (i / double(n) + time);
    const double radius = 0.3 + 0.05 * (i % 4);
    g.positions[3 * i] = static_cast<float>(scene_scale * radius * std::cos(phase));
    g.positions[3 * i + 1] = static_cast<float>(scene_scale * 0.1 * ((i % 3) - 1));
    g.positions[3 * i + 2] = static_cast<float>(scene_scale * radius * std::sin(phase));
    g.rotations[4 * i] = 1;
    for (int k = 0; k < 3; ++k) g.log_scales[3 * i + k] = static_cast<float>(std::log(0.25 * scene_scale));
    g.opacity_logits[i] = 3;
    for (int k = 0; k < 3; ++k) g.sh[3 * i + k] = static_cast<float>(((i + k) % 3) - 0.5);
  }
  return g;
}

struct VideoOptions {
  int timesteps = 200;
  int size = 16;
  int train_cameras = 8;
  double scene_scale = 1;
  bool nan_frame = false;  // one training frame full of NaN
  bool black = false;      // every frame black
};

// Train cameras on a ring (distance 3), one test camera between two of them.
StatusOr<std::unique_ptr<Dataset>> MakeVideo(const VideoOptions& o, const DatasetOptions& dataset_options = {}) {
  std::vector<InMemoryFrame> frames;
  const double d = 3.0 * o.scene_scale;
  for (int t = 0; t < o.timesteps; ++t) {
    const double time = o.timesteps > 1 ? t / double(o.timesteps - 1) : 0.0;
    const Gaussians scene = MovingScene(time, o.scene_scale);
    for (int cam = 0; cam <= o.train_cameras; ++cam) {
      const bool test = cam == o.train_cameras;
      const double angle = 2 * std::numbers::pi * (cam + (test ? 0.5 : 0.0)) / o.train_cameras;
      InMemoryFrame f;
      f.view.camera = LookAt({d * std::cos(angle), 0.4 * d, d * std::sin(angle)}, {0, 0, 0}, o.size, o.size,
                             o.size * 1.2);
      f.view.camera.time = time;
      f.view.camera_id = cam;
      f.view.timestep = t;
      f.test = test;
      RenderSettings settings;
      settings.active_sh_degree = 0;
      ATEX_ASSIGN_OR_RETURN(RenderOutput out, RenderForward<float>(f.view.camera, scene, nullptr, settings));
      f.image = RenderedImage(out);
      for (float& v : f.image.pixels) v = o.black ? 0.0f : std::clamp(v, 0.0f, 1.0f);
      if (o.nan_frame && t == 1 && cam == 0) std::fill(f.image.pixels.begin(), f.image.pixels.end(), NAN);
      frames.push_back(std::move(f));
    }
  }
  return MakeInMemoryDataset("synthetic-video", std::move(frames), dataset_options);
}

train::TrainConfig TinyConfig() {
  train::TrainConfig c = train::DefaultConfig("generic");
  c.stage1.coarse_iterations = 150;
  c.stage1.fine_iterations = 150;
  c.stage1.batch_size = 2;
  c.stage1.sh_degree = 1;
  c.stage1.sh_increase_interval = 20;
  c.stage1.init_method = "volume";
  c.stage1.init_points = 300;
  c.stage1.densify.from_step = 10;
  c.stage1.densify.interval = 10;
  c.stage1.densify.until_step = 50;
  c.stage1.deformation.grid.channels = 4;
  c.stage1.deformation.grid.base_resolution = {8, 8, 8, 16};
  c.stage1.deformation.mlp_width = 16;
  c.stage2.iterations = 20;
  c.stage2.batch_size = 2;
  c.stage2.growth_steps = {8, 16};
  c.eval_every = 0;
  c.checkpoint_every = 0;
  return c;
}

// A backend that hands the CPU backend a NaN target image on chosen steps (a corrupt frame
// arriving from the data pipeline): the CPU backend itself sees the NaN and reports it.
class NanInjectingBackend final : public train::Backend {
 public:
  NanInjectingBackend(int first_bad, int last_bad) : inner_(train::MakeCpuBackend()), first_(first_bad), last_(last_bad) {}
  std::string name() const override { return "cpu+nan"; }
  Status Load(const train::ModelState& s) override { return inner_->Load(s); }
  Status Save(train::ModelState* s) override { return inner_->Save(s); }
  Status ReadGaussians(Gaussians* g) override { return inner_->ReadGaussians(g); }
  StatusOr<train::StepResult> Step(const train::StepRequest& r, std::span<const train::TrainView> v) override {
    const int step = steps_++;
    if (step < first_ || step > last_) return inner_->Step(r, v);
    ++injected_;
    std::vector<train::TrainView> views(v.begin(), v.end());
    poisoned_ = *views[0].target;
    poisoned_.pixels[poisoned_.pixels.size() / 2] = NAN;
    views[0].target = &poisoned_;
    return inner_->Step(r, views);
  }
  Status ReadGradients(train::ModelState* g) override { return inner_->ReadGradients(g); }
  Status ReadStats(int k, train::TrainingStats* s) override { return inner_->ReadStats(k, s); }
  Status ResetStats(int k) override { return inner_->ResetStats(k); }
  Status ApplyEdit(const train::GaussianEdit& e) override { return inner_->ApplyEdit(e); }
  Status AttachTextures(const TexturePool& l) override { return inner_->AttachTextures(l); }
  Status ResizeTextures(const train::TextureResize& r) override { return inner_->ResizeTextures(r); }
  StatusOr<Image> Render(const Camera& c, const train::RenderRequest& r) override { return inner_->Render(c, r); }
  int injected_ = 0;

 private:
  std::unique_ptr<train::Backend> inner_;
  int first_, last_;
  int steps_ = 0;
  Image poisoned_;
};

// Test PSNR of the untrained model (zero steps) on `data`: a run must clear it by 3 dB.
double UntrainedFloor(const Dataset& data, const train::TrainConfig& config) {
  train::TrainerOptions options;
  options.config = config;
  options.config.stage1.coarse_iterations = options.config.stage1.fine_iterations = 0;
  options.stages = train::kStage1;
  auto backend = train::MakeCpuBackend();
  auto result = train::Train(data, *backend, options);
  EXPECT_TRUE(result.ok()) << result.status().ToString();
  return result.ok() ? result->test.mean.psnr + 3.0 : 0.0;
}

// Classifies a finished training run: NaN anywhere in the asset or the metrics fails.
void ClassifyTraining(Case& c, const StatusOr<train::TrainSummary>& result, double psnr_floor,
                      const std::string& extra = "") {
  if (!result.ok()) return c.Error(result.status());
  const train::TrainSummary& s = *result;
  const Status valid = ValidateAsset(s.asset);  // every float finite, sizes consistent
  if (!valid.ok()) return c.Set("nan", StrCat("trained asset is invalid: ", valid.ToString()));
  // +inf is CompareImages' documented PSNR of a view identical to its target; NaN is a bug.
  if (!s.test.views.empty() && std::isnan(s.test.mean.psnr)) return c.Set("nan", "test PSNR is NaN");
  const std::string what =
      StrCat(s.asset.gaussians.size(), " Gaussians, ", s.test.views.size(), " test views, PSNR ",
             Fmt("%.2f", s.test.mean.psnr), " dB (floor ", Fmt("%.2f", psnr_floor), "), ", s.events.size(), " events",
             extra.empty() ? "" : "; ", extra);
  if (s.asset.gaussians.size() == 0) return c.Set("collapse", what);
  if (!s.test.views.empty() && s.test.mean.psnr < psnr_floor) return c.Set("low-psnr", what);
  c.Ok(what);
}

TEST(StressTrain, LongSequenceAtTinyResolution) {
  Case c("train/200-timesteps-16x16 (both stages)", "long sequence");
  auto data = MakeVideo({});
  ASSERT_TRUE(data.ok()) << data.status().ToString();
  ASSERT_EQ((*data)->timestep_count(), 200);
  train::TrainerOptions options;
  options.config = TinyConfig();
  auto backend = train::MakeCpuBackend();
  auto result = train::Train(**data, *backend, options);
  std::string extra;
  if (result.ok()) {
    EXPECT_EQ(result->test.views.size(), 200u);
    extra = StrCat("textures ", result->asset.textures ? result->asset.textures->texel_count() : 0, " texels");
  }
  ClassifyTraining(c, result, UntrainedFloor(**data, options.config), extra);
}

TEST(StressTrain, FastMotionAndSparseViews) {
  for (int stride : {2, 8}) {
    Case c(StrCat("train/fast-motion-stride-", stride), "fast motion");
    DatasetOptions options;
    options.timestep_stride = stride;
    auto data = MakeVideo({.timesteps = 64}, options);
    ASSERT_TRUE(data.ok()) << data.status().ToString();
    EXPECT_EQ((*data)->timestep_count(), 64 / stride);
    train::TrainerOptions topts;
    topts.config = TinyConfig();
    topts.stages = train::kStage1;
    auto backend = train::MakeCpuBackend();
    ClassifyTraining(c, train::Train(**data, *backend, topts), UntrainedFloor(**data, topts.config));
  }
  for (int cameras : {12, 6, 3, 1}) {
    Case c(StrCat("train/sparse-views-", cameras, "-of-12-cameras"), "sparse views");
    DatasetOptions options;
    options.train_cameras = cameras;
    auto data = MakeVideo({.timesteps = 16, .train_cameras = 12}, options);
    ASSERT_TRUE(data.ok()) << data.status().ToString();
    train::TrainerOptions topts;
    topts.config = TinyConfig();
    topts.config.stage1.init_method = "auto";  // view volume needs 3 cameras: see what one camera gives
    topts.stages = train::kStage1;
    auto backend = train::MakeCpuBackend();
    ClassifyTraining(c, train::Train(**data, *backend, topts), UntrainedFloor(**data, topts.config));
  }
}

TEST(StressTrain, NanInjectionRollsBack) {
  auto data = MakeVideo({.timesteps = 8});
  ASSERT_TRUE(data.ok()) << data.status().ToString();
  const double floor = UntrainedFloor(**data, TinyConfig());
  {
    Case c("train/nan-injected-once", "numerical stress");
    train::TrainerOptions options;
    options.config = TinyConfig();
    options.stages = train::kStage1;
    NanInjectingBackend backend(12, 12);
    auto result = train::Train(**data, backend, options);
    bool rolled_back = false;
    if (result.ok()) {
      for (const auto& e : result->events) rolled_back |= e.find("rolled back") != std::string::npos;
    }
    EXPECT_TRUE(!result.ok() || rolled_back) << "no rollback event logged";
    EXPECT_EQ(backend.injected_, 1);
    ClassifyTraining(c, result, floor, rolled_back ? "rollback event logged" : "NO rollback event");
  }
  {
    Case c("train/nan-on-every-step-from-12", "numerical stress");
    train::TrainerOptions options;
    options.config = TinyConfig();
    options.stages = train::kStage1;
    NanInjectingBackend backend(12, 1 << 30);
    auto result = train::Train(**data, backend, options);
    // Unrecoverable: the loop must give up with kNumericalError after its rollbacks.
    EXPECT_FALSE(result.ok());
    if (!result.ok()) {
      EXPECT_EQ(result.status().code(), StatusCode::kNumericalError) << result.status().ToString();
    }
    ClassifyTraining(c, result, floor);
  }
  {
    Case c("train/nan-frame-in-dataset", "numerical stress");
    auto bad = MakeVideo({.timesteps = 8, .nan_frame = true});
    ASSERT_TRUE(bad.ok()) << bad.status().ToString();
    train::TrainerOptions options;
    options.config = TinyConfig();
    options.stages = train::kStage1;
    auto backend = train::MakeCpuBackend();
    auto result = train::Train(**bad, *backend, options);
    int rollbacks = 0;
    if (result.ok()) {
      for (const auto& e : result->events) rollbacks += e.find("rolled back") != std::string::npos;
    }
    ClassifyTraining(c, result, floor, StrCat(rollbacks, " rollbacks"));
  }
}

TEST(StressTrain, TightBudgetsAndCollapse) {
  auto data = MakeVideo({.timesteps = 8});
  ASSERT_TRUE(data.ok()) << data.status().ToString();
  train::TrainerOptions s1;
  s1.config = TinyConfig();
  s1.stages = train::kStage1;
  auto b1 = train::MakeCpuBackend();
  auto stage1 = train::Train(**data, *b1, s1);
  ASSERT_TRUE(stage1.ok()) << stage1.status().ToString();
  const double floor = UntrainedFloor(**data, TinyConfig());
  for (double fraction : {0.01, 0.0}) {
    Case c(Fmt("train/texel-budget-%g-of-uniform", fraction), "tight budget");
    train::TrainerOptions s2;
    s2.config = TinyConfig();
    s2.config.stage2.texel_budget_fraction = fraction;
    s2.stages = train::kStage2;
    auto b2 = train::MakeCpuBackend();
    auto result = train::Train(**data, *b2, s2, &stage1->asset);
    std::string extra;
    if (result.ok() && result->asset.textures) {
      const uint64_t texels = result->asset.textures->texel_count();
      extra = StrCat(texels, " texels for ", result->asset.gaussians.size(), " Gaussians (1x1 each: no growth)");
      EXPECT_EQ(texels, result->asset.gaussians.size());
    }
    // Textures that cannot grow must not cost the stage-1 quality (1 dB slack).
    ClassifyTraining(c, result, stage1->test.mean.psnr - 1.0, extra);
  }
  {
    Case c("train/max-gaussians-1", "tight budget");
    train::TrainerOptions options = s1;
    options.config.stage1.densify.max_gaussians = 1;
    auto backend = train::MakeCpuBackend();
    ClassifyTraining(c, train::Train(**data, *backend, options), floor);
  }
  {
    Case c("train/prune-everything (min_opacity 0.9999)", "degenerate content");
    train::TrainerOptions options = s1;
    options.config.stage1.densify.min_opacity = 0.9999;
    options.config.stage2.iterations = 10;
    options.config.stage2.growth_steps = {5};
    options.stages = train::kBothStages;
    auto backend = train::MakeCpuBackend();
    ClassifyTraining(c, train::Train(**data, *backend, options), floor);
  }
  {
    Case c("train/all-black-frames", "degenerate content");
    auto black = MakeVideo({.timesteps = 8, .black = true});
    ASSERT_TRUE(black.ok());
    train::TrainerOptions options = s1;
    auto backend = train::MakeCpuBackend();
    ClassifyTraining(c, train::Train(**black, *backend, options), UntrainedFloor(**black, options.config));
  }
}

// Stage 2 with checkpoints, stopped between the two growth steps and resumed.
TEST(StressTrain, StageTwoCheckpointAndResume) {
  auto data = MakeVideo({.timesteps = 8});
  ASSERT_TRUE(data.ok()) << data.status().ToString();
  train::TrainerOptions s1;
  s1.config = TinyConfig();
  s1.stages = train::kStage1;
  auto b1 = train::MakeCpuBackend();
  auto stage1 = train::Train(**data, *b1, s1);
  ASSERT_TRUE(stage1.ok()) << stage1.status().ToString();

  Case c("train/stage-2 checkpoint, stop at step 12, resume", "checkpoints");
  testing::TempDir dir;
  train::TrainerOptions s2;
  s2.config = TinyConfig();
  s2.config.checkpoint_every = 4;
  s2.stages = train::kStage2;
  auto straight_backend = train::MakeCpuBackend();
  auto straight = train::Train(**data, *straight_backend, s2, &stage1->asset);

  train::TrainerOptions part = s2;
  part.checkpoint_dir = (dir / "ckpt").string();
  part.log_every = 4;
  part.progress = [](const train::TrainProgress& p) { return !(p.phase == "textures" && p.step == 12); };
  auto b2 = train::MakeCpuBackend();
  auto stopped = train::Train(**data, *b2, part, &stage1->asset);
  if (stopped.status().code() != StatusCode::kCancelled) {
    return stopped.ok() ? c.Set("error", "the progress callback did not stop training")
                        : c.Error(stopped.status());
  }
  train::TrainerOptions resume = s2;
  resume.resume_dir = part.checkpoint_dir;
  auto b3 = train::MakeCpuBackend();
  auto resumed = train::Train(**data, *b3, resume, &stage1->asset);
  if (!straight.ok()) return c.Error(straight.status());
  if (!resumed.ok()) return c.Error(resumed.status());
  const bool same = resumed->asset.textures && straight->asset.textures &&
                    resumed->asset.textures->heights == straight->asset.textures->heights &&
                    resumed->asset.textures->widths == straight->asset.textures->widths &&
                    resumed->asset.textures->texels == straight->asset.textures->texels;
  ClassifyTraining(c, resumed, straight->test.mean.psnr - 1.0,
                   same ? "identical to the uninterrupted run"
                        : StrCat("differs from the uninterrupted run: texels ",
                                 resumed->asset.textures ? resumed->asset.textures->texel_count() : 0, " vs ",
                                 straight->asset.textures ? straight->asset.textures->texel_count() : 0,
                                 " (growth statistics since the last growth are not in the checkpoint)"));
}

TEST(StressTrain, HugeSceneScale) {
  Case c("train/scene-scale-x1e4", "numerical stress");
  auto data = MakeVideo({.timesteps = 8, .scene_scale = 1e4});
  ASSERT_TRUE(data.ok()) << data.status().ToString();
  train::TrainerOptions options;
  options.config = TinyConfig();
  options.stages = train::kStage1;
  auto backend = train::MakeCpuBackend();
  ClassifyTraining(c, train::Train(**data, *backend, options), UntrainedFloor(**data, options.config));
}

}  // namespace
}  // namespace atex
