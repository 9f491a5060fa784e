// Backend::LoadKeyed on the CUDA backend: an array whose key equals the one the backend holds
// from the last keyed load is kept, not copied again, and a load, a step or an edit in between
// makes the backend copy everything again. The result of a keyed load with true keys is
// Load's. Skips without a GPU.
#include <random>

#include <gtest/gtest.h>

#include "atex/cuda/cuda_backend.h"
#include "atex/deform.h"
#include "atex/train/backend.h"
#include "gpu_test_support.h"
#include "render/render_test_util.h"

namespace atex::cuda {
namespace {

struct Scene {
  Camera camera;
  train::ModelState state;  // textured, deformed, no moments
};

Scene MakeScene(uint32_t seed) {
  std::mt19937 rng(seed);
  Scene s;
  s.camera = render_testing::RandomCamera(96, 72, rng);
  s.camera.time = 0.5;
  render_testing::SceneOptions options;
  options.count = 300;
  options.sh_degree = 1;
  options.extras = false;
  options.textures = render_testing::TextureKind::kAdaptiveMixed;
  s.state.gaussians = render_testing::RandomGaussians<float>(s.camera, options, rng);
  s.state.textures = render_testing::RandomTextures<float>(s.state.gaussians, options.textures, 0.5, rng);
  DeformationConfig dc;
  dc.grid.channels = 4;
  dc.grid.base_resolution = {8, 8, 8, 4};
  dc.grid.multires = {1};
  dc.mlp_width = 16;
  dc.sh_coeffs = s.state.gaussians.sh_coeffs();
  dc.aabb_lo = {-3, -3, -3};
  dc.aabb_hi = {3, 3, 3};
  auto field = InitDeformationField(dc, seed);
  EXPECT_TRUE(field.ok());
  s.state.deformation = *field;
  return s;
}

// Distinct keys for each array of a state; `salt` makes another state's.
train::StateKeys Keys(uint64_t salt) {
  train::StateKeys k;
  uint64_t next = 1;
  for (auto* key :
       {&k.positions, &k.rotations, &k.log_scales, &k.opacity, &k.sh, &k.time_windows, &k.texels, &k.deformation}) {
    *key = {salt, next++};
  }
  return k;
}

class KeyedLoad : public ::testing::Test {
 protected:
  void SetUp() override {
    ATEX_REQUIRE_CUDA_DEVICE();
    scene_ = MakeScene(41);
    CudaBackendOptions options;
    options.tf32 = false;
    auto backend = MakeCudaBackend(options);
    ASSERT_TRUE(backend.ok()) << backend.status().ToString();
    backend_ = std::move(*backend);
    request_.active_sh_degree = 1;
  }
  // The render of `state` by a backend that loads it plainly.
  std::vector<float> Plain(const train::ModelState& state) {
    CudaBackendOptions options;
    options.tf32 = false;
    auto other = MakeCudaBackend(options);
    EXPECT_TRUE(other.ok());
    EXPECT_TRUE((*other)->Load(state).ok());
    return Pixels(**other);
  }
  std::vector<float> Pixels(train::Backend& backend) {
    auto image = backend.Render(scene_.camera, request_);
    EXPECT_TRUE(image.ok()) << image.status().ToString();
    return image.ok() ? image->pixels : std::vector<float>{};
  }

  Scene scene_;
  std::unique_ptr<train::Backend> backend_;
  train::RenderRequest request_;
};

TEST_F(KeyedLoad, TrueKeysGiveLoadsResult) {
  train::ModelState other = scene_.state;
  for (float& x : other.textures->texels) x = -x;
  for (float& x : other.gaussians.opacity_logits) x += 0.5f;
  train::StateKeys other_keys = Keys(1);
  other_keys.texels = Keys(2).texels;
  other_keys.opacity = Keys(2).opacity;
  ATEX_ASSERT_OK(backend_->LoadKeyed(scene_.state, Keys(1)));
  ATEX_ASSERT_OK(backend_->LoadKeyed(other, other_keys));
  EXPECT_EQ(Pixels(*backend_), Plain(other));
  ATEX_ASSERT_OK(backend_->LoadKeyed(scene_.state, Keys(1)));  // texels and opacities back
  EXPECT_EQ(Pixels(*backend_), Plain(scene_.state));
}

TEST_F(KeyedLoad, AnArrayWithTheHeldKeyIsNotCopiedAgain) {
  // A key that lies (other SH under the held SH key) shows that the array was kept.
  train::ModelState other_sh = scene_.state;
  for (float& x : other_sh.gaussians.sh) x += 0.3f;
  ATEX_ASSERT_OK(backend_->LoadKeyed(scene_.state, Keys(1)));
  ATEX_ASSERT_OK(backend_->LoadKeyed(other_sh, Keys(1)));
  const std::vector<float> kept = Pixels(*backend_);
  EXPECT_EQ(kept, Plain(scene_.state));
  EXPECT_NE(kept, Plain(other_sh));
  // Zero keys are unknown: copied.
  ATEX_ASSERT_OK(backend_->LoadKeyed(scene_.state, Keys(1)));
  ATEX_ASSERT_OK(backend_->LoadKeyed(other_sh, train::StateKeys{}));
  EXPECT_EQ(Pixels(*backend_), Plain(other_sh));
}

TEST_F(KeyedLoad, ALoadOrAnEditInBetweenForgetsTheKeys) {
  train::ModelState other_sh = scene_.state;
  for (float& x : other_sh.gaussians.sh) x += 0.3f;
  // A plain load in between: the held arrays are no longer the keyed ones.
  ATEX_ASSERT_OK(backend_->LoadKeyed(scene_.state, Keys(1)));
  ATEX_ASSERT_OK(backend_->Load(other_sh));
  ATEX_ASSERT_OK(backend_->LoadKeyed(scene_.state, Keys(1)));
  EXPECT_EQ(Pixels(*backend_), Plain(scene_.state));
  // An edit in between (every Gaussian kept, opacities capped): copied again.
  ATEX_ASSERT_OK(backend_->LoadKeyed(other_sh, Keys(1)));
  train::GaussianEdit edit;
  for (uint32_t i = 0; i < other_sh.gaussians.size(); ++i) edit.source.push_back(i);
  edit.cap_opacity_logit = -1.0f;
  ATEX_ASSERT_OK(backend_->ApplyEdit(edit));
  ATEX_ASSERT_OK(backend_->LoadKeyed(other_sh, Keys(1)));
  EXPECT_EQ(Pixels(*backend_), Plain(other_sh));
}

}  // namespace
}  // namespace atex::cuda
