// Data parallelism on two GPUs through NCCL (issue 25): two ranks as threads of this process,
// each with its own CUDA backend on its own GPU and an NCCL communicator whose unique id goes
// over the TCP rendezvous on 127.0.0.1, each stepping on half of a batch, must compute the
// gradients of one GPU stepping on the whole batch and keep bit-identical replicas. Skips
// without NCCL or with fewer than two GPUs.
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <thread>

#include <gtest/gtest.h>

#include "atex/cuda/cuda_backend.h"
#include "atex/cuda/nccl_communicator.h"
#include "atex/deform.h"
#include "atex/render.h"
#include "atex/train/backend.h"
#include "gpu_test_support.h"
#include "render/render_test_util.h"

namespace atex::cuda {
namespace {

using testing::RelativeError;

int FreePort() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t length = sizeof(a);
  ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof(a));
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &length);
  ::close(fd);
  return ntohs(a.sin_port);
}

// 300 textured Gaussians with a deformation field, one camera pose at four times, targets
// rendered from a perturbed copy (as backend_parity_test's scene).
struct Scene {
  std::vector<Camera> cameras;
  std::vector<Image> targets;
  train::ModelState state;
};

Scene MakeScene(uint32_t seed) {
  std::mt19937 rng(seed);
  Scene s;
  const Camera base = render_testing::RandomCamera(96, 72, rng);
  render_testing::SceneOptions options;
  options.count = 300;
  options.sh_degree = 1;
  options.extras = false;
  options.textures = render_testing::TextureKind::kAdaptiveMixed;
  Gaussians g = render_testing::RandomGaussians<float>(base, options, rng);
  TexturePool pool = render_testing::RandomTextures<float>(g, options.textures, 0.5, rng);
  DeformationConfig dc;
  dc.grid.channels = 4;
  dc.grid.base_resolution = {8, 8, 8, 4};
  dc.grid.multires = {1, 2};
  dc.mlp_width = 16;
  dc.heads = {true, true, true, true, true};
  dc.sh_coeffs = g.sh_coeffs();
  for (int k = 0; k < 3; ++k) {
    float lo = 1e30f, hi = -1e30f;
    for (size_t i = 0; i < g.size(); ++i) {
      lo = std::min(lo, g.positions[3 * i + k]);
      hi = std::max(hi, g.positions[3 * i + k]);
    }
    dc.aabb_lo[k] = lo;
    dc.aabb_hi[k] = hi;
  }
  auto field = InitDeformationField(dc, seed);
  EXPECT_TRUE(field.ok());
  s.state.gaussians = g;
  s.state.textures = pool;
  s.state.deformation = *field;
  train::ResetMoments(&s.state);
  Gaussians shifted = g;
  std::normal_distribution<float> noise(0.0f, 0.05f);
  for (float& v : shifted.sh) v += noise(rng);
  for (int k = 0; k < 4; ++k) {
    Camera c = base;
    c.time = 0.25 * k;
    Gaussians deformed;
    EXPECT_TRUE(DeformForward(*field, shifted, c.time, &deformed, nullptr).ok());
    auto out = RenderForward<float>(c, deformed, &pool, RenderSettings{});
    EXPECT_TRUE(out.ok());
    s.cameras.push_back(c);
    s.targets.push_back(RenderedImage(*out));
  }
  return s;
}

train::StepRequest Request() {
  train::StepRequest r;
  r.learning_rates = {1e-3, 1e-3, 5e-3, 5e-2, 2.5e-3, 1.25e-4, 2.5e-3, 1.6e-3, 1.6e-4};
  r.active_sh_degree = 1;
  r.apply_deformation = true;
  r.use_textures = true;
  r.plane_tv = 2e-4;
  r.time_smoothness = 1e-3;
  r.time_l1 = 1e-4;
  r.accumulate_densify_stats = true;
  return r;
}

struct RankResult {
  Status status = Status::Ok();
  double loss = 0;
  train::ModelState gradients, after;
};

TEST(NcclDataParallel, TwoGpusWithHalfTheBatchComputeTheGradientsOfOne) {
  if (!NcclAvailable()) GTEST_SKIP() << "this build has no NCCL";
  if (testing::CudaDeviceCount() < 2) GTEST_SKIP() << "needs two CUDA devices";
  const Scene scene = MakeScene(7);
  std::vector<train::TrainView> views;
  for (size_t k = 0; k < 4; ++k) views.push_back({&scene.cameras[k], &scene.targets[k], k + 1, {}});

  // One GPU, the whole batch.
  CudaBackendOptions options;
  options.tf32 = false;
  auto one = MakeCudaBackend(options);
  ASSERT_TRUE(one.ok()) << one.status().ToString();
  ATEX_ASSERT_OK((*one)->Load(scene.state));
  auto one_step = (*one)->Step(Request(), views);
  ASSERT_TRUE(one_step.ok() && one_step->finite) << one_step.status().ToString();
  train::ModelState one_grad;
  ATEX_ASSERT_OK((*one)->ReadGradients(&one_grad));

  // Two GPUs, half the batch each.
  const int port = FreePort();
  std::vector<RankResult> ranks(2);
  std::vector<std::thread> threads;
  for (int r = 0; r < 2; ++r) {
    threads.emplace_back([&, r] {
      RankResult& out = ranks[r];
      train::LaunchEnvironment env;
      env.rank = r;
      env.world_size = 2;
      env.local_rank = r;
      env.master_addr = "127.0.0.1";
      env.master_port = port;
      auto comm = MakeNcclCommunicator(env, r);
      if (!comm.ok()) {
        out.status = comm.status();
        return;
      }
      CudaBackendOptions mine = options;
      mine.device = r;
      auto backend = MakeCudaBackend(mine);
      if (!backend.ok()) {
        out.status = backend.status();
        return;
      }
      out.status = (*backend)->Load(scene.state);
      if (out.status.ok()) out.status = (*backend)->SetCommunicator(comm->get());
      if (!out.status.ok()) return;
      auto step = (*backend)->Step(Request(), std::span<const train::TrainView>(views).subspan(2 * r, 2));
      if (!step.ok()) {
        out.status = step.status();
        return;
      }
      out.loss = step->loss;
      out.status = (*backend)->ReadGradients(&out.gradients);
      if (out.status.ok()) out.status = (*backend)->Save(&out.after);
      (void)(*backend)->SetCommunicator(nullptr);
    });
  }
  for (std::thread& t : threads) t.join();
  for (const RankResult& r : ranks) ATEX_ASSERT_OK(r.status);

  EXPECT_EQ(ranks[0].loss, ranks[1].loss);
  EXPECT_NEAR(ranks[0].loss, one_step->loss, 1e-5 * std::abs(one_step->loss));
  // The replicas after the identical Adam step: bit for bit.
  EXPECT_EQ(ranks[0].after.gaussians.positions, ranks[1].after.gaussians.positions);
  EXPECT_EQ(ranks[0].after.textures->texels, ranks[1].after.textures->texels);
  EXPECT_EQ(ranks[0].after.deformation->trunk[0].weight, ranks[1].after.deformation->trunk[0].weight);
  // The summed gradients: one GPU's, up to the order of float sums.
  const train::ModelState& g = ranks[0].gradients;
  ASSERT_TRUE(g.textures && g.deformation && one_grad.textures && one_grad.deformation);
  EXPECT_LE(RelativeError(g.gaussians.positions, one_grad.gaussians.positions), 1e-4);
  EXPECT_LE(RelativeError(g.gaussians.sh, one_grad.gaussians.sh), 1e-4);
  EXPECT_LE(RelativeError(g.gaussians.opacity_logits, one_grad.gaussians.opacity_logits), 1e-4);
  EXPECT_LE(RelativeError(g.textures->texels, one_grad.textures->texels), 1e-4);
  EXPECT_LE(RelativeError(g.deformation->planes[0][0], one_grad.deformation->planes[0][0]), 1e-4);
  EXPECT_LE(RelativeError(g.deformation->trunk[0].weight, one_grad.deformation->trunk[0].weight), 1e-4);
}

TEST(NcclDataParallel, TheCudaBackendRefusesAHostOnlyCommunicator) {
  ATEX_REQUIRE_CUDA_DEVICE();
  auto backend = MakeCudaBackend();
  ASSERT_TRUE(backend.ok()) << backend.status().ToString();
  auto group = train::MakeInProcessGroup(2);
  ASSERT_TRUE(group.ok());
  EXPECT_EQ((*backend)->SetCommunicator((*group)[0].get()).code(), StatusCode::kUnsupported);
  EXPECT_TRUE((*backend)->SetCommunicator(nullptr).ok());
}

}  // namespace
}  // namespace atex::cuda
