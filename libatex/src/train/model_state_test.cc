// Model state <-> asset conversions (trainer.h): the render-only state carries the parameters
// and no moments, and a backend loading it starts the moments at zero.
#include <gtest/gtest.h>

#include "atex/train/backend.h"
#include "atex/train/trainer.h"
#include "container/synthetic_asset.h"

namespace atex::train {
namespace {

// A synthetic asset with textures and a deformation field, without training statistics.
Asset SmallAsset(size_t gaussians) {
  container::SyntheticAssetOptions o;
  o.gaussians = gaussians;
  o.stats = false;
  return container::MakeSyntheticAsset(o);
}

TEST(ModelState, ARenderStateCarriesTheParametersWithoutMoments) {
  const Asset asset = SmallAsset(50);
  const ModelState bare = RenderStateFromAsset(asset);
  EXPECT_EQ(bare.gaussians.positions, asset.gaussians.positions);
  EXPECT_EQ(bare.gaussians.sh, asset.gaussians.sh);
  ASSERT_TRUE(bare.textures && asset.textures);
  EXPECT_EQ(bare.textures->texels, asset.textures->texels);
  ASSERT_TRUE(bare.deformation.has_value());
  EXPECT_EQ(bare.m_gaussians.size(), 0u);
  EXPECT_TRUE(bare.m_texels.empty() && bare.v_texels.empty());
  EXPECT_FALSE(bare.m_deformation.has_value() || bare.v_deformation.has_value());

  // Loaded after a state with moments (the fitter reuses one backend for every candidate),
  // the moments start at zero, shaped like the parameters.
  ModelState noisy = StateFromAsset(asset);
  for (float& x : noisy.m_gaussians.positions) x = 0.5f;
  for (float& x : noisy.v_texels) x = 0.25f;
  auto backend = MakeCpuBackend();
  ASSERT_TRUE(backend->Load(noisy).ok());
  ASSERT_TRUE(backend->Load(bare).ok());
  ModelState saved;
  ASSERT_TRUE(backend->Save(&saved).ok());
  EXPECT_EQ(saved.gaussians.positions, asset.gaussians.positions);
  EXPECT_EQ(saved.m_gaussians.positions, std::vector<float>(asset.gaussians.positions.size(), 0.0f));
  EXPECT_EQ(saved.v_texels, std::vector<float>(asset.textures->texels.size(), 0.0f));
}

// Each group's moments are filled independently: texel and deformation moments missing beside
// present Gaussian ones are zeroed (the CPU backend once checked the Gaussians' alone and left
// the others empty), and present ones are kept.
TEST(ModelState, MissingMomentsAreFilledPerGroup) {
  const Asset asset = SmallAsset(30);
  ModelState state = StateFromAsset(asset);
  for (float& x : state.m_gaussians.positions) x = 0.5f;
  state.m_texels.clear();
  state.v_deformation.reset();
  FillMissingMoments(&state);
  EXPECT_EQ(state.m_gaussians.positions, std::vector<float>(asset.gaussians.positions.size(), 0.5f));
  EXPECT_EQ(state.m_texels, std::vector<float>(asset.textures->texels.size(), 0.0f));
  ASSERT_TRUE(state.m_deformation && state.v_deformation);
  EXPECT_EQ(state.v_deformation->planes.size(), asset.deformation->planes.size());

  auto backend = MakeCpuBackend();
  state.m_texels.clear();
  ASSERT_TRUE(backend->Load(state).ok());
  ModelState saved;
  ASSERT_TRUE(backend->Save(&saved).ok());
  EXPECT_EQ(saved.m_gaussians.positions, state.m_gaussians.positions);  // kept, not reset
  EXPECT_EQ(saved.m_texels.size(), asset.textures->texels.size());
}

}  // namespace
}  // namespace atex::train
