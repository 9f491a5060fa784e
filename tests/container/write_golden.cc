// atex_write_golden SOURCE_DIR: rewrites the frozen container files (golden
// files, demo sample, fuzz seeds) from golden_assets.cc. Run it only when the
// format or the generator changes on purpose; the tests then pin the new bytes.
#include <cstdio>
#include <filesystem>

#include "atex/file_io.h"
#include "golden_assets.h"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s SOURCE_DIR\n", argv[0]);
    return 2;
  }
  const std::filesystem::path root = argv[1];
  int failures = 0;
  auto write = [&](const std::filesystem::path& path, const atex::Asset& asset, const atex::WriteOptions& options) {
    atex::Status s = atex::WriteAssetFile(path.string(), asset, options);
    std::printf("%s %s\n", s.ok() ? "wrote" : "FAILED", path.c_str());
    if (!s.ok()) {
      std::fprintf(stderr, "%s\n", s.ToString().c_str());
      ++failures;
    }
  };
  using namespace atex::golden;
  write(root / kGoldenRawFile, GoldenAsset(), GoldenOptions(atex::Codec::kRaw));
  write(root / kGoldenZstdFile, GoldenAsset(), GoldenOptions(atex::Codec::kDeltaShuffleZstd));
  write(root / kSampleFile, SampleAsset(), SampleOptions());
  const std::filesystem::path corpus = root / "tests/fuzz/corpus/atex";
  std::filesystem::create_directories(corpus);
  for (const auto& [name, bytes] : FuzzSeeds()) {
    atex::Status s = atex::WriteFileAtomic((corpus / name).string(), bytes);
    std::printf("%s %s\n", s.ok() ? "wrote" : "FAILED", (corpus / name).c_str());
    failures += s.ok() ? 0 : 1;
  }
  return failures == 0 ? 0 : 1;
}
