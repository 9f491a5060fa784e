// The `atex info`, `verify` and `pack` commands end to end: exit codes, messages
// that name the problem, and JSON that carries the same facts as the library.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "atex/container.h"
#include "atex/file_io.h"
#include "core/test_support.h"

namespace atex {
namespace {

struct Result {
  int exit_code = -1;
  std::string out, err;
};

std::string Slurp(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

class Cli : public ::testing::Test {
 protected:
  void SetUp() override {
    const char* cli = std::getenv("ATEX_CLI");
    ASSERT_NE(cli, nullptr) << "ATEX_CLI is not set (CTest sets it)";
    cli_ = cli;
    golden_ = (testing::SourceDir() / "tests/container/golden_v1_zstd.atex").string();
  }

  Result Run(const std::string& args) {
    Result r;
    const auto out = dir_ / "stdout", err = dir_ / "stderr";
    const std::string command = "'" + cli_ + "' " + args + " >'" + out.string() + "' 2>'" + err.string() + "'";
    const int status = std::system(command.c_str());
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.out = Slurp(out);
    r.err = Slurp(err);
    return r;
  }

  std::string Copy(const std::string& name, size_t cut = 0, long flip_at = -1) {
    auto bytes = ReadFileBytes(golden_);
    EXPECT_TRUE(bytes.ok());
    if (cut) bytes->resize(cut);
    if (flip_at >= 0) (*bytes)[flip_at] ^= 0x01;
    const std::string path = (dir_ / name).string();
    EXPECT_TRUE(WriteFileAtomic(path, *bytes).ok());
    return path;
  }

  std::string cli_, golden_;
  testing::TempDir dir_;
};

TEST_F(Cli, InfoJsonCarriesTheLibrarysFacts) {
  const Result r = Run("info --json '" + golden_ + "'");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  auto bytes = ReadFileBytes(golden_);
  auto asset = DecodeAsset(bytes->data(), bytes->size());
  ASSERT_TRUE(asset.ok());
  EXPECT_EQ(j["version"], "1.0");
  EXPECT_EQ(j["file_size"], bytes->size());
  EXPECT_EQ(j["gaussians"], asset->gaussians.size());
  EXPECT_EQ(j["sh_degree"], 2);
  EXPECT_EQ(j["chunks"].size(), 14u);
  uint64_t sum = 0;
  for (const auto& c : j["components"]) sum += c["bytes"].get<uint64_t>();
  EXPECT_EQ(sum, bytes->size());
  uint64_t histogram = 0;
  for (const auto& [shape, count] : j["textures"]["histogram_hxw"].items()) histogram += count.get<uint64_t>();
  EXPECT_EQ(histogram, asset->gaussians.size());
  EXPECT_EQ(j["textures"]["texels"], asset->textures->texel_count());
  EXPECT_EQ(j["deformation"]["channels"], asset->deformation->config.grid.channels);
  // Encodings come from the stream headers: rotations f16, opacities q8 (golden_assets.cc).
  EXPECT_EQ(j["chunks"][3]["type"], "GROT");
  EXPECT_EQ(j["chunks"][3]["encoding"], "f16");
  EXPECT_EQ(j["chunks"][5]["encoding"], "q8");
  EXPECT_EQ(j["chunks"][5]["codec"], "delta-shuffle-zstd");
}

TEST_F(Cli, InfoText) {
  const Result r = Run("info '" + golden_ + "'");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const char* part : {"format 1.0", "gaussians    24", "SH degree 2", "uniform 4x4", "HexPlane", "GSHR", "TEXL",
                           "bytes per component", "textures"}) {
    EXPECT_NE(r.out.find(part), std::string::npos) << part << "\n" << r.out;
  }
}

TEST_F(Cli, VerifyValidFile) {
  Result r = Run("verify '" + golden_ + "'");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("OK"), std::string::npos);
  r = Run("verify --json '" + golden_ + "'");
  ASSERT_EQ(r.exit_code, 0);
  EXPECT_EQ(nlohmann::json::parse(r.out)["valid"], true);
}

TEST_F(Cli, VerifyNamesTheProblem) {
  // A flipped bit inside chunk #2 (GPOS): its offset comes from the TOC.
  auto bytes = ReadFileBytes(golden_);
  auto info = InspectContainer(bytes->data(), bytes->size());
  ASSERT_TRUE(info.ok());
  const uint64_t gpos = info->chunks[2].offset;
  Result r = Run("verify '" + Copy("flip.atex", 0, static_cast<long>(gpos + 3)) + "'");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("E6 checksum-mismatch"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("chunk 'GPOS' (#2) at byte " + std::to_string(gpos)), std::string::npos) << r.err;
  r = Run("verify --json '" + Copy("cut.atex", 100) + "'");
  EXPECT_EQ(r.exit_code, 1);
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["valid"], false);
  EXPECT_EQ(j["error"]["name"], "truncated");
  EXPECT_EQ(j["error"]["code"], 3);
  r = Run("verify '" + (dir_ / "missing.atex").string() + "'");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("not-found"), std::string::npos) << r.err;
}

TEST_F(Cli, PackReencodesAndReportsSizes) {
  const std::string out = (dir_ / "packed.atex").string();
  Result r = Run("pack '" + golden_ + "' '" + out + "' --codec raw --positions f16 --texels q8 --sh q8 --level 5 --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  auto packed = ReadFileBytes(out);
  ASSERT_TRUE(packed.ok());
  EXPECT_EQ(j["out_bytes"], packed->size());
  EXPECT_EQ(j["options"]["codec"], "raw");
  auto info = InspectContainer(packed->data(), packed->size());
  ASSERT_TRUE(info.ok());
  for (const ChunkInfo& c : info->chunks) EXPECT_EQ(c.codec, Codec::kRaw) << c.type;
  EXPECT_EQ(*StreamEncodingOf(packed->data(), packed->size(), info->chunks[2]), ScalarEncoding::kFloat16);
  EXPECT_EQ(*StreamEncodingOf(packed->data(), packed->size(), info->chunks[6]), ScalarEncoding::kQuant8);
  EXPECT_EQ(Run("verify '" + out + "'").exit_code, 0);
  // Encodings without an option keep the input's: rotations stay f16, opacities q8.
  r = Run("pack '" + golden_ + "' '" + out + "' --codec zstd --force");  // replaces the first output
  ASSERT_EQ(r.exit_code, 0) << r.err;
  packed = ReadFileBytes(out);
  info = InspectContainer(packed->data(), packed->size());
  ASSERT_TRUE(info.ok());
  EXPECT_EQ(*StreamEncodingOf(packed->data(), packed->size(), info->chunks[3]), ScalarEncoding::kFloat16);
  EXPECT_EQ(*StreamEncodingOf(packed->data(), packed->size(), info->chunks[5]), ScalarEncoding::kQuant8);
  EXPECT_EQ(*StreamEncodingOf(packed->data(), packed->size(), info->chunks[7]), ScalarEncoding::kQuant8);
  // Text form.
  r = Run("pack '" + golden_ + "' '" + out + "' --codec delta-shuffle-zstd -f");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("packed"), std::string::npos);
  EXPECT_NE(r.out.find("positions"), std::string::npos);
}

TEST_F(Cli, PackDraco) {
  const std::string out = (dir_ / "draco.atex").string();
  const Result r = Run("pack '" + golden_ + "' '" + out + "' --positions draco");
  if (!HaveDracoCodec()) {
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_NE(r.err.find("unsupported-codec"), std::string::npos);
    return;
  }
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(Run("verify '" + out + "'").exit_code, 0);
}

TEST_F(Cli, UsageErrorsAndHelp) {
  EXPECT_EQ(Run("pack a b --codec lz4").exit_code, 2);
  EXPECT_EQ(Run("pack a b --positions f64").exit_code, 2);
  EXPECT_EQ(Run("info").exit_code, 2);
  for (const char* command : {"info", "verify", "pack"}) {
    const Result r = Run(std::string(command) + " --help");
    EXPECT_EQ(r.exit_code, 0) << command;
    EXPECT_NE(r.out.find("--json"), std::string::npos) << command << ": " << r.out;
  }
  const std::string not_atex = (dir_ / "text.atex").string();
  std::ofstream(not_atex) << "hello\n";
  const Result r = Run("info '" + not_atex + "'");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("E4 bad-magic"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace atex
