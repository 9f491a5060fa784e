// The fitter's CPU probe renderer against the CPU backend's renders (the reference):
// equal within kTolerance on the first render, after moves that keep positions (prune,
// texels) and after moves that change them (requantised positions, a coarser field).
#include <cmath>
#include <numeric>

#include <gtest/gtest.h>

#include "atex/container.h"
#include "atex/fit.h"
#include "atex/train/backend.h"
#include "atex/train/trainer.h"
#include "container/synthetic_asset.h"
#include "fit/cpu_probes.h"
#include "fit/levers.h"
#include "fit/probe_test_util.h"
#include "fit/texture_shrink.h"

namespace atex::fit {
namespace {

// Largest difference of a pixel channel allowed between the two renderers. The only
// difference is the MLP's summation order for residuals computed in another block of
// Gaussians (last bits of float, ~1e-7 relative); colours are in [0, 1].
constexpr float kTolerance = 2e-5f;

Asset DynamicAsset(uint64_t seed) {
  container::SyntheticAssetOptions o;
  o.seed = seed;
  o.gaussians = 600;
  o.sh_degree = 1;
  o.textures = container::SyntheticTextures::kMixed;
  o.sh_head = true;
  return container::MakeSyntheticAsset(o);
}

std::vector<Image> Reference(const Asset& asset, const std::vector<Probe>& probes) {
  auto backend = train::MakeCpuBackend();
  EXPECT_TRUE(backend->Load(train::StateFromAsset(asset)).ok());
  std::vector<Image> images;
  for (const Probe& p : probes) {
    auto image = backend->Render(p.camera, train::RenderRequestFor(asset));
    EXPECT_TRUE(image.ok()) << image.status().ToString();
    images.push_back(std::move(*image));
  }
  return images;
}

using testing::MaxDifference;
using testing::MeanValue;

TEST(CpuProbes, MatchTheCpuBackendAcrossMoves) {
  Asset asset = DynamicAsset(5);
  ASSERT_TRUE(asset.deformation.has_value());
  const std::vector<Probe> probes = OrbitProbes(asset, 4, 48, 36);
  ProbeRenderer renderer(nullptr, probes);
  internal::CpuProbeRenderer direct;
  std::vector<Camera> cameras;
  for (const Probe& p : probes) cameras.push_back(p.camera);

  const auto check = [&](const Asset& a, const char* what) {
    auto mine = renderer.Render(a);
    ASSERT_TRUE(mine.ok()) << what << ": " << mine.status().ToString();
    const std::vector<Image> reference = Reference(a, probes);
    EXPECT_LE(MaxDifference(*mine, reference), kTolerance) << what;
    EXPECT_GT(MeanValue(reference), 1e-3) << what << ": the probes must see the asset";
    auto again = direct.Render(a, cameras, train::RenderRequestFor(a));
    ASSERT_TRUE(again.ok());
    EXPECT_LE(MaxDifference(*again, reference), kTolerance) << what;
  };
  check(asset, "input");
  const uint64_t deformed_once = direct.deformed();
  EXPECT_EQ(deformed_once, asset.gaussians.size() * probes.size());

  // Prune: the kept positions are all known.
  std::vector<uint8_t> keep(asset.gaussians.size(), 1);
  for (size_t i = 0; i < keep.size(); i += 3) keep[i] = 0;
  const Asset pruned = SubsetGaussians(asset, keep);
  check(pruned, "pruned");
  EXPECT_EQ(direct.deformed(), deformed_once) << "a prune deforms nothing new";
  EXPECT_GT(direct.reused(), 0u);

  // A texture move changes a few Gaussians: most tiles come from the cache, and the
  // renders still equal the reference.
  Asset shrunk = pruned;
  ASSERT_TRUE(ShrinkTextures(&shrunk, 3).ok());
  const uint64_t tiles_reused = direct.tiles_reused(), tiles_drawn = direct.tiles_drawn();
  check(shrunk, "three texture axes halved");
  EXPECT_GT(direct.tiles_reused(), tiles_reused);
  EXPECT_GT(direct.tiles_drawn(), tiles_drawn) << "the changed textures' tiles are drawn again";

  // Requantised positions: every position new.
  WriteOptions q8;
  q8.positions = ScalarEncoding::kQuant8;
  auto bytes = EncodeAsset(pruned, q8);
  ASSERT_TRUE(bytes.ok());
  auto decoded = DecodeAsset(bytes->data(), bytes->size());
  ASSERT_TRUE(decoded.ok());
  check(*decoded, "q8 positions");
  EXPECT_GT(direct.deformed(), deformed_once);

  // A different field (coarser grid): the cache starts over.
  Asset coarse = pruned;
  ASSERT_TRUE(CoarsenGrid(&coarse, 2).ok());
  check(coarse, "coarser grid");
  // Lower SH degree (the field's SH head loses outputs) and a static asset.
  Asset lower = coarse;
  ASSERT_TRUE(LowerShDegree(&lower).ok());
  check(lower, "SH degree lowered");
  Asset still = lower;
  still.deformation.reset();
  check(still, "static");
}

}  // namespace
}  // namespace atex::fit
