// Issue 24 end to end through the `atex` binary: each defect of the robustness probe as a
// regression case. Bad option values and configs are refused before any work (exit 2 for a
// bad command line, 1 for a refused operation), existing outputs are never clobbered
// without --force, an output that is the input needs --force (and is refused where the
// input is read while writing), the output's extension names what is written, and under
// --json every error is JSON on stdout.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

#include "atex/file_io.h"
#include "core/test_support.h"

namespace atex {
namespace {

namespace fs = std::filesystem;

struct Result {
  int exit_code = -1;
  bool signalled = false;
  std::string out, err;
  double seconds = 0;
};

std::string Slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

class CliRobustness : public ::testing::Test {
 protected:
  void SetUp() override {
    const char* cli = std::getenv("ATEX_CLI");
    ASSERT_NE(cli, nullptr) << "ATEX_CLI is not set (CTest sets it)";
    cli_ = cli;
    asset_ = (testing::SourceDir() / "samples/sample.atex").string();
    npz_ = (testing::DataDir() / "dnerf_lego_tiny/tiny_dnerf_data.npz").string();
  }

  Result Run(const std::string& args) {
    Result r;
    const auto out = dir_ / "stdout", err = dir_ / "stderr";
    const std::string command = "'" + cli_ + "' " + args + " >'" + out.string() + "' 2>'" + err.string() + "'";
    const auto start = std::chrono::steady_clock::now();
    const int status = std::system(command.c_str());
    r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    // std::system runs sh; a signal kills the child, and sh reports 128 + signal.
    r.signalled = !WIFEXITED(status) || r.exit_code >= 128;
    r.out = Slurp(out);
    r.err = Slurp(err);
    return r;
  }

  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  std::string CopyAsset(const std::string& name) {
    fs::copy_file(asset_, Path(name), fs::copy_options::overwrite_existing);
    return Path(name);
  }
  void Write(const std::string& name, const std::string& text) { std::ofstream(Path(name)) << text; }

  // A clean refusal: the given exit code, a message naming `needle`, no signal.
  static void ExpectRefused(const Result& r, int code, const std::string& needle, const std::string& what) {
    EXPECT_FALSE(r.signalled) << what << ": crashed\n" << r.err;
    EXPECT_EQ(r.exit_code, code) << what << "\n" << r.err;
    EXPECT_NE(r.err.find(needle), std::string::npos) << what << ": message does not name '" << needle << "'\n"
                                                     << r.err;
  }

  std::string cli_, asset_, npz_;
  testing::TempDir dir_;
};

// One-step training options (the probe's R): seconds on the CPU.
const char* kTiny =
    "--backend cpu --set stage1.coarse_iterations=1 --set stage1.fine_iterations=1 --set stage1.init_points=300 "
    "--set stage2.iterations=2 --set stage2.growth_steps=[1] --set eval_every=0 --set stage2.batch_size=1";

TEST_F(CliRobustness, TrainRefusesBadConfigsBeforeTraining) {
  ATEX_REQUIRE_DATA_FILE(npz, "dnerf_lego_tiny/tiny_dnerf_data.npz");
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"stage2.time_bins=0", "stage2.time_bins"},  // was: double free after stage 1
      {"stage2.time_bins=-1", "stage2.time_bins"},
      {"stage2.time_bins=1e8", "stage2.time_bins"},
      {"stage1.densify.interval=0 --set stage1.densify.from_step=0", "stage1.densify.interval"},  // was: SIGFPE
      {"background=[2,2,2]", "background"},  // was: refused only when writing, after training
      {"stage1.batch_size=1.5", "stage1.batch_size"},
      {"stage1.batch_size=true", "stage1.batch_size"},
      {"background=[1,1,1,1]", "background"},
      {"stage1.lr.opacity=-1", "stage1.lr.opacity"},
      {"stage1.lambda_dssim=5", "stage1.lambda_dssim"},
      {"stage1.densify.interval=-1", "stage1.densify.interval"},
      {"stage2.iterations=3 --set stage2.growth_steps=[10]", "stage2.growth_steps"},
  };
  for (const auto& [set, key] : cases) {
    const std::string out = Path("bad.atex");
    const Result r = Run("train --data '" + npz.string() + "' " + kTiny + " --set " + set + " --out '" + out + "'");
    ExpectRefused(r, 1, key, set);
    EXPECT_EQ(r.err.find("initialised"), std::string::npos) << set << ": refused only after training started";
    EXPECT_FALSE(fs::exists(out)) << set;
  }
}

TEST_F(CliRobustness, ResumeHonoursTheCheckpointsConfigAndDataset) {
  ATEX_REQUIRE_DATA_FILE(npz, "dnerf_lego_tiny/tiny_dnerf_data.npz");
  const std::string ckpt = Path("ckpt"), data = "--data '" + npz.string() + "' ";
  // A run stopped after its first checkpoint (the time limit ends it early).
  Result r = Run("train " + data + kTiny + " --set stage2.iterations=6 --set stage2.growth_steps=[2] "
                 "--checkpoint-dir '" + ckpt + "' --checkpoint-every 1 --out '" + Path("first.atex") + "'");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  ASSERT_TRUE(fs::exists(fs::path(ckpt) / "trainer.json")) << r.err;
  // A model-shaping override contradicts the checkpoint's model.
  r = Run("train " + data + "--backend cpu --resume '" + ckpt +
          "' --set stage1.deformation.grid.channels=8 --out '" + Path("wide.atex") + "'");
  ExpectRefused(r, 1, "stage1.deformation.grid.channels", "resume with channels=8");
  // Another dataset (here: another training-camera selection of the same file).
  r = Run("train " + data + "--train-cameras 10 --backend cpu --resume '" + ckpt + "' --out '" +
          Path("other.atex") + "'");
  ExpectRefused(r, 1, "training views", "resume on another dataset");
  // No options: the checkpoint's 6-step stage 2, not the default 5,000.
  r = Run("train " + data + "--backend cpu --json --resume '" + ckpt + "' --out '" + Path("resumed.atex") + "'");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto report = nlohmann::json::parse(r.out);
  EXPECT_LE(report["steps"]["textures"].get<int>(), 6) << r.out;
}

TEST_F(CliRobustness, TrainWithSeveralRanks) {
  ATEX_REQUIRE_DATA_FILE(npz, "dnerf_lego_tiny/tiny_dnerf_data.npz");
  const std::string data = "--data '" + npz.string() + "' ";
  // Two CPU ranks as threads (docs/multi_gpu.md): rank 0 writes the asset and the report.
  const std::string out = Path("ranks.atex");
  Result r = Run("train " + data + kTiny + " --ranks 2 --set stage1.batch_size=2 --set stage2.batch_size=2 --json "
                 "--out '" + out + "'");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::exists(out));
  EXPECT_GT(nlohmann::json::parse(r.out)["gaussians"].get<int>(), 0) << r.out;
  // The batch must divide by the ranks, before training.
  r = Run("train " + data + kTiny + " --ranks 2 --out '" + Path("odd.atex") + "'");
  ExpectRefused(r, 1, "multiple of 2 ranks", "--ranks 2 with batch 1");
  EXPECT_FALSE(fs::exists(Path("odd.atex")));
  // Threads of ranks are CPU ranks; a GPU list must be GPU indices.
  ExpectRefused(Run("train " + data + "--ranks 2 --backend auto --out '" + Path("a.atex") + "'"), 2, "--backend cpu",
                "--ranks without --backend cpu");
  ExpectRefused(Run("train " + data + "--gpus 0,x --out '" + Path("g.atex") + "'"), 2, "'x' is not a GPU index",
                "--gpus 0,x");
  ExpectRefused(Run("train " + data + "--gpus 1,1 --out '" + Path("g.atex") + "'"), 2, "listed twice", "--gpus 1,1");
}

TEST_F(CliRobustness, FitOptionValues) {
  const std::string in = CopyAsset("in.atex");
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"--budget .", "--budget"},               // was: uncaught std::invalid_argument
      {"--keep-count nan", "--keep-count"},     // was: exit 0, everything kept
      {"--budget 100KiB,102400 ", "--budget"},  // was: one file written for two budgets
      {"--keep-count 0.5 --probes 0", "--probes"},
      {"--keep-count 1.5", "--keep-count"},
      {"--budget 1MiB --seed -1", "--seed"},
      {"--budget 1MiB --step-growth 0.5", "--step-growth"},
      {"--budget 1MiB --step-growth nan", "--step-growth"},
      {"--budget 1MiB --parallel-candidates -1", "--parallel-candidates"},
      {"--budget 1MiB --parallel-candidates 65", "--parallel-candidates"},
      {"--budget 1MiB --min-texture-step -0.1", "--min-texture-step"},
      {"--budget 1MiB --min-texture-step 2", "--min-texture-step"},
      {"--budget 1MiB --min-texture-step nan", "--min-texture-step"},
  };
  for (const auto& [args, needle] : cases) {
    const std::string out = Path("out_{}.atex");
    ExpectRefused(Run("fit '" + in + "' '" + out + "' " + args), 2, needle, args);
  }
  // in == out: refused without --force.
  const Result same = Run("fit '" + in + "' '" + in + "' --keep-count 0.5");
  ExpectRefused(same, 1, "is the input", "fit in == out");
}

// Every budget that the E16 check accepts is met, the smallest one included: the greedy plan
// can stop a few bytes above it (was: E10 "the fit plan reaches 7672 bytes at best" for a
// 7,665-byte budget of this sample, whose minimum is 7,616).
TEST_F(CliRobustness, FitMeetsTheSmallestBudgetThatTheCheckAccepts) {
  const std::string in = CopyAsset("in.atex");
  const Result refused = Run("fit --backend cpu '" + in + "' '" + Path("tiny.atex") + "' --budget 1");
  ExpectRefused(refused, 1, "E16", "budget 1");
  const std::string marker = "from this input, ";
  const size_t at = refused.err.find(marker);
  ASSERT_NE(at, std::string::npos) << refused.err;
  const uint64_t minimum = std::stoull(refused.err.substr(at + marker.size()));
  const std::string out = Path("smallest.atex");
  const Result fitted =
      Run("fit --backend cpu --json '" + in + "' '" + out + "' --budget " + std::to_string(minimum));
  ASSERT_EQ(fitted.exit_code, 0) << fitted.err;
  EXPECT_LE(fs::file_size(out), minimum);
  EXPECT_EQ(Run("verify '" + out + "'").exit_code, 0);
}

TEST_F(CliRobustness, RenderAndFpsOptionValues) {
  ATEX_REQUIRE_DATA_FILE(npz, "dnerf_lego_tiny/tiny_dnerf_data.npz");
  const std::string data = " --data '" + npz.string() + "' ";
  const std::string camera = " --intrinsics 50 50 32 32 --world-to-camera 1 0 0 0 0 1 0 0 0 0 1 4 0 0 0 1 ";
  ExpectRefused(Run("fps '" + asset_ + "'" + data + "--backend cpu --repeats 0"), 2, "--repeats",
                "fps --repeats 0");  // was: segfault
  ExpectRefused(Run("render '" + asset_ + "' -o '" + Path("a.png") + "' --size 64x64" + camera + "--time nan"), 2,
                "--time", "render --time nan");  // was: rendered t = 0
  ExpectRefused(Run("render '" + asset_ + "' -o '" + Path("b.png") + "' --size 4294967344x48" + camera), 2, "--size",
                "render --size 4294967344x48");  // was: rendered 48x48
  ExpectRefused(Run("render '" + asset_ + "' -o '" + Path("c.png") + "'" + data + "--view test:1abc"), 1, "--view",
                "render --view test:1abc");  // was: test:1
  ExpectRefused(Run("render '" + asset_ + "' -o '" + Path("d.png") + "'" + data + "--size 64x64"), 2, "--size",
                "render --size with --data");  // was: the explicit camera silently dropped
  EXPECT_FALSE(fs::exists(Path("a.png")) || fs::exists(Path("b.png")) || fs::exists(Path("c.png")));
}

TEST_F(CliRobustness, OutputsAreNeverClobbered) {
  const std::string in = CopyAsset("m.atex");
  Write("existing.atex", "precious");
  ExpectRefused(Run("pack '" + in + "' '" + Path("existing.atex") + "'"), 1, "--force", "pack over an existing file");
  EXPECT_EQ(Slurp(Path("existing.atex")), "precious");
  Result r = Run("pack '" + in + "' '" + Path("existing.atex") + "' --force");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  // in == out: only with --force (read whole, written atomically).
  ExpectRefused(Run("pack '" + in + "' '" + in + "'"), 1, "is the input", "pack in == out");
  r = Run("pack '" + in + "' '" + in + "' -f --codec zstd");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  // The extension names the bytes: no .atex bytes in out.ply.
  ExpectRefused(Run("pack '" + in + "' '" + Path("out.ply") + "'"), 1, ".ply", "pack to .ply");
  ExpectRefused(Run("convert '" + in + "' '" + Path("out.ply") + "' --to atex"), 1, ".ply", "convert --to atex to .ply");
  EXPECT_FALSE(fs::exists(Path("out.ply")));
  // export m.bin m.gltf would write the glTF's buffer over its own input.
  const std::string bin = CopyAsset("m.bin");
  ExpectRefused(Run("export '" + bin + "' '" + Path("m.gltf") + "' --force"), 1, "m.bin", "export m.bin m.gltf");
  EXPECT_TRUE(fs::exists(bin));
  EXPECT_FALSE(fs::exists(Path("m.gltf")));
  // import: the output is an .atex, never the glTF or its buffer.
  r = Run("export '" + in + "' '" + Path("g.gltf") + "'");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string before = Slurp(Path("g.bin"));
  ExpectRefused(Run("import '" + Path("g.gltf") + "' '" + Path("g.bin") + "' --force"), 1, ".bin", "import over buffer");
  EXPECT_EQ(Slurp(Path("g.bin")), before);
  r = Run("export '" + in + "' '" + Path("s.glb") + "'");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  ExpectRefused(Run("import '" + Path("s.glb") + "' '" + Path("s.glb") + "'"), 1, "s.glb", "import s.glb s.glb");
  // render: an existing image is kept.
  Write("view.png", "keep");
  ExpectRefused(Run("render '" + in + "' -o '" + Path("view.png") +
                    "' --size 32x32 --intrinsics 30 30 16 16 --world-to-camera 1 0 0 0 0 1 0 0 0 0 1 4 0 0 0 1"),
                1, "--force", "render over an existing image");
  EXPECT_EQ(Slurp(Path("view.png")), "keep");
  // Every command that writes says so in its help.
  for (const char* command : {"train", "fit", "pack", "convert", "export", "import", "render", "view"}) {
    const Result help = Run(std::string(command) + " --help");
    EXPECT_EQ(help.exit_code, 0) << command;
    EXPECT_NE(help.out.find("--force"), std::string::npos) << command;
    EXPECT_NE(help.out.find("never replaced unless --force"), std::string::npos) << command << "\n" << help.out;
  }
}

TEST_F(CliRobustness, JsonErrorsOnStdout) {
  const std::string missing = Path("missing.atex");
  Result r = Run("info --json '" + missing + "'");
  EXPECT_NE(r.exit_code, 0);
  auto j = nlohmann::json::parse(r.out, nullptr, false);
  ASSERT_FALSE(j.is_discarded()) << "stdout is not JSON: " << r.out;
  ASSERT_TRUE(j.contains("error")) << r.out;
  for (const char* key : {"code", "name", "message", "path", "offset"}) EXPECT_TRUE(j["error"].contains(key)) << key;
  EXPECT_EQ(j["error"]["code"], 12) << r.out;  // kNotFound
  EXPECT_EQ(j["error"]["name"], "not-found") << r.out;
  // A corrupted file: the byte offset the message names.
  auto bytes = ReadFileBytes(asset_);
  ASSERT_TRUE(bytes.ok());
  (*bytes)[200] ^= 0x40;
  ASSERT_TRUE(WriteFileAtomic(Path("flipped.atex"), *bytes).ok());
  r = Run("verify --json '" + Path("flipped.atex") + "'");
  EXPECT_NE(r.exit_code, 0);
  j = nlohmann::json::parse(r.out, nullptr, false);
  ASSERT_FALSE(j.is_discarded()) << r.out;
  if (j.contains("error")) {
    EXPECT_TRUE(j["error"]["offset"].is_number() || j["error"]["offset"].is_null());
  }
  // A bad command line under --json: JSON too, exit 2.
  r = Run("fit --json '" + asset_ + "' '" + Path("o.atex") + "' --budget .");
  EXPECT_EQ(r.exit_code, 2);
  j = nlohmann::json::parse(r.out, nullptr, false);
  ASSERT_FALSE(j.is_discarded()) << r.out;
  EXPECT_NE(j["error"]["message"].get<std::string>().find("--budget"), std::string::npos) << r.out;
}

// --print-config with --data prints the defaults a run on that dataset starts from: the Panoptic
// kind's stereo initialisation and camera colours (issue 20), the lego's D-NeRF defaults.
TEST_F(CliRobustness, PrintConfigFollowsTheDatasetsKind) {
  ATEX_REQUIRE_DATA_FILE(meta, "panoptic_basketball/train_meta.json");
  Result r = Run("train --data '" + meta.parent_path().string() + "' --print-config");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["stage1"]["init_method"], "mvs+hull");
  EXPECT_EQ(j["camera_colour"]["enabled"], true);
  r = Run("train --data '" + npz_ + "' --print-config");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["stage1"]["init_method"], "auto");
  EXPECT_EQ(j["camera_colour"]["enabled"], false);
  EXPECT_EQ(j["stage1"]["deformation"]["grid"]["channels"], 32);
  ExpectRefused(Run("train --data '" + Path("missing") + "' --print-config"), 1, "missing", "print-config, no data");
}

}  // namespace
}  // namespace atex
