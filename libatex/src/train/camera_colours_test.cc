// The trainer-facing pieces of issue 20 on a synthetic in-memory rig: per-camera colour fits
// from a model (CameraColours::Fit) and the dynamic-region PSNR of Evaluate.
#include "atex/train/camera_colours.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "atex/train/trainer.h"
#include "render/render_test_util.h"

namespace atex::train {
namespace {

struct Rig {
  std::unique_ptr<Dataset> dataset;
  std::unique_ptr<Backend> backend;
  RenderRequest request;
};

// Three fixed cameras with two frames each and one camera seen once, all looking at the same
// random static scene; each frame's image is `frame_image(camera, timestep, render)`.
template <typename FrameImage>
Rig MakeRig(FrameImage frame_image) {
  std::mt19937 rng(7);
  Rig rig;
  const Camera first = render_testing::RandomCamera(40, 30, rng);
  render_testing::SceneOptions options;
  options.count = 150;
  options.sh_degree = 0;
  options.extras = false;
  ModelState state;
  state.gaussians = render_testing::RandomGaussians<float>(first, options, rng);
  ResetMoments(&state);
  rig.backend = MakeCpuBackend();
  EXPECT_TRUE(rig.backend->Load(state).ok());
  rig.request.active_sh_degree = 0;
  rig.request.apply_deformation = false;
  rig.request.use_textures = false;
  std::vector<InMemoryFrame> frames;
  for (int camera = 0; camera < 4; ++camera) {
    Camera pose = first;
    pose.world_to_camera[3] += 0.03 * camera;  // sideways, the scene stays in view
    for (int t = 0; t < (camera == 3 ? 1 : 2); ++t) {
      InMemoryFrame f;
      f.view.camera = pose;
      f.view.camera.time = t;
      f.view.camera_id = camera;
      f.view.timestep = t;
      auto render = rig.backend->Render(f.view.camera, rig.request);
      EXPECT_TRUE(render.ok());
      f.image = frame_image(camera, t, *render);
      f.test = camera == 2;  // camera 2 is held out: its frames are test views
      frames.push_back(std::move(f));
    }
  }
  auto dataset = MakeInMemoryDataset("rig", std::move(frames), {});
  EXPECT_TRUE(dataset.ok()) << dataset.status().message();
  rig.dataset = std::move(*dataset);
  return rig;
}

TEST(CameraColours, FitRecoversEachTrainingCamerasCast) {
  // Casts with mean gain 1 and mean offset 0 over the training cameras 0 and 1 (3 is seen once
  // and gets none), so the normalised fit must return them as they are.
  const std::vector<ColourAffine> casts = {{{1.1f, 0.95f, 1.0f}, {-0.02f, 0.01f, 0.03f}},
                                           {{0.9f, 1.05f, 1.0f}, {0.02f, -0.01f, -0.03f}},
                                           {}, {{1.3f, 1.3f, 1.3f}, {0, 0, 0}}};
  Rig rig = MakeRig([&](int camera, int, Image render) {
    casts[camera].Apply(render.pixels.data(), size_t(render.width) * render.height);
    return render;
  });
  CameraColours colours;
  CameraColourConfig config;
  config.keep = 1.0;
  ASSERT_TRUE(colours.Fit(*rig.dataset, *rig.backend, rig.request, config).ok());
  EXPECT_EQ(colours.size(), 2u) << colours.Summary();
  for (int camera : {0, 1}) {
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(colours.For(camera).gain[c], casts[camera].gain[c], 2e-3) << camera << " " << c;
      EXPECT_NEAR(colours.For(camera).offset[c], casts[camera].offset[c], 2e-3) << camera << " " << c;
    }
  }
  EXPECT_TRUE(colours.For(3).IsIdentity()) << "a camera seen once gets no correction";
  config.views_per_camera = 0;
  EXPECT_EQ(colours.Fit(*rig.dataset, *rig.backend, rig.request, config).code(), StatusCode::kInvalidArgument);
}

TEST(Evaluate, DynamicRegionPsnrWhereACameraSeesChange) {
  // Test camera 2's second frame has a bright square the model does not render: that square is
  // its dynamic region, where the render is off by 0.5 in every channel.
  Rig rig = MakeRig([](int camera, int t, Image render) {
    if (camera == 2 && t == 1) {
      for (int y = 5; y < 15; ++y)
        for (int x = 10; x < 20; ++x)
          for (int c = 0; c < 3; ++c) render.at(x, y, c) = std::min(1.0f, render.at(x, y, c) + 0.5f);
    }
    return render;
  });
  auto eval = Evaluate(*rig.dataset, *rig.backend, rig.dataset->test_views(), rig.request);
  ASSERT_TRUE(eval.ok()) << eval.status().message();
  ASSERT_EQ(eval->views.size(), 2u);
  for (const ViewMetrics& v : eval->views) {
    ASSERT_FALSE(std::isnan(v.dynamic_psnr));
    EXPECT_GT(v.dynamic_fraction, 0.0);
    EXPECT_LE(v.dynamic_fraction, 100.0 / 1200.0);
    if (v.timestep == 0) {
      EXPECT_GT(v.dynamic_psnr, 60.0);  // frame 0 is the render: +infinity or nearly
    }
    if (v.timestep == 1) {
      EXPECT_LT(v.dynamic_psnr, 10.0);  // ≈ 0.5 off (less where the +0.5 clipped at 1)
    }
  }
  EXPECT_EQ(eval->dynamic_views, 2u);
  // Off: no region, no dynamic PSNR.
  auto plain = Evaluate(*rig.dataset, *rig.backend, rig.dataset->test_views(), rig.request, {.dynamic_region = false});
  ASSERT_TRUE(plain.ok());
  EXPECT_TRUE(std::isnan(plain->views[0].dynamic_psnr));
  EXPECT_EQ(plain->dynamic_views, 0u);
  EXPECT_TRUE(EvalToJson(*plain)["mean"]["dynamic_psnr"].is_null());
}

}  // namespace
}  // namespace atex::train
