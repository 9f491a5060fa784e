// The fitter on a real trained asset: the committed lego sample (samples/, trained on
// the GPU from the real tiny D-NeRF lego) fitted to shrinking budgets, with the test
// PSNR measured against the real images by the CPU reference renderer.
#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include <gtest/gtest.h>

#include "atex/container.h"
#include "atex/dataset.h"
#include "atex/file_io.h"
#include "atex/fit.h"
#include "atex/train/trainer.h"
#include "core/test_support.h"

namespace atex::fit {
namespace {

// The committed lego sample of samples/ (ATEX_SOURCE_DIR is set by CTest).
std::filesystem::path SamplePath() {
  const char* source = std::getenv("ATEX_SOURCE_DIR");
  return std::filesystem::path(source ? source : ".") / "samples" / "lego_adaptive_2MiB.atex";
}

TEST(FitLego, TestPsnrNeverRisesAsTheBudgetShrinks) {
  ATEX_REQUIRE_DATA_FILE(data, "dnerf_lego_tiny/tiny_dnerf_data.npz");
  const std::filesystem::path sample = SamplePath();
  ASSERT_TRUE(std::filesystem::exists(sample)) << sample;
  auto bytes = ReadFileBytes(sample.string());
  ASSERT_TRUE(bytes.ok());
  auto asset = DecodeAsset(bytes->data(), bytes->size());
  ASSERT_TRUE(asset.ok()) << asset.status().ToString();
  auto dataset = OpenDataset(data.string());
  ASSERT_TRUE(dataset.ok()) << dataset.status().ToString();
  auto write = EncodingsOfFile(bytes->data(), bytes->size(), WriteOptions{});
  ASSERT_TRUE(write.ok());

  auto backend = train::MakeCpuBackend();
  std::vector<Probe> probes;
  const auto& train_views = (*dataset)->train_views();
  for (int k = 0; k < 4; ++k) probes.push_back({train_views[k * train_views.size() / 4].camera});
  ProbeRenderer renderer(backend.get(), probes);
  ASSERT_TRUE(EnsureImportance(&*asset, probes).ok());
  const uint64_t full = bytes->size();
  PlanOptions o;
  o.write = *write;
  o.floor_bytes = full / 5;
  auto plan = BuildPlan(*asset, &renderer, o);
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();

  std::vector<View> test_views;
  const auto& all = (*dataset)->test_views();
  for (size_t k = 0; k < all.size(); k += 2) test_views.push_back(all[k]);
  double previous = 1e9;
  for (int percent : {100, 80, 60, 40, 20}) {
    const uint64_t budget = full * percent / 100;
    auto fitted = ApplyPlan(*asset, *plan, *write, budget);
    ASSERT_TRUE(fitted.ok()) << fitted.status().ToString();
    ASSERT_LE(fitted->bytes.size(), budget);
    ASSERT_TRUE(backend->Load(train::StateFromAsset(fitted->asset)).ok());
    auto eval = train::Evaluate(**dataset, *backend, test_views, train::RenderRequestFor(fitted->asset));
    ASSERT_TRUE(eval.ok()) << eval.status().ToString();
    std::printf("[fit lego] budget %3d%% = %8llu bytes: file %8zu bytes, %zu Gaussians, test PSNR %.3f dB\n", percent,
                static_cast<unsigned long long>(budget), fitted->bytes.size(), fitted->asset.gaussians.size(),
                eval->mean.psnr);
    // Non-increasing, with 0.05 dB of slack: removing a floater can help a held-out view a little.
    EXPECT_LE(eval->mean.psnr, previous + 0.05) << "budget " << percent << "%";
    previous = std::min(previous, eval->mean.psnr);
  }
}

// `atex fit --finetune` retrains a fitted asset with stage 2 alone: the trainer must keep the
// asset's own texture pool (sizes and texels as fitted), its Gaussians and its SH degree.
TEST(FitLego, FinetuneKeepsTheFittedTexturePool) {
  ATEX_REQUIRE_DATA_FILE(data, "dnerf_lego_tiny/tiny_dnerf_data.npz");
  const std::filesystem::path sample = SamplePath();
  auto asset = ReadAssetFile(sample.string());
  ASSERT_TRUE(asset.ok()) << asset.status().ToString();
  // Give the pool different sizes, as a fit of a grown asset would have.
  for (size_t i = 0; i < asset->textures->size(); i += 3) asset->textures->widths[i] = 2;
  asset->textures->RebuildOffsets();
  asset->textures->texels.assign(asset->textures->texel_count() * kTexelChannels, 0.01f);
  ASSERT_TRUE(ValidateAsset(*asset).ok());
  auto dataset = OpenDataset(data.string());
  ASSERT_TRUE(dataset.ok());

  train::TrainerOptions options;
  options.config = train::DefaultConfig("dnerf");
  options.config.stage1.sh_degree = asset->gaussians.sh_degree;
  options.config.stage2.iterations = 2;
  options.config.stage2.batch_size = 1;
  options.config.stage2.growth_steps.clear();
  options.config.eval_every = 0;
  options.config.checkpoint_every = 0;
  options.stages = train::kStage2;
  auto backend = train::MakeCpuBackend();
  auto tuned = train::Train(**dataset, *backend, options, &*asset);
  ASSERT_TRUE(tuned.ok()) << tuned.status().ToString();
  const Asset& out = tuned->asset;
  ASSERT_TRUE(out.textures);
  EXPECT_EQ(out.gaussians.size(), asset->gaussians.size());
  EXPECT_EQ(out.gaussians.sh_degree, asset->gaussians.sh_degree);
  EXPECT_EQ(out.textures->widths, asset->textures->widths);
  EXPECT_EQ(out.textures->heights, asset->textures->heights);
  EXPECT_NE(out.textures->texels, asset->textures->texels) << "the texels were trained";
  bool kept_event = false;
  for (const std::string& e : tuned->events) kept_event |= e.find("kept the initial asset") != std::string::npos;
  EXPECT_TRUE(kept_event);
  EXPECT_TRUE(ValidateAsset(out).ok()) << ValidateAsset(out).ToString();
}

}  // namespace
}  // namespace atex::fit
