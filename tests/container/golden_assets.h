// The assets and write options behind the frozen files of tests/container,
// the fuzz seed corpus and the demo sample. Changing anything here changes those
// files: rebuild them with atex_write_golden and say why in the commit.
#pragma once

#include <string>
#include <vector>

#include "atex/container.h"

namespace atex::golden {

// Golden files (tests/container/golden_v1_*.atex): 24 Gaussians, SH degree 2,
// mixed textures, a small deformation field with every head, statistics.
Asset GoldenAsset();
// Every scalar encoding appears once or more; `codec` is raw for golden_v1_raw
// and delta-shuffle-zstd (without raw fallback) for golden_v1_zstd.
WriteOptions GoldenOptions(Codec codec);
inline constexpr const char* kGoldenRawFile = "tests/container/golden_v1_raw.atex";
inline constexpr const char* kGoldenZstdFile = "tests/container/golden_v1_zstd.atex";

// The worked example of format_spec/atex.md §12: one Gaussian, raw chunks.
Asset SpecExampleAsset();
WriteOptions SpecExampleOptions();

// The demo sample (samples/sample.atex): 2000 Gaussians, SH degree 1, mixed
// textures, deformation, compact encodings.
Asset SampleAsset();
WriteOptions SampleOptions();
inline constexpr const char* kSampleFile = "samples/sample.atex";

// Small seed files for tests/fuzz/corpus/atex: name -> bytes.
std::vector<std::pair<std::string, std::vector<uint8_t>>> FuzzSeeds();

}  // namespace atex::golden
